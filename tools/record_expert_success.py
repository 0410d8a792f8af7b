#!/usr/bin/env python
"""The reference scripted experts' success rates and the serial reference's wall time.

Runs in the reference venv (see tools/README_reference.md); never imports mwjax. For every v3
task: `metaworld.MT1(task, seed=42)`, one episode per goal variant (50), each up to 500 steps,
success if the task reports success at any step (the episode ends there, as with the
reference's `terminate_on_success` evaluation). One process, one env at a time: the serial
protocol that `benchmarks/experts.py` is compared against.

    .venv-ref/bin/python tools/record_expert_success.py
    # -> benchmarks/results/reference/reference-experts-seed42.json
"""

from __future__ import annotations

import argparse
import json
import platform
import time
import warnings
from importlib import metadata

import metaworld
import metaworld.env_dict as mw_env_dict
import metaworld.policies as mw_policies
import numpy as np


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--out", default="benchmarks/results/reference/reference-experts-seed42.json")
    parser.add_argument("--seed", type=int, default=42)
    parser.add_argument("--steps", type=int, default=500)
    args = parser.parse_args()
    warnings.filterwarnings("ignore")
    rates: dict[str, float] = {}
    env_steps = 0
    start = time.perf_counter()
    for task in mw_env_dict.ALL_V3_ENVIRONMENTS:
        bench = metaworld.MT1(task, seed=args.seed)
        env = bench.train_classes[task]()
        policy = mw_policies.ENV_POLICY_MAP[task]()
        solved = []
        for goal in bench.train_tasks:
            env.set_task(goal)
            obs, _ = env.reset()
            success = False
            for _ in range(args.steps):
                obs, _, _, _, info = env.step(np.clip(policy.get_action(obs), -1.0, 1.0))
                env_steps += 1
                if info["success"]:
                    success = True
                    break
            solved.append(success)
        rates[task] = float(np.mean(solved))
        print(f"{task:32s} {rates[task]:.2f}", flush=True)
    wall = time.perf_counter() - start
    result = {
        "what": "reference experts, MT1(task, seed) goal variants, one episode each, success at any step",
        "seed": args.seed,
        "max_steps": args.steps,
        "success_rate": rates,
        "mean_success_rate": float(np.mean(list(rates.values()))),
        "env_steps": env_steps,
        "wall_seconds": wall,
        "machine": f"{platform.processor() or platform.machine()}, one process (serial)",
        "date": time.strftime("%Y-%m-%d"),
        "versions": {p: metadata.version(p) for p in ("metaworld", "mujoco", "numpy")},
    }
    with open(args.out, "w") as f:
        json.dump(result, f, indent=1)


if __name__ == "__main__":
    main()
