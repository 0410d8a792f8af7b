"""Where the Gymnasium adapter's step goes, beyond its jitted step's, at one batch size.

    python benchmarks/profile_adapter.py --set MT10 --batch 131070 --steps 100

One adapter (`make_vector`, NumPy, its default physics) with its episodes staggered as the
throughput benchmark staggers them, warmed up for `--steps` steps; then `--steps` steps of each
level below, each step waited for and timed on its own (medians in ms):
  numpy step     `envs.step`, what a Gymnasium user calls: action checks, the step, the
                 Gymnasium results (info masks, autoreset fields) and their copy to the host
  jax step       the adapter under it: the same without the copy to the host
  jitted step    the adapter's jitted `env.step` alone, called from Python, and waited for
  launch         how long that call takes to return, before the wait: the host's work of
                 launching it (XLA's program and MJX-Warp's calls into Warp)
  actions in     the copy of the actions to the device
  scan of K      per step, K steps in one jitted `lax.scan` of the same `env.step` and physics,
                 called from Python (`--scan-steps`, 0: not timed): near the jitted step, the
                 time is in each step itself; near the jitted rollout's step, in starting a
                 program from Python
`--graph-mode warp` runs the scan level alone in MJX's default graph mode, the jitted rollout's,
warmed up by scans too: against the default's scan level it tells what the adapter's staged mode
costs. The other levels cannot run in that mode: each step called from Python captures its graphs
anew, with their scratch, and at 131,070 MT10 envs the warm-up ran out of device memory (which is
why the adapter stages them).
The jitted rollout's own step time is the throughput benchmark's row (the device's time with
the host running ahead); a step from Python also pays what of its launch the device does not hide.
"""

from __future__ import annotations

import argparse
import json
import statistics
import time
from collections.abc import Callable
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
from common import (
    add_concurrent_scenes_argument,
    build_kernels,
    provenance,
    result_path,
    scene_settings,
    set_arg,
    staggered_vector_env,
    tasks_arg,
)

import mwjax
from mwjax import warp_graphs
from mwjax.benchmarks import task_names
from mwjax.wrappers.gymnasium import make_vector


def median_ms(timed: Callable[[np.ndarray], float], actions: np.ndarray) -> float:
    return 1e3 * statistics.median(timed(action) for action in actions)


def scanned_steps(step: Callable[..., Any]) -> Callable[..., Any]:
    """`step` applied along the actions' first axis in one jitted `lax.scan`, donating the state
    as the adapter's step does (and, like it, traced for calls from Python)."""

    def run(state: Any, actions: jax.Array) -> Any:
        return jax.lax.scan(lambda s, a: (step(s, a), None), state, actions)[0]

    return warp_graphs.stepped_from_python(jax.jit(run, donate_argnums=0))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--set", type=set_arg, default="MT10", help="a task set or a task (MT10, MT1:pick-place-v3, ...)"
    )
    parser.add_argument("--batch", type=int, default=131070, help="total envs (a multiple of the task count)")
    parser.add_argument("--steps", type=int, default=100, help="warm-up steps, then timed steps per level")
    parser.add_argument(
        "--scan-steps", type=int, default=10, help="steps per call of the scan level (0: skip it)"
    )
    parser.add_argument(
        "--graph-mode",
        default=None,
        help="the adapter's PhysicsConfig.graph_mode (default: its own, on one GPU Warp's staged mode); "
        "'warp', MJX's default, times only the scan level, as the jitted rollout runs its steps",
    )
    add_concurrent_scenes_argument(parser)
    args = parser.parse_args()
    n_tasks = len(task_names(tasks_arg(args.set)))
    if args.scan_steps < 0 or (args.scan_steps and args.steps % args.scan_steps):
        parser.error("--scan-steps must be 0 or divide --steps")
    if args.batch < n_tasks or args.batch % n_tasks:
        parser.error(f"--batch must be a positive multiple of the {n_tasks} tasks of {args.set}")
    try:
        physics = mwjax.PhysicsConfig(graph_mode=args.graph_mode, **scene_settings(args))
    except ValueError as e:
        parser.error(str(e))
    # In Warp's own mode a step called from Python captures anew: only scans can be timed.
    scans_only = args.graph_mode == "warp"
    if scans_only and not args.scan_steps:
        parser.error("--graph-mode warp times only the scan level: --scan-steps must be positive")
    kernel_build_s = build_kernels(tasks_arg(args.set), physics)
    envs = make_vector(tasks_arg(args.set), envs_per_task=args.batch // n_tasks, seed=0, physics=physics)
    adapter = staggered_vector_env(envs)
    actions = np.random.default_rng(0).uniform(-1, 1, (args.steps, envs.num_envs, 4)).astype(np.float32)
    if not scans_only:
        for action in actions:  # the first step compiles
            envs.step(action)

    def numpy_step(action: np.ndarray) -> float:
        start = time.perf_counter()
        envs.step(action)
        return time.perf_counter() - start

    def jax_step(action: np.ndarray) -> float:
        start = time.perf_counter()
        jax.block_until_ready(adapter.step(action))
        return time.perf_counter() - start

    launches: list[float] = []

    def jitted_step(action: np.ndarray) -> float:
        action = jax.block_until_ready(jnp.asarray(action))
        start = time.perf_counter()
        state = adapter._step(adapter.state, action)  # the adapter's own program, not a second copy
        launches.append(time.perf_counter() - start)
        adapter.state = jax.block_until_ready(state)
        return time.perf_counter() - start

    def actions_in(action: np.ndarray) -> float:
        start = time.perf_counter()
        jax.block_until_ready(jnp.asarray(action))
        return time.perf_counter() - start

    levels = {}
    if not scans_only:
        levels["numpy step"] = median_ms(numpy_step, actions)
        levels["jax step"] = median_ms(jax_step, actions)
        levels["jitted step"] = median_ms(jitted_step, actions)
        levels["launch"] = 1e3 * statistics.median(launches)
        levels["actions in"] = median_ms(actions_in, actions)
    if args.scan_steps:
        k = args.scan_steps
        scan = scanned_steps(adapter.env.step)
        chunks = actions.reshape(-1, k, *actions.shape[1:])
        warm_up = chunks if scans_only else chunks[:1]  # the first call compiles
        for chunk in warm_up:
            adapter.state = jax.block_until_ready(scan(adapter.state, jnp.asarray(chunk)))

        def scan_step(chunk: np.ndarray) -> float:
            chunk = jax.block_until_ready(jnp.asarray(chunk))
            start = time.perf_counter()
            adapter.state = jax.block_until_ready(scan(adapter.state, chunk))
            return (time.perf_counter() - start) / k

        levels[f"scan of {k}"] = median_ms(scan_step, chunks)
    for name, ms in levels.items():
        print(
            f"{name:>12}: {ms:8.2f} ms per step ({envs.num_envs / ms * 1e3:>12,.0f} env steps/s)", flush=True
        )
    result = {
        **provenance(),
        "set": args.set,
        "num_envs": envs.num_envs,
        "steps": args.steps,
        "scan_steps": args.scan_steps,
        "physics": str(adapter.env.physics.config),
        "scenes_together": adapter.env.physics.concurrent_scenes,
        "kernel_build_s": kernel_build_s,
        "median_ms_per_step": levels,
    }
    mode = f"-{args.graph_mode.replace('_', '-')}" if args.graph_mode else ""
    name = f"profile-adapter-{args.set.replace(':', '_')}-{envs.num_envs}{mode}"
    out = result_path("profile", name, ".json")
    out.write_text(json.dumps(result, indent=2))
    print(f"-> {out}")


if __name__ == "__main__":
    main()
