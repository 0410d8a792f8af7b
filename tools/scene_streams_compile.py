"""How long the env step takes to lower and to compile with its scenes' Warp calls in turn and
issued together (`PhysicsConfig.concurrent_scenes`), JAX's persistent cache off, each mode in a
fresh process. On the CPU this times XLA's passes over the program's FFI calls (the GPU's compile
follows the same passes and adds its own):

    python tools/scene_streams_compile.py --set MT10 --out scene-streams-compile-MT10.json

Each mode's row also lists the XLA passes that took longest over the step's module (`slowest_passes`,
seconds summed over every run of a pass), from XLA's own pass timing log.
"""

from __future__ import annotations

import argparse
import collections
import json
import os
import re
import subprocess
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).parents[1]))
from benchmarks.common import add_set_argument, provenance  # noqa: E402

CHILD = """
import json, sys, time
import jax, jax.numpy as jnp
import mwjax
from benchmarks.common import tasks_arg
name, envs_per_task, together = sys.argv[1], int(sys.argv[2]), sys.argv[3] == "1"
env = mwjax.make(tasks_arg(name), envs_per_task=envs_per_task,
                 physics=mwjax.PhysicsConfig(concurrent_scenes=together))
state = jax.jit(env.reset)(jax.random.key(0))
actions = jnp.zeros((env.num_envs, 4))
t0 = time.perf_counter()
lowered = jax.jit(env.step).lower(state, actions)
t1 = time.perf_counter()
lowered.compile()
t2 = time.perf_counter()
print(json.dumps({"lower_s": round(t1 - t0, 2), "compile_s": round(t2 - t1, 2),
                  "ffi_calls": lowered.as_text().count("stablehlo.custom_call")}))
"""


# Set before jaxlib loads: XLA then logs each pass's time to stderr.
PASS_LOG_ENV = {"TF_CPP_MIN_LOG_LEVEL": "0", "TF_CPP_VMODULE": "hlo_pass_pipeline=1"}
# XLA logs each pipeline's module, then each pass's time, when hlo_pass_pipeline logs at level 1.
_PIPELINE = re.compile(r"Running HLO pass pipeline on module (\S+?):")
_PASS = re.compile(r"HLO pass: (.+?) time: ([0-9.]+) (us|ms|s) ")
_UNIT_S = {"us": 1e-6, "ms": 1e-3, "s": 1.0}


def slowest_passes(log: str, module: str = "jit_step", top: int = 8) -> list[tuple[str, float]]:
    """The `top` passes that took longest over `module` in XLA's pass log, seconds summed."""
    seconds: collections.Counter[str] = collections.Counter()
    current = None
    for line in log.splitlines():
        if pipeline := _PIPELINE.search(line):
            current = pipeline.group(1)
        elif current == module and (timed := _PASS.search(line)):
            seconds[timed.group(1)] += float(timed.group(2)) * _UNIT_S[timed.group(3)]
    return [(name, round(s, 3)) for name, s in seconds.most_common(top)]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    add_set_argument(parser, default="MT10")
    parser.add_argument("--envs-per-task", type=int, default=1)
    parser.add_argument("--out", default=None, help="JSON path")
    args = parser.parse_args()
    root = Path(__file__).parents[1]
    path = f"{root}{os.pathsep}{os.environ.get('PYTHONPATH', '')}"
    env = dict(os.environ, MWJAX_NO_CACHE="1", PYTHONPATH=path, **PASS_LOG_ENV)
    rows = {}
    for mode, flag in (("in_turn", "0"), ("together", "1")):
        command = [sys.executable, "-c", CHILD, args.set, str(args.envs_per_task), flag]
        run = subprocess.run(command, env=env, capture_output=True, text=True, check=True)
        rows[mode] = json.loads(run.stdout.strip().splitlines()[-1])
        rows[mode]["slowest_passes"] = slowest_passes(run.stderr)
        print(mode, json.dumps(rows[mode]), flush=True)
    row = {"set": args.set, "envs_per_task": args.envs_per_task, "modes": rows, **provenance()}
    print(json.dumps(row))
    if args.out:
        Path(args.out).write_text(json.dumps(row, indent=1) + "\n")


if __name__ == "__main__":
    main()
