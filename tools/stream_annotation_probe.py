"""Can XLA run the scenes' physics calls of one env step side by side on separate GPU streams?

An env step calls each scene's MJX-Warp chain one after another; at small and mid batches each
chain is bound by its kernels' latency, not by the GPU's width (docs/performance.md). JAX's
`compute_on("gpu_stream:<k>")` asks XLA to run a call on stream k (with
`XLA_FLAGS=--xla_gpu_experimental_stream_annotation=true`). This times a seeded random-action
rollout (staggered episodes, as `benchmarks/throughput.py --stagger`) with the scenes' calls as
they are, then with scene g on stream g % STREAMS + 1, and prints a JSON row each:

    XLA_FLAGS=--xla_gpu_experimental_stream_annotation=true XLA_PYTHON_CLIENT_MEM_FRACTION=0.45 \\
        python tools/stream_annotation_probe.py --set MT10 --envs-per-task 50 --streams 8
    JAX_PLATFORMS=cpu python tools/stream_annotation_probe.py --set reach-v3,push-v3 \\
        --envs-per-task 1 --steps 3        # CPU: the annotation is ignored; the rows must agree
"""

from __future__ import annotations

import argparse
import functools
import inspect
import json
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
from jax.experimental import compute_on as compute_on_module

sys.path.insert(0, str(Path(__file__).parents[1]))
import mwjax  # noqa: E402
from mwjax import physics  # noqa: E402
from mwjax.env import staggered  # noqa: E402


def on_stream(stream: int, fn: Callable[..., Any], *args: Any) -> Any:
    """`fn(*args)` as one call that XLA is asked to run on GPU stream `stream`."""
    compute_on = compute_on_module.compute_on
    if "out_memory_spaces" in inspect.signature(compute_on).parameters:  # JAX >= 0.11
        wrapped = compute_on(compute_type=f"gpu_stream:{stream}", out_memory_spaces=jax.memory.Space.Device)
        return wrapped(fn)(*args)
    with compute_on(f"gpu_stream:{stream}"):
        return jax.jit(fn)(*args)


def streamed_step(streams: int) -> Callable[..., Any]:
    """`Physics.step` with scene g's call on stream g % streams + 1."""

    def step(self: physics.Physics, states: tuple[physics.PhysicsState, ...]) -> tuple:
        stepped = tuple(
            on_stream(
                g % streams + 1,
                functools.partial(self.step_group, g),
                state.replace(overflow=jnp.zeros_like(state.overflow)),
            )
            for g, state in enumerate(states)
        )
        self._warn_on_host(stepped)
        return stepped

    return step


def measure(tasks: str | list[str], envs_per_task: int, steps: int, streams: int | None) -> dict:
    """One row: compile, a warm-up run and a timed run of the same rollout."""
    original = physics.Physics.step
    if streams is not None:
        physics.Physics.step = streamed_step(streams)
    try:
        env = mwjax.make(tasks, envs_per_task=envs_per_task, seed=0)
        key = jax.random.key(0)

        def rollout(state: Any, key: jax.Array) -> tuple[Any, jax.Array]:
            def body(state: Any, key: jax.Array) -> tuple[Any, jax.Array]:
                action = jax.random.uniform(key, (env.num_envs, 4), minval=-1.0, maxval=1.0)
                state = env.step(state, action)
                return state, state.reward.sum()

            return jax.lax.scan(body, state, jax.random.split(key, steps))

        start = time.perf_counter()
        state = staggered(jax.block_until_ready(jax.jit(env.reset)(key)), env.max_episode_steps, key)
        compiled = jax.jit(rollout).lower(state, key).compile()
        compile_s = time.perf_counter() - start
        start = time.perf_counter()
        jax.block_until_ready(compiled(state, key))
        first_s = time.perf_counter() - start
        start = time.perf_counter()
        final, rewards = jax.block_until_ready(compiled(state, key))
        timed_s = time.perf_counter() - start
    finally:
        physics.Physics.step = original
    overflow = np.asarray(final.info["physics_overflow"]).reshape(env.num_envs, -1).any(axis=1)
    return {
        "tasks": tasks if isinstance(tasks, str) else ",".join(tasks),
        "envs": env.num_envs,
        "steps": steps,
        "streams": streams,
        "compile_s": round(compile_s, 1),
        "first_run_s": round(first_s, 2),
        "timed_run_s": round(timed_s, 3),
        "env_steps_per_s": round(env.num_envs * steps / timed_s),
        "ms_per_step": round(1000 * timed_s / steps, 2),
        "reward_sums": [float(rewards[0]), float(rewards[-1])],
        "overflow_envs": int(overflow.sum()),
        "device": jax.devices()[0].device_kind,
    }


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--set", default="MT10", help="a set name, or tasks separated by commas")
    parser.add_argument("--envs-per-task", type=int, default=50)
    parser.add_argument("--steps", type=int, default=100)
    parser.add_argument("--streams", type=int, default=8, help="GPU streams the scenes' calls go round")
    args = parser.parse_args()
    tasks = args.set.split(",") if "," in args.set else args.set
    for streams in (None, args.streams):
        print(json.dumps(measure(tasks, args.envs_per_task, args.steps, streams)), flush=True)


if __name__ == "__main__":
    main()
