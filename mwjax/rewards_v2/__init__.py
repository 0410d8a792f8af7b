"""Meta-World's V2 reward functions in jax.numpy, one per task, on one env (vmapped by the core).

One module per task family, as in `mwjax.tasks` and `mwjax.policies`; the shared vocabulary
(dm_control's `tolerance`, the hamacher product, the gripper-caging term) is written once in
`terms`, and task kernels compose it exactly as `metaworld==3.1.1` does, including its quirks
(each one is named where it is reproduced). Every kernel returns `(reward, info)` where `info`
carries the reference's info terms and `success`.
"""
