"""Run-to-run determinism of the evaluator: the same jitted rollout twice with the same key.

    XLA_PYTHON_CLIENT_MEM_FRACTION=0.45 python tools/determinism.py hand-insert-v3
    python tools/determinism.py hand-insert-v3 --warp-deterministic   # Warp's RUN_TO_RUN atomics

On the CPU Warp runs kernels serially and rollouts are bit-identical (tests/test_env.py). On a GPU,
MJX-Warp's kernels use atomics whose order varies, so returns differ between identical runs.
"""

from __future__ import annotations

import argparse

import numpy as np


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("tasks", nargs="+")
    parser.add_argument("--episodes", type=int, default=50)
    parser.add_argument("--warp-deterministic", action="store_true")
    args = parser.parse_args()
    if args.warp_deterministic:  # must precede the creation of MJX-Warp's kernel modules
        import warp as wp

        wp.config.deterministic = wp.DeterministicMode.RUN_TO_RUN
    import jax

    import mwjax
    from mwjax import policies
    from mwjax.evaluation import evaluator

    env = mwjax.make(args.tasks, seed=42)
    policy = policies.expert_policy(env.replace(envs_per_task=args.episodes))
    run = jax.jit(evaluator(env, policy, args.episodes))
    first, second = (run(None, jax.random.key(0)) for _ in range(2))
    returns = np.asarray(first.returns), np.asarray(second.returns)
    print(
        f"device {jax.devices()[0].device_kind}: success {np.asarray(first.success_rate).round(2).tolist()} "
        f"then {np.asarray(second.success_rate).round(2).tolist()}; returns identical: "
        f"{np.array_equal(*returns)}, max difference {float(np.abs(returns[0] - returns[1]).max()):.4g}"
    )


if __name__ == "__main__":
    main()
