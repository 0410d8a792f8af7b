#!/usr/bin/env python
"""Engine-only baseline: replay episode fixtures on the reference code with a newer MuJoCo.

Runs in a scratch venv with metaworld 3.1.1 forced onto MuJoCo 3.17 (how to build it:
``tools/reference_on_mujoco317.py``), never in the reference venv and never with mwjax. Every
model gets MuJoCo 3.3.0's engine defaults back (multi-contact CCD and constraint islands off,
50 CCD iterations), as mwjax's scenes do, so what differs from the reference is the engine
version alone.

For each task and reset r of a ``tools/record_episodes.py`` fixture directory it builds the envs
like the recorder (``metaworld.MT1(task, seed)`` with the fixture's seed, v2 and v1 envs,
``set_task(bench.train_tasks[r])``, fully observable), calls ``reset()``, asserts that it is
the same goal (``_last_rand_vec`` and the ``model.body_pos`` rows of the bodies the reset moves
are bit-identical, so are the x, y of the moved ``site_pos`` rows; their z may differ by up to
1e-4, because push, push-back and push-wall put the goal at the object's height as simulated
during the reset; the sets of moved bodies / sites and the reset mocap pose), then
overwrites the state with the fixture's recorded reset state: ``set_state(reset_qpos,
reset_qvel)`` (which calls ``mj_forward``), then ``data.qacc_warmstart = reset_qacc_warmstart``
(``mj_forward`` rewrites the warm start, and a 1e-14 change of it is enough to make e.g. reach's
puck orientation drift by 2e-3 within 200 steps; ``--qpos-qvel-only`` skips this), and the
frame-stack buffer ``_prev_obs = reset_obs[:18]``, so that the first step's previous-frame half
is the reference's. Episode constants (``init_tcp``, ``obj_init_pos``, ``_target_pos``, ...) are
the env's own, from its own reset on this engine. Then it replays the fixture's actions for T
steps.

Per task ``<out>/<task>.npz``: ``reward_v2``, ``reward_v1`` (R, T) float32, ``success_v2``,
``success_v1`` (R, T) bool, ``obs`` (R, T, 39) float32 (v2 env) and ``meta`` (JSON: versions,
the fixture's seed and versions, the engine options, per reset the largest difference between
this engine's own reset and the fixture's (qpos, qvel, obs, moved site_pos), how).

Usage (from the repo root):

    /tmp/ref317/bin/python tools/reference_baseline.py --fixtures tests/fixtures/episodes \
        --out tests/fixtures/episodes_baseline
    /tmp/ref317/bin/python tools/reference_baseline.py --fixtures /tmp/ep7 --out /tmp/ep7_base \
        --tasks reach-v3 push-v3

Run in the reference venv itself (MuJoCo 3.3.0), it must reproduce the fixture bit-exactly (a
self-check of the replay). ``--own-engine-defaults`` keeps the newer engine's own defaults.
The output is deterministic: the same inputs and versions give bit-identical arrays.
"""

from __future__ import annotations

import argparse
import json
import os
import shlex
import sys
import time
from importlib import metadata as importlib_metadata

import gymnasium
import metaworld
import mujoco
import numpy as np
import scipy

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import record_reference  # noqa: E402  (tools/record_reference.py)

CCD_ITERATIONS_330 = 50
SITE_Z_TOL = 1e-4  # see replay_task


def v330_defaults(model) -> None:
    """MuJoCo 3.3.0's engine defaults that later versions changed (on 3.3.0 itself: nothing to do)."""
    if mujoco.__version__ == "3.3.0":
        return
    off = mujoco.mjtDisableBit
    model.opt.disableflags |= off.mjDSBL_MULTICCD | off.mjDSBL_ISLAND
    model.opt.ccd_iterations = CCD_ITERATIONS_330


def replay_task(
    fixture: dict,
    task: str,
    how: str,
    own_defaults: bool = False,
    warmstart: bool = True,
    perturb: float = 0.0,
) -> dict:
    fmeta = json.loads(str(fixture["meta"]))
    assert fmeta["task_name"] == task
    R, T = int(fmeta["R"]), int(fmeta["T"])
    bench = metaworld.MT1(task, seed=int(fmeta["seed"]))
    cls = bench.train_classes[task]
    env2 = record_reference.make_env(cls, "v2")
    env1 = record_reference.make_env(cls, "v1")
    envs = (env2, env1)
    if not own_defaults:
        for e in envs:
            v330_defaults(e.model)
    model, data = env2.model, env2.data
    fresh = mujoco.MjModel.from_xml_path(env2.fullpath)
    body_ids = [model.body(n).id for n in fmeta["moved_bodies"]]
    site_ids = [model.site(n).id for n in fmeta["moved_sites"]]

    out = {k: np.zeros((R, T), np.float32) for k in ("reward_v2", "reward_v1")}
    out.update({k: np.zeros((R, T), np.bool_) for k in ("success_v2", "success_v1")})
    out["obs"] = np.zeros((R, T, 39), np.float32)
    own_reset = []
    for r in range(R):
        qpos0, qvel0 = fixture["reset_qpos"][r], fixture["reset_qvel"][r]
        prev_obs0 = np.asarray(fixture["reset_obs"][r][:18], np.float64)
        for e in envs:
            record_reference.set_task_fully_observable(e, bench.train_tasks[r])
            obs_own, _ = e.reset()
            # the same goal as the fixture's
            assert np.array_equal(e._last_rand_vec, fixture["rand_vec"][r]), f"{task} r={r}: rand_vec"
            assert np.array_equal(e.model.body_pos[body_ids], fixture["body_pos_moved"][r]), (
                f"{task} r={r}: body_pos of {fmeta['moved_bodies']}"
            )
            # push, push-back, push-wall: the goal site's z is the object's height as simulated
            # during the reset (objGeom xpos), so it moves with the engine (by ~3e-5 on 3.17)
            site_gap = e.model.site_pos[site_ids] - fixture["site_pos_moved"][r]
            assert np.array_equal(site_gap[:, :2], np.zeros_like(site_gap[:, :2])), (
                f"{task} r={r}: site_pos x, y of {fmeta['moved_sites']}"
            )
            assert np.all(np.abs(site_gap[:, 2]) <= SITE_Z_TOL), f"{task} r={r}: site_pos z {site_gap[:, 2]}"
            diffs = record_reference.model_diffs(e, fresh)
            assert diffs.get("body_pos", []) == fmeta["moved_bodies"], f"{task} r={r}: moved bodies"
            assert diffs.get("site_pos", []) == fmeta["moved_sites"], f"{task} r={r}: moved sites"
            assert np.array_equal(e.data.mocap_pos, fixture["reset_mocap_pos"][r])
            assert np.array_equal(e.data.mocap_quat, fixture["reset_mocap_quat"][r])
            if e is env2:
                own_reset.append(
                    {
                        "qpos_max_abs_diff": float(np.max(np.abs(e.data.qpos - qpos0))),
                        "qvel_max_abs_diff": float(np.max(np.abs(e.data.qvel - qvel0))),
                        "obs_max_abs_diff": float(np.max(np.abs(obs_own - fixture["reset_obs"][r]))),
                        "moved_site_pos_max_abs_diff": float(np.max(np.abs(site_gap), initial=0.0)),
                    }
                )
            # the fixture's reset state
            # --perturb: the reference's own sensitivity, every joint speed nudged by `perturb`
            e.set_state(qpos0, qvel0 + perturb)  # -> mj_forward
            if warmstart:
                e.data.qacc_warmstart[:] = fixture["reset_qacc_warmstart"][r]
            e._prev_obs = prev_obs0.copy()
        for t in range(T):
            a = np.array(fixture["action"][r, t], dtype=np.float32)
            o2, rw2, _, _, info2 = env2.step(a.copy())
            _, rw1, _, _, info1 = env1.step(a.copy())
            assert np.array_equal(env2.data.qpos, env1.data.qpos), f"{task} r={r} t={t}: v1/v2 qpos"
            out["obs"][r, t] = o2
            out["reward_v2"][r, t] = rw2
            out["reward_v1"][r, t] = rw1
            out["success_v2"][r, t] = bool(info2["success"])
            out["success_v1"][r, t] = bool(info1["success"])
    assert data is env2.data

    meta = {
        "metaworld_version": importlib_metadata.version("metaworld"),
        "mujoco_version": mujoco.__version__,
        "numpy_version": np.__version__,
        "scipy_version": scipy.__version__,
        "gymnasium_version": gymnasium.__version__,
        "python_version": sys.version.split()[0],
        "engine_options": {
            "restored": "this engine's own defaults"
            if own_defaults or mujoco.__version__ == "3.3.0"
            else "3.3.0's: disableflags |= mjDSBL_MULTICCD | mjDSBL_ISLAND, ccd_iterations = 50",
            "disableflags": int(model.opt.disableflags),
            "ccd_iterations": int(model.opt.ccd_iterations),
        },
        "task_name": task,
        "R": R,
        "T": T,
        "fixture_seed": fmeta["seed"],
        "fixture_versions": {k: fmeta[k] for k in fmeta if k.endswith("_version")},
        "fixture_how": fmeta["how"],
        "state_at_step_0": "fixture reset_qpos/qvel via set_state (mj_forward), "
        + ("then qacc_warmstart = reset_qacc_warmstart, " if warmstart else "")
        + "_prev_obs = reset_obs[:18]",
        "own_reset_vs_fixture": own_reset,
        "how": how,
    }
    out["meta"] = np.array(json.dumps(meta, sort_keys=True))
    for e in envs:
        e.close()
    return out


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--fixtures", default="tests/fixtures/episodes", help="a record_episodes.py output dir")
    p.add_argument("--out", default="tests/fixtures/episodes_baseline")
    p.add_argument("--tasks", nargs="+", default=["all"], help="task names or 'all' (every fixture file)")
    p.add_argument(
        "--own-engine-defaults",
        action="store_true",
        help="keep this MuJoCo's own engine defaults (on 3.3.0 there is nothing to restore anyway)",
    )
    p.add_argument(
        "--qpos-qvel-only",
        action="store_true",
        help="do not restore the fixture's reset qacc_warmstart (keep what mj_forward leaves)",
    )
    p.add_argument(
        "--perturb",
        type=float,
        default=0.0,
        help="add this to every joint speed of the reset state (run on 3.3.0: the reference's own "
        "chaos floor, e.g. 1e-6)",
    )
    args = p.parse_args(argv)

    if args.tasks == ["all"]:
        tasks = sorted(f[: -len(".npz")] for f in os.listdir(args.fixtures) if f.endswith(".npz"))
    else:
        tasks = args.tasks
    os.makedirs(args.out, exist_ok=True)
    how = "python tools/reference_baseline.py " + " ".join(
        shlex.quote(a) for a in (sys.argv[1:] if argv is None else argv)
    )
    total = 0
    start = time.perf_counter()
    for task in tasks:
        with np.load(os.path.join(args.fixtures, f"{task}.npz")) as z:
            fixture = {k: z[k] for k in z.files}
        out = replay_task(fixture, task, how, args.own_engine_defaults, not args.qpos_qvel_only, args.perturb)
        path = os.path.join(args.out, f"{task}.npz")
        np.savez_compressed(path, **out)
        size = os.path.getsize(path)
        total += size
        agree = float(np.mean(out["success_v2"] == fixture["success_v2"]))
        ret_ref = fixture["reward_v2"].astype(np.float64).sum(axis=1)
        ret = out["reward_v2"].astype(np.float64).sum(axis=1)
        print(
            f"{task:28s} {size / 1024:6.1f} KiB  success_v2 agreement {agree:.3f}  "
            f"returns ref {np.round(ret_ref, 1).tolist()} baseline {np.round(ret, 1).tolist()}",
            flush=True,
        )
    print(f"{len(tasks)} tasks, total {total / 1024 / 1024:.2f} MiB, {time.perf_counter() - start:.0f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
