"""What JAX's persistent compilation cache saves a fresh process: the env step compiled in two
processes one after the other, over one empty cache directory.

    python benchmarks/compile_cache.py --set MT10 --envs-per-task 2
    python benchmarks/compile_cache.py --set MT50 --envs-per-task 8192   # a GPU

Each process makes the env, then lowers and compiles `jit(env.step)` (timed apart) and says
whether JAX wrote the step to the cache. `--host-callback` adds a Python host callback to the
step under a never-taken `lax.cond`, as the overflow warning was once made: JAX writes no program
holding one, so every process compiles it afresh. `--trace-first SET` makes the second process
trace SET's step before its own, as another script or test order would: the step's Warp calls
must still get the ids they got in the first process (`mwjax.warp_call_ids`; with
`MWJAX_STABLE_CALL_IDS=0`, Warp's counter, they do not, and the cache misses). Writes
`results/compile/compile-cache-<set>-<commit>-<device>-<date>.json`.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from common import commit, provenance, result_path, tasks_arg


def child(args: argparse.Namespace) -> None:
    import jax
    import jax.numpy as jnp

    import mwjax

    jax.config.update("jax_compilation_cache_dir", args.cache_dir)
    if args.trace_first:
        other = mwjax.make(tasks_arg(args.trace_first), envs_per_task=args.envs_per_task)
        other_state = jax.eval_shape(other.reset, jax.random.key(0))
        jax.jit(other.step).lower(other_state, jnp.zeros((other.num_envs, 4)))
    t0 = time.perf_counter()
    env = mwjax.make(tasks_arg(args.set), envs_per_task=args.envs_per_task)
    state = jax.jit(env.reset)(jax.random.key(0))
    jax.block_until_ready(state.obs)
    made = time.perf_counter() - t0

    def step(state: mwjax.State, action: jax.Array) -> mwjax.State:
        state = env.step(state, action)
        if args.host_callback:
            jax.lax.cond(state.steps[0] < 0, lambda: jax.debug.callback(print, 0), lambda: None)
        return state

    actions = jnp.zeros((env.num_envs, 4))
    t0 = time.perf_counter()
    lowered = jax.jit(step).lower(state, actions)
    t1 = time.perf_counter()
    lowered.compile()
    t2 = time.perf_counter()
    written = any(p.name.startswith("jit_step-") for p in Path(args.cache_dir).iterdir())
    print(
        json.dumps(
            {"make_and_reset_s": made, "lower_s": t1 - t0, "compile_s": t2 - t1, "step_cached": written}
        )
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--set", default="MT10", help="a set name, MT1:<task>, or tasks separated by commas")
    parser.add_argument("--envs-per-task", type=int, default=2)
    parser.add_argument("--host-callback", action="store_true", help="add a Python host callback to the step")
    parser.add_argument("--trace-first", help="a set whose step the second process traces before its own")
    parser.add_argument("--child", action="store_true", help=argparse.SUPPRESS)
    parser.add_argument("--cache-dir", help=argparse.SUPPRESS)
    args = parser.parse_args()
    from mwjax import warp_call_ids

    if args.child:
        child(args)
        return
    runs = []
    with tempfile.TemporaryDirectory() as cache_dir:
        for process in ("first", "second"):
            command = [sys.executable, __file__, "--child", "--cache-dir", cache_dir, "--set", args.set]
            command += ["--envs-per-task", str(args.envs_per_task)] + ["--host-callback"] * args.host_callback
            if process == "second" and args.trace_first:
                command += ["--trace-first", args.trace_first]
            out = subprocess.run(command, capture_output=True, text=True, check=True).stdout
            runs.append({"process": process, **json.loads(out.strip().splitlines()[-1])})
            print(runs[-1], flush=True)
    result = {
        **provenance(),
        "set": args.set,
        "envs_per_task": args.envs_per_task,
        "host_callback": args.host_callback,
        "trace_first": args.trace_first,
        "stable_call_ids": warp_call_ids.enabled(),
        "runs": runs,
    }
    name = f"compile-cache-{args.set.replace(':', '-')}" + ("-host-callback" * args.host_callback)
    if args.trace_first:
        name += f"-after-{args.trace_first.replace(':', '-')}"
        name += "" if warp_call_ids.enabled() else "-warp-counter"
    path = result_path("compile", name, ".json")
    path.write_text(json.dumps(result, indent=2) + "\n")
    print(f"-> {path} ({commit()[:7]})")


if __name__ == "__main__":
    main()
