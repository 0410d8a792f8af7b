#!/usr/bin/env python
"""Record the reference's goal variants (`rand_vec`s) of its benchmarks (metaworld==3.1.1).

Runs in the reference venv (see tools/README_reference.md); never imports mwjax. For each
benchmark and seed it builds the reference's own `Benchmark` object and stores, per split and
task, the 50 `rand_vec`s in the order of `train_tasks` / `test_tasks`.

    .venv-ref/bin/python tools/record_goal_variants.py   # -> tests/fixtures/reference/goal_variants.npz

Keys: "<benchmark>/<seed>/<split>/<task>", benchmark "MT10", "ML45", ... or "ML1:<task>".

Sampling calls `env.reset()` 50 times per task, and every reset simulates the hand settling
(250+ physics steps), about 20 s per task. The physics draws no random numbers, so by default
`SawyerXYZEnv.do_simulation` only refreshes kinematics while sampling (10x faster);
`--full-physics` keeps it, and `--check` records MT10 and ML1 both ways and asserts equality.
"""

from __future__ import annotations

import argparse
import json
import pickle
import shlex
import sys
from importlib import metadata

import metaworld
import mujoco
import numpy as np
from metaworld.sawyer_xyz_env import SawyerXYZEnv

SEEDS = (0, 1, 42)
BENCHMARKS = {
    "MT10": SEEDS,
    "MT50": SEEDS,
    "ML10": SEEDS,
    "ML45": SEEDS,
    "MT25": (0,),
    "ML25": (0,),
    "ML1:pick-place-v3": SEEDS,
    "ML1:door-lock-v3": SEEDS,
    "ML1:bin-picking-v3": (42,),
}


def build(name: str, seed: int) -> metaworld.Benchmark:
    if name.startswith("ML1:"):
        return metaworld.ML1(name[4:], seed=seed)
    return getattr(metaworld, name)(seed=seed)


def _kinematics_only(env: SawyerXYZEnv, ctrl: object, n_frames: int | None = None) -> None:
    mujoco.mj_forward(env.model, env.data)  # observations still need valid frames


def record(benchmarks: dict[str, tuple[int, ...]]) -> dict[str, np.ndarray]:
    arrays: dict[str, np.ndarray] = {}
    for name, seeds in benchmarks.items():
        for seed in seeds:
            bench = build(name, seed)
            for split, tasks in (("train", bench.train_tasks), ("test", bench.test_tasks)):
                per_task: dict[str, list[np.ndarray]] = {}
                for task in tasks:
                    per_task.setdefault(task.env_name, []).append(pickle.loads(task.data)["rand_vec"])
                for task_name, vecs in per_task.items():
                    arrays[f"{name}/{seed}/{split}/{task_name}"] = np.stack(vecs)
            print(name, seed, flush=True)
    return arrays


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--out", default="tests/fixtures/reference/goal_variants.npz")
    parser.add_argument("--full-physics", action="store_true")
    parser.add_argument("--check", action="store_true")
    args = parser.parse_args()
    simulate = SawyerXYZEnv.do_simulation
    if args.check:
        subset = {"MT10": (0,), "ML1:door-lock-v3": (0,)}
        full = record(subset)
        SawyerXYZEnv.do_simulation = _kinematics_only
        fast = record(subset)
        assert full.keys() == fast.keys() and all(np.array_equal(full[k], fast[k]) for k in full)
        print("physics-free sampling gives the same goal variants")
        return
    if not args.full_physics:
        SawyerXYZEnv.do_simulation = _kinematics_only
    arrays = record(BENCHMARKS)
    SawyerXYZEnv.do_simulation = simulate
    meta = {
        "how": " ".join(shlex.quote(a) for a in sys.argv),
        "full_physics": args.full_physics,
        "versions": {p: metadata.version(p) for p in ("metaworld", "mujoco", "numpy")},
    }
    np.savez_compressed(args.out, meta=json.dumps(meta), **arrays)


if __name__ == "__main__":
    main()
