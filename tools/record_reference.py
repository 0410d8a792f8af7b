#!/usr/bin/env python
"""Record reference trajectories from the original Meta-World (metaworld==3.1.1).

This script runs in a SEPARATE virtual environment that has the reference
implementation installed (metaworld 3.1.1, which pins mujoco 3.3.0). It must not
import anything from ``mwjax``; it only uses metaworld, mujoco, numpy, gymnasium
and scipy. See ``tools/README_reference.md``.

For every task it builds the benchmark the real way (``metaworld.MT1``), creates
two envs of the task class (reward_function_version "v2" and "v1"), and for each
of R resets (goal variants ``bench.train_tasks[r]``) steps both envs with the same
actions for T steps. Resets 0,1 use uniform random actions; resets 2,3 (and any
further) use the reference scripted expert (``metaworld.policies``) plus Gaussian
noise (sd 0.1). Everything is written to ``<out>/<task>.npz``.

Usage:
    .venv-ref/bin/python tools/record_reference.py            # the 10 default tasks
    .venv-ref/bin/python tools/record_reference.py --tasks all # all 50 v3 tasks
"""

from __future__ import annotations

import argparse
import inspect
import json
import os
import shlex
import sys
import warnings
from importlib import metadata as importlib_metadata

import gymnasium
import metaworld
import metaworld.env_dict as mw_env_dict
import metaworld.policies as mw_policies
import mujoco
import numpy as np
import scipy

DEFAULT_TASKS = [
    "reach-v3",
    "push-v3",
    "pick-place-v3",
    "door-open-v3",
    "drawer-open-v3",
    "drawer-close-v3",
    "button-press-topdown-v3",
    "peg-insert-side-v3",
    "window-open-v3",
    "window-close-v3",
]

# Episode constants that are always recorded when present & numeric.
EXPLICIT_CONSTS = [
    "obj_init_pos",
    "_target_pos",
    "init_tcp",
    "init_left_pad",
    "init_right_pad",
    "objHeight",
    "heightTarget",
    "maxPlacingDist",
    "maxPushDist",
    "obj_init_angle",
    "peg_head_pos_init",
]
# Attributes that change at reset but are not episode constants (or are recorded
# under another key).
SKIP_CONSTS = {
    "curr_path_length",
    "_last_rand_vec",  # -> rand_vec
    "_prev_obs",  # frame-stack buffer (== reset_obs[:18])
    "_last_stable_obs",
    "init_qpos",
    "init_qvel",
    "num_resets",
}
MAX_CONST_SIZE = 64  # skip "big" arrays
EXPECTED_INFO_KEYS = [
    "near_object",
    "grasp_success",
    "grasp_reward",
    "in_place_reward",
    "obj_to_target",
    "unscaled_reward",
]


# ----------------------------------------------------------------------------
# helpers
# ----------------------------------------------------------------------------
def _is_numeric(v) -> bool:
    if isinstance(v, (bool, np.bool_)):
        return False
    if isinstance(v, (int, float, np.integer, np.floating)):
        return True
    if isinstance(v, np.ndarray):
        return v.dtype.kind in "fiu" and v.size <= MAX_CONST_SIZE
    return False


def _snapshot(v):
    if isinstance(v, np.ndarray):
        return np.array(v, copy=True)
    return v


def _same(a, b) -> bool:
    if isinstance(a, np.ndarray) or isinstance(b, np.ndarray):
        try:
            return (
                np.shape(a) == np.shape(b)
                and np.asarray(a).dtype == np.asarray(b).dtype
                and np.array_equal(a, b)
            )
        except Exception:
            return False
    try:
        return bool(a == b)
    except Exception:
        return False


def _obj_type_for_field(prefix_obj: str, field: str, arr: np.ndarray, model):
    """Best-effort mujoco object type for the rows of a model/data array."""
    prefixes = [
        ("site_", mujoco.mjtObj.mjOBJ_SITE),
        ("geom_", mujoco.mjtObj.mjOBJ_GEOM),
        ("cam_", mujoco.mjtObj.mjOBJ_CAMERA),
        ("light_", mujoco.mjtObj.mjOBJ_LIGHT),
        ("body_", mujoco.mjtObj.mjOBJ_BODY),
        ("jnt_", mujoco.mjtObj.mjOBJ_JOINT),
        ("actuator_", mujoco.mjtObj.mjOBJ_ACTUATOR),
    ]
    for p, t in prefixes:
        if field.startswith(p):
            return t
    if prefix_obj == "data" and not field.startswith("mocap_") and arr.shape[0] == model.nbody:
        return mujoco.mjtObj.mjOBJ_BODY  # xpos, xquat, xipos, subtree_com, cvel, ...
    return None


def _mj_arrays(obj):
    out = {}
    for f in dir(obj):
        if f.startswith("_"):
            continue
        try:
            a = getattr(obj, f)
        except Exception:
            continue
        if isinstance(a, np.ndarray) and a.size > 0:
            out[f] = a
    return out


def find_live_views(env) -> dict:
    """For every ndarray attribute of env, report which env.data / env.model buffer it
    is a view of (np.shares_memory), or whether it aliases the task's rand_vec or
    another attribute."""
    model, data = env.model, env.data
    bufs = [("data", f, a) for f, a in _mj_arrays(data).items()]
    bufs += [("model", f, a) for f, a in _mj_arrays(model).items()]
    attrs = {k: v for k, v in vars(env).items() if isinstance(v, np.ndarray) and v.dtype.kind in "fiu"}
    out = {}
    for k, v in sorted(attrs.items()):
        hits = []
        for which, f, a in bufs:
            if not np.shares_memory(v, a):
                continue
            desc = f"{which}.{f}"
            if a.ndim >= 2:
                off = v.__array_interface__["data"][0] - a.__array_interface__["data"][0]
                row = int(off // a.strides[0])
                t = _obj_type_for_field(which, f, a, model)
                name = mujoco.mj_id2name(model, t, row) if t is not None else None
                desc += f"[{row}]" + (f" ({name})" if name else "")
            hits.append(desc)
        if k != "_last_rand_vec" and env._last_rand_vec is not None:
            if np.shares_memory(v, env._last_rand_vec):
                hits.append("_last_rand_vec (the task's rand_vec!)")
        for k2, v2 in attrs.items():
            if k2 != k and k2 != "_last_rand_vec" and np.shares_memory(v, v2):
                hits.append(f"attr {k2}")
        if hits:
            out[k] = hits
    return out


def model_diffs(env, fresh) -> dict:
    """Model arrays that differ between env.model (after reset) and a freshly loaded
    model of the same XML, with names for body_/site_/geom_ fields."""
    out = {}
    fa = _mj_arrays(fresh)
    for f, a in _mj_arrays(env.model).items():
        b = fa.get(f)
        if b is None or a.shape != b.shape or a.dtype.kind not in "fiub":
            continue
        nan_ok = a.dtype.kind == "f"
        if np.array_equal(a, b, equal_nan=nan_ok):
            continue
        neq = a != b
        if nan_ok:
            neq &= ~(np.isnan(a) & np.isnan(b))
        rows = np.nonzero(np.any(neq.reshape(a.shape[0], -1), axis=1))[0]
        t = _obj_type_for_field("model", f, a, env.model)
        names = [
            (mujoco.mj_id2name(env.model, t, int(r)) if t is not None else None) or str(int(r)) for r in rows
        ]
        out[f] = names
    return out


def names_of(model, objtype, n):
    return [mujoco.mj_id2name(model, objtype, i) or "" for i in range(n)]


def stale_kinematics(env) -> dict:
    """Bodies / sites whose data.xpos / site_xpos would change under mj_kinematics,
    i.e. reset left the kinematics out of date w.r.t. qpos (so reset obs and
    constants computed from xpos lag behind qpos)."""
    d2 = mujoco.MjData(env.model)
    d2.qpos[:] = env.data.qpos
    d2.qvel[:] = env.data.qvel
    if env.model.na:
        d2.act[:] = env.data.act
    d2.mocap_pos[:] = env.data.mocap_pos
    d2.mocap_quat[:] = env.data.mocap_quat
    mujoco.mj_kinematics(env.model, d2)
    out = {}
    for key, a, b, t in (
        ("bodies", d2.xpos, env.data.xpos, mujoco.mjtObj.mjOBJ_BODY),
        ("sites", d2.site_xpos, env.data.site_xpos, mujoco.mjtObj.mjOBJ_SITE),
    ):
        diff = np.nonzero(np.any(a != b, axis=1))[0]
        out[key] = [mujoco.mj_id2name(env.model, t, int(i)) or str(int(i)) for i in diff]
    # init_tcp (set at the end of _reset_hand) vs the tcp of the reset qpos
    init_tcp = getattr(env, "init_tcp", None)
    if init_tcp is not None:
        tcp = (d2.site("rightEndEffector").xpos + d2.site("leftEndEffector").xpos) / 2.0
        out["init_tcp_minus_fk_tcp"] = float(np.max(np.abs(np.asarray(init_tcp) - tcp)))
    return out


def find_policy(task: str):
    """Scripted expert for a task: convert the task name (reach-v3 ->
    SawyerReachV3Policy); fall back to the reference's own ENV_POLICY_MAP for the
    few irregular names (e.g. peg-insert-side-v3 -> SawyerPegInsertionSideV3Policy)."""
    base = task[: -len("-v3")] if task.endswith("-v3") else task
    cand = "Sawyer" + "".join(p.capitalize() for p in base.split("-")) + "V3Policy"
    cls = getattr(mw_policies, cand, None)
    if cls is not None:
        return cls
    return mw_policies.ENV_POLICY_MAP[task]


def make_env(cls, version: str):
    params = inspect.signature(cls.__init__).parameters
    if "reward_function_version" not in params:
        raise TypeError(f"{cls.__name__} has no reward_function_version argument")
    env = cls(reward_function_version=version)
    assert env.reward_function_version == version
    return env


def set_task_fully_observable(env, task) -> None:
    """MT convention: goal visible in obs. set_task() reads partially_observable
    from the task data (MT1 -> False) and, only when the flag changes, deletes the
    cached `sawyer_observation_space` (whose goal bounds are zeros while partially
    observable). step() clips obs to that space, so a stale cache would zero the
    goal. Set the flag and force recomputation of the space."""
    env.set_task(task)
    assert env._partially_observable is False, "MT1 tasks should be fully observable"
    env._partially_observable = False
    env.__dict__.pop("sawyer_observation_space", None)  # cached_property
    sp = env.sawyer_observation_space
    assert np.array_equal(sp.low[-3:], env.goal_space.low)
    assert np.array_equal(sp.high[-3:], env.goal_space.high)


def _counting_reset_model(env):
    orig = env.reset_model
    env._rec_reset_model_calls = 0

    def counted():
        env._rec_reset_model_calls += 1
        return orig()

    env.reset_model = counted  # instance attribute shadows the method


def _tolist(x):
    if x is None:
        return None
    return np.asarray(x, dtype=np.float64).tolist()


# ----------------------------------------------------------------------------
# recording
# ----------------------------------------------------------------------------
def record_task(task: str, seed: int, R: int, T: int, how: str) -> tuple[dict, dict]:
    all_names = list(mw_env_dict.ALL_V3_ENVIRONMENTS.keys())
    task_idx = all_names.index(task)

    bench = metaworld.MT1(task, seed=seed)
    cls = bench.train_classes[task]
    tasks = bench.train_tasks
    assert len(tasks) >= R

    env2 = make_env(cls, "v2")
    env1 = make_env(cls, "v1")
    envs = (env2, env1)
    for e in envs:
        _counting_reset_model(e)
    model, data = env2.model, env2.data
    nq, nv, nu, na, nmocap = model.nq, model.nv, model.nu, model.na, model.nmocap
    nbody, nsite = model.nbody, model.nsite
    fresh = mujoco.MjModel.from_xml_path(env2.fullpath)

    policy_cls = find_policy(task)
    policy = policy_cls()

    rec: dict[str, list] = {}

    def put(key, val):
        rec.setdefault(key, []).append(val)

    const_snaps = []  # per reset: {name: value}
    changed_names: set = set()
    inplace_names: set = set()
    live_views_per_reset = []
    model_diff_per_reset = []
    stale_per_reset = []
    reset_model_calls = []
    notes = []
    goal_clipped_steps = 0
    obs_v1_v2_mismatch_steps = 0
    info_keys = None
    n_success = {"v1": 0, "v2": 0}
    n_success_disagree = 0

    for r in range(R):
        for e in envs:
            set_task_fully_observable(e, tasks[r])

        before = {k: (id(v), _snapshot(v)) for k, v in vars(env2).items()}
        for e in envs:
            e._rec_reset_model_calls = 0
        obs2, _ = env2.reset()
        obs1, _ = env1.reset()
        reset_model_calls.append(env2._rec_reset_model_calls)

        assert np.array_equal(env2.data.qpos, env1.data.qpos), f"{task} r={r}: reset qpos differ"
        assert np.array_equal(obs2, obs1), f"{task} r={r}: reset obs differ"
        assert np.array_equal(env2._last_rand_vec, env1._last_rand_vec)
        goal = env2._get_pos_goal()
        assert np.array_equal(obs2[-3:], goal), f"{task}: reset obs goal != _get_pos_goal()"
        if not np.any(goal):
            notes.append(f"r={r}: goal is all zeros?")

        # ---- reset state
        put("rand_vec", np.array(env2._last_rand_vec, dtype=np.float64))
        put("reset_qpos", data.qpos.copy())
        put("reset_qvel", data.qvel.copy())
        if na:
            put("reset_act", data.act.copy())
        put("reset_mocap_pos", data.mocap_pos.copy())
        put("reset_mocap_quat", data.mocap_quat.copy())
        put("reset_qacc_warmstart", data.qacc_warmstart.copy())
        put("reset_ctrl", data.ctrl.copy())
        put("reset_obs", np.asarray(obs2, dtype=np.float64).copy())
        put("body_pos", model.body_pos.copy())
        put("body_quat", model.body_quat.copy())
        put("site_pos", model.site_pos.copy())

        # ---- episode constants (copied NOW: some are live views of env.data)
        snap = {}
        for k, v in vars(env2).items():
            if k.startswith("_rec_") or k in SKIP_CONSTS or not _is_numeric(v):
                continue
            snap[k] = np.array(v, copy=True)
            if k not in before or before[k][0] != id(v):
                changed_names.add(k)  # (re)assigned during reset
            elif not _same(before[k][1], v):
                inplace_names.add(k)  # same object, new value (e.g. a live view)
        const_snaps.append(snap)
        # v1 env should have identical constants
        for k in snap:
            v1v = getattr(env1, k, None)
            if v1v is None or not _same(np.asarray(v1v), snap[k]):
                notes.append(f"r={r}: const {k} differs between v1 and v2 env")
        live_views_per_reset.append(find_live_views(env2))
        model_diff_per_reset.append(model_diffs(env2, fresh))
        stale_per_reset.append(stale_kinematics(env2))

        # ---- rollout
        rng = np.random.default_rng([seed, task_idx, r])
        use_expert = r >= 2
        obs_prev = obs2
        for t in range(T):
            if use_expert:
                with warnings.catch_warnings():
                    warnings.simplefilter("ignore")
                    a = np.asarray(policy.get_action(obs_prev), dtype=np.float64)
                a = np.clip(a + rng.normal(0.0, 0.1, size=4), -1.0, 1.0).astype(np.float32)
            else:
                a = rng.uniform(-1.0, 1.0, size=4).astype(np.float32)

            o2, rw2, term2, trunc2, info2 = env2.step(a.copy())
            o1, rw1, term1, trunc1, info1 = env1.step(a.copy())
            assert np.array_equal(env2.data.qpos, env1.data.qpos), (
                f"{task} r={r} t={t}: qpos differ between v1 and v2 envs"
            )
            assert not term2 and not term1
            if not np.array_equal(o2, o1):
                obs_v1_v2_mismatch_steps += 1
            if not np.array_equal(o2[-3:], env2._get_pos_goal()):
                goal_clipped_steps += 1

            put("action", a)
            put("qpos", data.qpos.copy())
            put("qvel", data.qvel.copy())
            if na:
                put("act", data.act.copy())
            put("mocap_pos", data.mocap_pos.copy())
            put("mocap_quat", data.mocap_quat.copy())
            put("qacc_warmstart", data.qacc_warmstart.copy())
            put("ctrl", data.ctrl.copy())
            put("obs", np.asarray(o2, dtype=np.float64).copy())
            put("reward_v1", np.float64(rw1))
            put("reward_v2", np.float64(rw2))
            put("success_v1", np.float64(info1["success"]))
            put("success_v2", np.float64(info2["success"]))
            put("truncated", np.bool_(trunc2))
            n_success["v1"] += bool(info1["success"])
            n_success["v2"] += bool(info2["success"])
            n_success_disagree += bool(info1["success"]) != bool(info2["success"])
            keys = sorted(
                k
                for k, v in info2.items()
                if k != "success" and isinstance(v, (int, float, np.integer, np.floating, bool, np.bool_))
            )
            if info_keys is None:
                info_keys = keys
            assert keys == info_keys, f"{task}: info keys changed {keys} vs {info_keys}"
            for k in keys:
                put(f"info_v2_{k}", np.float64(info2[k]))
            obs_prev = o2

    # ---- is reset independent of the env's history? Re-do reset 0 on the v2 env
    # (which has now run R episodes) and compare with what was recorded.
    set_task_fully_observable(env2, tasks[0])
    obs_again, _ = env2.reset()
    history_diffs = []
    if not np.array_equal(obs_again, rec["reset_obs"][0]):
        history_diffs.append("reset_obs")
    for k, cur in (
        ("reset_qpos", data.qpos),
        ("reset_qvel", data.qvel),
        ("reset_qacc_warmstart", data.qacc_warmstart),
        ("reset_mocap_pos", data.mocap_pos),
        ("body_pos", model.body_pos),
        ("site_pos", model.site_pos),
    ):
        if not np.array_equal(cur, rec[k][0]):
            history_diffs.append(k)
    for k, v in const_snaps[0].items():
        if not _same(np.array(getattr(env2, k, None), copy=True), v):
            history_diffs.append(f"const_{k}")

    # ---- assemble arrays
    out: dict[str, np.ndarray] = {}
    per_reset = {
        "rand_vec",
        "reset_qpos",
        "reset_qvel",
        "reset_act",
        "reset_mocap_pos",
        "reset_mocap_quat",
        "reset_qacc_warmstart",
        "reset_ctrl",
        "reset_obs",
        "body_pos",
        "body_quat",
        "site_pos",
    }
    for k, vals in rec.items():
        arr = np.stack(vals)
        if k not in per_reset:
            arr = arr.reshape((R, T) + arr.shape[1:])
        if k == "action":
            arr = arr.astype(np.float32)
        elif k == "truncated":
            arr = arr.astype(np.bool_)
        else:
            arr = arr.astype(np.float64)
        out[k] = arr

    const_names = sorted(
        n for n in (set(EXPLICIT_CONSTS) | changed_names | inplace_names) if all(n in s for s in const_snaps)
    )
    skipped_consts = []
    for n in const_names:
        shapes = {s[n].shape for s in const_snaps}
        if len(shapes) != 1:
            skipped_consts.append(f"{n} (shape varies {shapes})")
            continue
        out[f"const_{n}"] = np.stack([s[n] for s in const_snaps]).astype(np.float64)

    # live views: union over resets
    live_views: dict = {}
    for lv in live_views_per_reset:
        for k, v in lv.items():
            live_views.setdefault(k, [])
            for x in v:
                if x not in live_views[k]:
                    live_views[k].append(x)
    model_changes: dict = {}
    for md in model_diff_per_reset:
        for f, names in md.items():
            cur = model_changes.setdefault(f, [])
            for n in names:
                if n not in cur:
                    cur.append(n)
    stale = {k: sorted({b for s in stale_per_reset for b in s[k]}) for k in ("bodies", "sites")}
    stale["init_tcp_minus_fk_tcp_per_reset"] = [s.get("init_tcp_minus_fk_tcp") for s in stale_per_reset]

    def _space(sp, attr):
        return None if sp is None else _tolist(getattr(sp, attr))

    meta = {
        "metaworld_version": importlib_metadata.version("metaworld"),
        "mujoco_version": mujoco.__version__,
        "scipy_version": scipy.__version__,
        "numpy_version": np.__version__,
        "gymnasium_version": gymnasium.__version__,
        "python_version": sys.version.split()[0],
        "seed": seed,
        "task_name": task,
        "task_index_in_ALL_V3_ENVIRONMENTS": task_idx,
        "env_class": cls.__name__,
        "R": R,
        "T": T,
        "action_source_per_reset": [
            "uniform[-1,1]" if r < 2 else f"{policy_cls.__name__}+N(0,0.1)" for r in range(R)
        ],
        "action_rng": "np.random.default_rng([seed, task_index_in_ALL_V3_ENVIRONMENTS, r])",
        "scene_xml": os.path.basename(env2.fullpath),
        "model_name": os.path.relpath(env2.fullpath, os.path.dirname(metaworld.__file__)),
        "nq": nq,
        "nv": nv,
        "nu": nu,
        "na": na,
        "nmocap": nmocap,
        "nbody": nbody,
        "nsite": nsite,
        "body_names": names_of(model, mujoco.mjtObj.mjOBJ_BODY, nbody),
        "site_names": names_of(model, mujoco.mjtObj.mjOBJ_SITE, nsite),
        "moved_bodies": model_changes.get("body_pos", []),
        "rotated_bodies": model_changes.get("body_quat", []),
        "moved_sites": model_changes.get("site_pos", []),
        "model_fields_changed_vs_fresh_xml": model_changes,
        "timestep": float(model.opt.timestep),
        "frame_skip": int(env2.frame_skip),
        "action_scale": float(env2.action_scale),
        "max_path_length": int(env2.max_path_length),
        "hand_init_pos": _tolist(env2.hand_init_pos),
        "mocap_low": _tolist(env2.mocap_low),
        "mocap_high": _tolist(env2.mocap_high),
        "hand_low": _tolist(env2.hand_low),
        "hand_high": _tolist(env2.hand_high),
        "random_reset_space_low": _space(env2._random_reset_space, "low"),
        "random_reset_space_high": _space(env2._random_reset_space, "high"),
        "goal_space_low": _space(env2.goal_space, "low"),
        "goal_space_high": _space(env2.goal_space, "high"),
        "obs_space_low": _tolist(env2.sawyer_observation_space.low),
        "obs_space_high": _tolist(env2.sawyer_observation_space.high),
        "policy": policy_cls.__name__,
        "policy_module": policy_cls.__module__,
        "policy_noise_sd": 0.1,
        "partially_observable": bool(env2._partially_observable),
        "info_v2_keys": info_keys,
        "const_keys": [k[len("const_") :] for k in out if k.startswith("const_")],
        "const_skipped": skipped_consts,
        "const_assigned_by_reset": sorted(changed_names),
        "const_changed_in_place_by_reset": sorted(inplace_names - changed_names),
        "live_view_attrs": live_views,
        "live_view_consts": sorted(
            k
            for k in live_views
            if f"const_{k}" in out and any(x.startswith(("data.", "model.")) for x in live_views[k])
        ),
        "reset_model_calls_per_reset": reset_model_calls,
        "reset_depends_on_history": history_diffs,
        "stale_kinematics_after_reset": stale,
        "goal_clipped_in_step_obs_steps": goal_clipped_steps,
        "obs_v1_v2_mismatch_steps": obs_v1_v2_mismatch_steps,
        "success_steps": n_success,
        "success_v1_v2_disagree_steps": n_success_disagree,
        "notes": sorted(set(notes)),
        "how": how,
    }
    out["meta"] = np.array(json.dumps(meta, sort_keys=True))
    for e in envs:
        e.close()
    return out, meta


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument(
        "--tasks",
        nargs="+",
        default=DEFAULT_TASKS,
        help="task names (e.g. reach-v3) or 'all' for all 50 v3 tasks",
    )
    p.add_argument("--out", default="tests/fixtures/reference")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--resets", type=int, default=4)
    p.add_argument("--steps", type=int, default=120)
    args = p.parse_args(argv)

    tasks = list(mw_env_dict.ALL_V3_ENVIRONMENTS.keys()) if args.tasks == ["all"] else args.tasks
    for t in tasks:
        if t not in mw_env_dict.ALL_V3_ENVIRONMENTS:
            p.error(f"unknown task {t}")
    os.makedirs(args.out, exist_ok=True)
    how = "python tools/record_reference.py " + " ".join(
        shlex.quote(a) for a in (sys.argv[1:] if argv is None else argv)
    )
    total = 0
    for t in tasks:
        out, meta = record_task(t, args.seed, args.resets, args.steps, how.strip())
        path = os.path.join(args.out, f"{t}.npz")
        np.savez_compressed(path, **out)
        size = os.path.getsize(path)
        total += size
        print(
            f"{t:28s} {size / 1024:7.1f} KiB  moved bodies={meta['moved_bodies']} "
            f"sites={meta['moved_sites']} live={meta['live_view_consts']} "
            f"succ v1/v2={meta['success_steps']['v1']}/{meta['success_steps']['v2']}",
            flush=True,
        )
    print(f"total {total / 1024 / 1024:.2f} MiB")
    return 0


if __name__ == "__main__":
    sys.exit(main())
