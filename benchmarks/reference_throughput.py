"""The reference's env steps per second: metaworld 3.1.1's own vector env on CPU, random actions.

Runs under the reference's interpreter (metaworld pins mujoco 3.3.0, so it never shares a venv
with mwjax); `throughput.py --vs-reference PYTHON` calls it and prints the ratio.

    python3 -m venv .venv-ref && .venv-ref/bin/pip install metaworld==3.1.1 packaging
    .venv-ref/bin/python benchmarks/reference_throughput.py --set MT10 --steps 500
    python benchmarks/throughput.py --sets MT10 --vs-reference .venv-ref/bin/python

Meta-World's `make_vec` builds one env per task (MT10: 10, MT50: 50, MT1: `--envs`), each in its
own process with `vector_strategy="async"`, as researchers run it. Prints one JSON line.
"""

from __future__ import annotations

import argparse
import json
import os
import time

import gymnasium as gym
import metaworld  # noqa: F401  (registers the Meta-World/ ids)
import numpy as np


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--set", default="MT10", help="MT10, MT50, or MT1:<task>")
    parser.add_argument("--steps", type=int, default=500)
    parser.add_argument("--envs", type=int, default=16, help="MT1 only: envs of the one task")
    args = parser.parse_args()
    if args.set.startswith("MT1:"):
        envs = gym.make_vec(
            "Meta-World/MT1", env_name=args.set[4:], num_envs=args.envs, vector_strategy="async", seed=0
        )
    else:
        envs = gym.make_vec(f"Meta-World/{args.set}", vector_strategy="async", seed=0)
    rng = np.random.default_rng(0)
    envs.reset(seed=0)
    actions = rng.uniform(-1, 1, size=(args.steps, envs.num_envs, 4)).astype(np.float32)
    envs.step(actions[0])  # the workers' first step outside the timing
    start = time.perf_counter()
    for action in actions:
        envs.step(action)
    elapsed = time.perf_counter() - start
    envs.close()
    print(
        json.dumps(
            {
                "benchmark": args.set,
                "num_envs": envs.num_envs,
                "steps": args.steps,
                "env_steps_per_s": envs.num_envs * args.steps / elapsed,
                "cpu_cores": os.cpu_count(),
                "vector_strategy": "async",
            }
        )
    )


if __name__ == "__main__":
    main()
