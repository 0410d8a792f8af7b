"""How long a user waits for a first env step: from `mwjax.make` to the result of `jit(env.step)`,
in this process, each phase timed apart.

    XLA_PYTHON_CLIENT_MEM_FRACTION=0.45 python benchmarks/first_step.py --set MT50 --envs-per-task 1024
    python benchmarks/first_step.py --set reach-v3 --envs-per-task 1          # CPU

Phases: `make` (on a GPU it first builds the scenes' Warp kernels in parallel where Warp's cache
lacks them, `mwjax.kernels.prebuild`), then for the reset and for one step of zero actions: tracing
and lowering, XLA's compile (a read where JAX's persistent cache has the program) and the run.
Run on a fresh machine (empty Warp and JAX caches) it is the cold first step, run again the warm
one. `--concurrent-scenes on|off` sets how the scenes run (default: side by side on one GPU),
`--scenes-per-call N|all` how many go into one call side by side (default: PhysicsConfig's).
Writes `results/compile/first-step-<set>-<commit>-<device>-<date>.json` (or `--out`).
"""

from __future__ import annotations

import argparse
import json
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from common import (
    add_concurrent_scenes_argument,
    add_set_argument,
    commit,
    provenance,
    result_path,
    scene_settings,
    tasks_arg,
)


def timed(phases: dict[str, float], name: str, work: Callable[[], Any]) -> Any:
    """`work()`, its seconds recorded as `phases[name]` and printed."""
    start = time.perf_counter()
    result = work()
    phases[name] = round(time.perf_counter() - start, 2)
    print(f"{name}: {phases[name]:.2f} s", flush=True)
    return result


_CACHE_EVENTS = {"/jax/compilation_cache/cache_hits": "hits", "/jax/compilation_cache/cache_misses": "writes"}


class CacheEvents:
    """What JAX's persistent cache did while listening: entries read (hits), entries written
    (misses of programs worth caching), and the seconds reading took."""

    def __init__(self) -> None:
        self.counts = {"hits": 0, "writes": 0}
        self.read_s = 0.0

    def __enter__(self) -> CacheEvents:
        import jax.monitoring

        jax.monitoring.register_event_listener(self._event)
        jax.monitoring.register_event_duration_secs_listener(self._duration)
        return self

    def __exit__(self, *exc: object) -> None:
        import jax.monitoring

        jax.monitoring.unregister_event_listener(self._event)
        jax.monitoring.unregister_event_duration_listener(self._duration)

    def _event(self, event: str, **kwargs: Any) -> None:
        if event in _CACHE_EVENTS:
            self.counts[_CACHE_EVENTS[event]] += 1

    def _duration(self, event: str, seconds: float, **kwargs: Any) -> None:
        if event == "/jax/compilation_cache/cache_retrieval_time_sec":
            self.read_s += seconds

    def summary(self) -> dict:
        return {**self.counts, "read_s": round(self.read_s, 2)}


def explain_cache_keys() -> None:
    """Print JAX's debug lines on its cache keys: the hash of each part (the program, XLA flags,
    compile options, ...), and each hit or miss with its key."""
    import logging

    handler = logging.StreamHandler()
    handler.setFormatter(logging.Formatter("jax-cache: %(message)s"))
    for name in ("jax._src.cache_key", "jax._src.compiler"):
        logger = logging.getLogger(name)
        logger.setLevel(logging.DEBUG)
        logger.addHandler(handler)


def write_program(path: Path, lowered: Any) -> float:
    """The lowered program's text (without locations) at `path`, to diff with another process's;
    returns the seconds this took, which the total leaves out."""
    start = time.perf_counter()
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(lowered.as_text(debug_info=False))
    return time.perf_counter() - start


def main(argv: list[str] | None = None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    add_set_argument(parser, default="MT50")
    parser.add_argument("--envs-per-task", type=int, default=1024)
    parser.add_argument("--out", type=Path, default=None, help="the result JSON (default: results/compile/)")
    add_concurrent_scenes_argument(parser)
    parser.add_argument(
        "--explain-cache",
        type=Path,
        default=None,
        metavar="DIR",
        help="log the hash of each part of JAX's cache keys and write the lowered reset and step to DIR,"
        " to compare two processes whose cache should have hit",
    )
    args = parser.parse_args(argv)
    if args.explain_cache:
        explain_cache_keys()
    import jax
    import jax.numpy as jnp
    import numpy as np
    import warp

    import mwjax
    from mwjax import progress
    from mwjax.physics import DROPPED

    config = {
        "envs_per_task": args.envs_per_task,
        "physics": mwjax.PhysicsConfig(**scene_settings(args)),
    }
    phases: dict[str, float] = {}
    start = time.perf_counter()
    writing = 0.0  # seconds spent writing programs for --explain-cache
    try:
        env = timed(phases, "make", lambda: mwjax.make(tasks_arg(args.set), **config))
    except ValueError as error:  # a batch that is not a positive int (`set_arg` checked the set)
        parser.error(str(error))
    key = jax.random.key(0)
    reset = timed(phases, "reset_lower", lambda: jax.jit(env.reset).lower(key))
    if args.explain_cache:
        writing += write_program(args.explain_cache / "reset.mlir", reset)
    with CacheEvents() as reset_cache:
        reset = timed(phases, "reset_compile", reset.compile)
    state = timed(phases, "reset_run", lambda: jax.block_until_ready(reset(key)))
    actions = jnp.zeros((env.num_envs, 4))
    step = timed(phases, "step_lower", lambda: jax.jit(env.step).lower(state, actions))
    if args.explain_cache:
        writing += write_program(args.explain_cache / "step.mlir", step)
    with CacheEvents() as step_cache:
        step = timed(phases, "step_compile", step.compile)
    state = timed(phases, "step_run", lambda: jax.block_until_ready(step(state, actions)))
    total = time.perf_counter() - start - writing
    builds = progress.kernel_builds()
    result = {
        **provenance(),
        "set": args.set,
        "envs": env.num_envs,
        "scenes_together": env.physics.concurrent_scenes,  # side by side (the default on one GPU)
        "scenes_per_call": env.physics.config.scenes_per_call,  # None: every scene in one call
        "phases_s": phases,
        "make_to_first_step_s": round(total, 2),
        "kernel_modules_built_in_this_process": builds.built,
        "kernel_modules_loaded_from_cache": builds.cached,
        "warp_cache": warp.config.kernel_cache_dir,
        # Per compile phase: did it read JAX's persistent cache (hits), write to it, and how long
        # reading took (a cached GPU program is fingerprinted as it loads; docs/performance.md).
        "jax_cache": {
            "dir": jax.config.jax_compilation_cache_dir,
            "reset": reset_cache.summary(),
            "step": step_cache.summary(),
        },
        "overflow_envs": int(np.count_nonzero(np.asarray(state.info["physics_overflow"]) & int(DROPPED))),
    }
    print(f"from mwjax.make to the first step's result: {total:.1f} s", flush=True)
    path = args.out or result_path("compile", f"first-step-{args.set.replace(':', '-')}", ".json")
    path.write_text(json.dumps(result, indent=2) + "\n")
    print(f"-> {path} ({commit()[:7]})")
    return result


if __name__ == "__main__":
    main()
