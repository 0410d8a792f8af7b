#!/usr/bin/env python
"""Record compact whole-episode fixtures from the original Meta-World (metaworld==3.1.1).

Runs in the reference venv (see tools/README_reference.md); never imports mwjax. The episodes
are exactly those of ``tools/record_reference.py`` (it is imported and its ``record_task`` does
the recording: ``metaworld.MT1(task, seed)``, goal variants ``bench.train_tasks[r]``, v2 and v1
envs stepped in lockstep, resets 0-1 uniform random actions, resets >= 2 the reference expert +
N(0, 0.1), RNG ``np.random.default_rng([seed, task index, r])``). Only what a whole-episode
comparison needs is kept, mostly as float32, so that all 50 tasks fit in a few MB.

Per task ``<out>/<task>.npz`` holds:

    meta                      0-d str, JSON: versions, seed, R, T, task, how (command line), ...
    rand_vec                  (R, d) float64   the goal/object vector after reset
    reset_qpos, reset_qvel    (R, nq/nv) float64   env.data after reset()
    reset_qacc_warmstart      (R, nv) float64      (the solver's warm start; replays need it to be exact)
    reset_mocap_pos/quat      (R, nmocap, 3/4) float64
    reset_obs                 (R, 39) float64  obs returned by reset()
    body_pos_moved            (R, len(meta["moved_bodies"]), 3) float64  model.body_pos rows
    site_pos_moved            (R, len(meta["moved_sites"]), 3) float64   model.site_pos rows
    action                    (R, T, 4) float32
    obs                       (R, T, 39) float32   obs returned by step() of the v2 env
    reward_v2, reward_v1      (R, T) float32
    success_v2, success_v1    (R, T) bool

Usage (from the repo root):

    .venv-ref/bin/python tools/record_episodes.py --tasks all --seed 1 --out tests/fixtures/episodes
    .venv-ref/bin/python tools/record_episodes.py --tasks reach-v3 push-v3 --seed 7 --out /tmp/ep7

Options: ``--tasks NAME...|all`` (default all), ``--seed`` (1), ``--resets`` R (4),
``--steps`` T (200), ``--out`` (tests/fixtures/episodes). Given the same versions the arrays are
bit-identical from run to run (only ``meta["how"]`` and the zip timestamps can differ).
"""

from __future__ import annotations

import argparse
import json
import os
import shlex
import sys
import time

import metaworld.env_dict as mw_env_dict
import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import record_reference  # noqa: E402  (tools/record_reference.py)

META_KEYS = [
    "metaworld_version",
    "mujoco_version",
    "numpy_version",
    "scipy_version",
    "gymnasium_version",
    "python_version",
    "seed",
    "task_name",
    "task_index_in_ALL_V3_ENVIRONMENTS",
    "env_class",
    "R",
    "T",
    "action_source_per_reset",
    "action_rng",
    "policy",
    "policy_noise_sd",
    "nq",
    "nv",
    "nmocap",
    "moved_bodies",
    "moved_sites",
    "success_steps",
    "success_v1_v2_disagree_steps",
    "stale_kinematics_after_reset",
]


def compact(full: dict, full_meta: dict, how: str) -> dict:
    """The episode-level subset of a ``record_reference.record_task`` result."""
    meta = {k: full_meta[k] for k in META_KEYS}
    meta["recorded_by"] = "tools/record_reference.py record_task, compacted by tools/record_episodes.py"
    meta["how"] = how
    names = full_meta["body_names"]
    sites = full_meta["site_names"]
    body_rows = [names.index(n) for n in full_meta["moved_bodies"]]
    site_rows = [sites.index(n) for n in full_meta["moved_sites"]]
    out = {
        "meta": np.array(json.dumps(meta, sort_keys=True)),
        "rand_vec": full["rand_vec"],
        "reset_qpos": full["reset_qpos"],
        "reset_qvel": full["reset_qvel"],
        "reset_qacc_warmstart": full["reset_qacc_warmstart"],
        "reset_mocap_pos": full["reset_mocap_pos"],
        "reset_mocap_quat": full["reset_mocap_quat"],
        "reset_obs": full["reset_obs"],
        "body_pos_moved": full["body_pos"][:, body_rows],
        "site_pos_moved": full["site_pos"][:, site_rows],
        "action": full["action"].astype(np.float32),
        "obs": full["obs"].astype(np.float32),
    }
    for v in ("v2", "v1"):
        out[f"reward_{v}"] = full[f"reward_{v}"].astype(np.float32)
        success = full[f"success_{v}"]
        assert np.all((success == 0.0) | (success == 1.0))
        out[f"success_{v}"] = success.astype(np.bool_)
    return out


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--tasks", nargs="+", default=["all"], help="task names (e.g. reach-v3) or 'all'")
    p.add_argument("--out", default="tests/fixtures/episodes")
    p.add_argument("--seed", type=int, default=1)
    p.add_argument("--resets", type=int, default=4)
    p.add_argument("--steps", type=int, default=200)
    args = p.parse_args(argv)

    all_tasks = list(mw_env_dict.ALL_V3_ENVIRONMENTS.keys())
    tasks = all_tasks if args.tasks == ["all"] else args.tasks
    for t in tasks:
        if t not in all_tasks:
            p.error(f"unknown task {t}")
    os.makedirs(args.out, exist_ok=True)
    how = "python tools/record_episodes.py " + " ".join(
        shlex.quote(a) for a in (sys.argv[1:] if argv is None else argv)
    )
    total = 0
    start = time.perf_counter()
    for t in tasks:
        full, full_meta = record_reference.record_task(t, args.seed, args.resets, args.steps, how)
        out = compact(full, full_meta, how)
        path = os.path.join(args.out, f"{t}.npz")
        np.savez_compressed(path, **out)
        size = os.path.getsize(path)
        total += size
        print(
            f"{t:28s} {size / 1024:6.1f} KiB  success steps v2/v1 = "
            f"{int(out['success_v2'].sum())}/{int(out['success_v1'].sum())}",
            flush=True,
        )
    print(f"{len(tasks)} tasks, total {total / 1024 / 1024:.2f} MiB, {time.perf_counter() - start:.0f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
