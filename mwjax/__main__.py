"""`python -m mwjax`: a short batched MT10 rollout that prints throughput and success.

Runs on the GPU when JAX sees one (set XLA_PYTHON_CLIENT_MEM_FRACTION≈0.45 there so Warp gets
memory), otherwise on the CPU with a small batch.
"""

from __future__ import annotations

import argparse
import time

import jax
import jax.numpy as jnp
import numpy as np

import mwjax


def main() -> None:
    on_gpu = jax.default_backend() == "gpu"
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--tasks", default="MT10", help='a set ("MT10", "MT1:<task>")')
    parser.add_argument("--envs-per-task", type=int, default=1024 if on_gpu else 2)
    parser.add_argument("--steps", type=int, default=500 if on_gpu else 20)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()

    env = mwjax.make(args.tasks, envs_per_task=args.envs_per_task, seed=args.seed)
    print(f"{args.tasks}: {env.num_envs} envs ({len(env.task_list)} tasks) on {jax.devices()[0]}")

    def rollout(state: mwjax.State, key: jax.Array) -> tuple[mwjax.State, jax.Array]:
        def body(carry: tuple[mwjax.State, jax.Array], key: jax.Array) -> tuple:
            state, succeeded = carry
            action = jax.random.uniform(key, (env.num_envs, 4), minval=-1.0, maxval=1.0)
            state = env.step(state, action)
            return (state, succeeded | state.info["success"]), None

        init = (state, jnp.zeros(env.num_envs, bool))
        (state, succeeded), _ = jax.lax.scan(body, init, jax.random.split(key, args.steps))
        return state, succeeded

    start = time.perf_counter()
    state = jax.jit(env.reset)(jax.random.key(args.seed))
    run = jax.jit(rollout).lower(state, jax.random.key(1)).compile()
    compile_s = time.perf_counter() - start
    start = time.perf_counter()
    state, succeeded = jax.block_until_ready(run(state, jax.random.key(1)))
    elapsed = time.perf_counter() - start

    print(
        f"compile {compile_s:.1f} s; {args.steps} steps in {elapsed:.2f} s: "
        f"{env.num_envs * args.steps / elapsed:,.0f} env steps/s (random actions)"
    )
    succeeded = np.asarray(succeeded)
    for task in env.task_list:
        rows = env.task_rows(task)
        print(
            f"  {task:<26} success at any step: {succeeded[rows].mean():.0%}  "
            f"mean last reward {float(np.asarray(state.reward)[rows].mean()):.3f}"
        )


if __name__ == "__main__":
    main()
