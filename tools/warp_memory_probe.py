"""Where a large batch's GPU memory goes: Warp's convex-collider scratch per call, the card's use.

    python tools/warp_memory_probe.py MT1:pick-place-v3 131070 --steps 500
    python tools/warp_memory_probe.py MT1:pick-place-v3 131070 --ccd-pairs 4
    python tools/warp_memory_probe.py MT10 131070 --steps 500 --carry-flags   # as throughput.py
    python tools/warp_memory_probe.py MT10 131070 --steps 50 --adapter        # the Gymnasium adapter

Builds one set at a batch, runs three random-action rollouts of `--steps` steps (the first one
includes Warp's kernel builds and graph captures), and prints per rollout its time, the card's
memory in use (nvidia-smi), Warp's memory-pool use, JAX's peak and how many CUDA graphs Warp's
callables keep: in MJX's default graph mode one per call and set of buffer addresses, each with
the scratch it allocated, so a count that grows from rollout to rollout shows buffers that moved
(`--no-donate`, `--carry-flags` and `--graph-mode` vary what might move them). `--adapter` steps
the Gymnasium adapter (`mwjax.make_vector`, one jitted step per Python call) `--steps` times per
round instead, which is where XLA may hand a call site new buffers at every call. The adapter
keeps one graph per call site by itself (`warp_graphs.stepped_from_python`), whatever
`MWJAX_WARP_GRAPHS_PER_SITE` says. Warp's policy is
the default; `MWJAX_WARP_GRAPHS_PER_SITE=K` bounds each call site to K (`mwjax.warp_graphs`).
At the end it prints the shapes of the scratch arrays that Warp's convex collider
(`collision_convex.convex_narrowphase`) allocated and how often: the first dimension is the
scene's `naccdmax` (envs x slots). It counts them by wrapping `wp.empty` in that module alone.
A diagnostic: it neither checks overflow nor follows the throughput protocol
(`benchmarks/throughput.py` does). Run one case per process.
"""

from __future__ import annotations

import argparse
import collections
import os
import subprocess
import time
from collections.abc import Callable
from typing import Any

import jax
import jax.numpy as jnp
import mujoco.mjx.third_party.mujoco_warp._src.collision_convex as collision_convex
import warp as wp
from warp._src.jax import ffi

import mwjax
from mwjax.benchmarks import parse_tasks, task_names
from mwjax.warp_graphs import kept_graphs
from mwjax.wrappers.gymnasium import make_vector

SHAPES: collections.Counter[str] = collections.Counter()


class _CountingWarp:
    """`warp` as `collision_convex` sees it, with `empty` counting the shapes it allocates."""

    def __getattr__(self, name: str) -> Any:
        return getattr(wp, name)

    @staticmethod
    def empty(*args: Any, **kwargs: Any) -> wp.array:
        SHAPES[str(kwargs.get("shape", args[0] if args else None))] += 1
        return wp.empty(*args, **kwargs)


def card_memory_mib() -> str:
    """Memory in use on the GPU this process runs on (nvidia-smi numbers every GPU of the host)."""
    card = os.environ.get("CUDA_VISIBLE_DEVICES", "0").split(",")[0] or "0"
    query = ["nvidia-smi", "--query-gpu=memory.used", "--format=csv,noheader", "-i", card]
    try:
        return subprocess.run(query, capture_output=True, text=True).stdout.strip()
    except OSError:
        return "n/a (no nvidia-smi)"


def warp_graphs() -> str:
    """CUDA graphs Warp's JAX callables keep, over the callables that keep any and the call
    sites they were traced at: `graphs (callables, sites)`."""
    graphs, callables = kept_graphs()
    sites = sum(len(c.call_descriptors) for c in ffi._FFI_CALLABLE_REGISTRY.values() if c.captures)
    return f"{graphs} ({callables} callables, {sites} sites)"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("set", help="a set name, e.g. MT10 or MT1:pick-place-v3")
    parser.add_argument("envs", type=int, help="total envs")
    parser.add_argument("--steps", type=int, default=20)
    parser.add_argument("--ccd-pairs", type=int, default=None, help="ccd_pairs_per_env (default: per scene)")
    parser.add_argument("--graph-mode", default=None, help="PhysicsConfig.graph_mode (default: MJX's)")
    parser.add_argument("--no-donate", action="store_true", help="do not donate the state to the rollout")
    parser.add_argument(
        "--carry-flags",
        action="store_true",
        help="carry the overflow flags and a success count through the scan, as throughput.py does",
    )
    parser.add_argument("--adapter", action="store_true", help="step the Gymnasium adapter from Python")
    args = parser.parse_args()
    collision_convex.wp = _CountingWarp()

    settings = {"ccd_pairs_per_env": args.ccd_pairs, "graph_mode": args.graph_mode}
    physics = mwjax.PhysicsConfig(**{k: v for k, v in settings.items() if v is not None})
    env = mwjax.make(args.set, envs_per_task=args.envs // len(task_names(args.set)), physics=physics)
    slots = {g.scene: env.physics.ccd_pairs(g.scene) for g in env.physics.groups}
    print(f"{args.set}: {env.num_envs} envs, convex-collider slots per env {slots}", flush=True)

    def rollout(state: mwjax.State, key: jax.Array) -> tuple:
        """The state, and with `--carry-flags` the overflow flags and success count; without it
        the scan carries the state alone, as the probe always did."""

        def body(carry: tuple, key: jax.Array) -> tuple[tuple, None]:
            state, *extra = carry
            action = jax.random.uniform(key, (env.num_envs, 4), minval=-1.0, maxval=1.0)
            state = env.step(state, action)
            if extra:
                flags, successes = extra
                extra = [flags | state.info["physics_overflow"], successes + state.info["success"].sum()]
            return (state, *extra), None

        flags = (jnp.zeros(env.num_envs, jnp.int32), jnp.zeros((), jnp.int32)) if args.carry_flags else ()
        return jax.lax.scan(body, (state, *flags), jax.random.split(key, args.steps))[0]

    if args.adapter:
        if args.graph_mode or args.ccd_pairs or args.no_donate or args.carry_flags:
            parser.error("--adapter steps the adapter with default physics, without the rollout options")
        run = adapter_rounds(args)
    else:
        state = jax.jit(env.reset)(jax.random.key(0))
        jitted = jax.jit(rollout, donate_argnums=() if args.no_donate else 0)

        def run(key: jax.Array) -> None:
            nonlocal state
            state = jax.block_until_ready(jitted(state, key))[0]

    device = wp.get_device()
    label = "adapter round" if args.adapter else "rollout"
    for i in range(3):
        t0 = time.perf_counter()
        run(jax.random.key(i))
        seconds = time.perf_counter() - t0
        stats = jax.devices()[0].memory_stats() or {}
        pool = wp.get_mempool_used_mem_current(device) / 2**30 if device.is_cuda else 0.0
        print(
            f"{label} {i}: {seconds:.1f} s ({env.num_envs * args.steps / seconds:,.0f} env steps/s), "
            f"card {card_memory_mib()}, Warp pool {pool:.2f} GiB, "
            f"JAX peak {stats.get('peak_bytes_in_use', 0) / 2**30:.2f} GiB, "
            f"Warp graphs kept {warp_graphs()}",
            flush=True,
        )
    print("convex-collider scratch shapes (calls):", dict(SHAPES.most_common(8)))


def adapter_rounds(args: argparse.Namespace) -> Callable[[jax.Array], None]:
    """One round: `--steps` adapter steps with device (jax) actions, as a Python training loop
    that keeps its data on the GPU would call it (default physics: the adapter takes no config)."""
    per_task = args.envs // len(task_names(args.set))
    envs = make_vector(parse_tasks(args.set), envs_per_task=per_task, array_type="jax")
    envs.reset(seed=0)

    def run(key: jax.Array) -> None:
        for k in jax.random.split(key, args.steps):
            out = envs.step(jax.random.uniform(k, (envs.num_envs, 4), minval=-1.0, maxval=1.0))
        jax.block_until_ready(out)

    return run


if __name__ == "__main__":
    main()
