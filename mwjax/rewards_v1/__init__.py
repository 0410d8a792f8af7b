"""Meta-World's V1 reward functions (`reward_function_version="v1"`, the original 2019 rewards) in
jax.numpy, one per task, on one env (vmapped by the core).

V1 rewards are sums of hand-tuned terms in the reference's units (hundreds to thousands), read
per-episode constants fixed at reset (`heightTarget`, `maxPlacingDist`, ...), and branch on
thresholds; every branch is a `where` here. Kernels return `(reward, info)` like V2's, with the
info terms the reference's `evaluate_state` builds from V1's `compute_reward` outputs.

One module per task family, as in `mwjax.tasks`; the terms several families share are in `terms`.
"""
