#!/usr/bin/env python
"""The most constraint rows (`data.nefc`) and contacts (`data.ncon`) MuJoCo C reaches per env
under the reference scripted experts and under uniform random actions: what the per-env
constraint buffer of each scene has to hold. Also the most geom pairs in contact at once that
MuJoCo Warp sends to its convex collider (GJK/EPA), counted per pair of geom types: each such
pair takes one slot of Warp's CCD scratch, which is pooled per pair of types.

Runs in the reference venv (see tools/README_reference.md); never imports mwjax. For each task:
`gym.make("Meta-World/MT1", env_name=task, seed=0)`, `--episodes` episodes of `--steps` expert
steps and as many of random actions (numpy seed 0), rows and contacts read after every substep.

    .venv-ref/bin/python tools/reference_constraint_rows.py
        # -> benchmarks/results/reference/reference-constraint-rows-cpu-<date>.md
        # -> mwjax/models/constraint_rows.json (per scene: the most over its tasks)
"""

from __future__ import annotations

import argparse
import datetime
import json
from pathlib import Path

import gymnasium as gym
import metaworld  # noqa: F401  (registers the Meta-World/ ids)
import mujoco
import numpy as np
from metaworld.policies import ENV_POLICY_MAP

ROOT = Path(__file__).parents[1]

# MuJoCo Warp's primitive colliders (`collision_driver.py`), as unordered pairs of `mjtGeom`
# values; box-box among them because mwjax sends box pairs to Warp's port of `mjc_BoxBox`. Every
# other pair in contact goes through the convex collider and needs a CCD slot.
_G = mujoco.mjtGeom
PRIMITIVE_PAIRS = {
    tuple(sorted((int(a), int(b))))
    for a, others in {
        _G.mjGEOM_PLANE: (
            _G.mjGEOM_SPHERE,
            _G.mjGEOM_CAPSULE,
            _G.mjGEOM_ELLIPSOID,
            _G.mjGEOM_CYLINDER,
            _G.mjGEOM_BOX,
            _G.mjGEOM_MESH,
        ),
        _G.mjGEOM_SPHERE: (_G.mjGEOM_SPHERE, _G.mjGEOM_CAPSULE, _G.mjGEOM_CYLINDER, _G.mjGEOM_BOX),
        _G.mjGEOM_CAPSULE: (_G.mjGEOM_CAPSULE, _G.mjGEOM_BOX),
        _G.mjGEOM_BOX: (_G.mjGEOM_BOX,),
    }.items()
    for b in others
}


def ccd_pairs(model: mujoco.MjModel, data: mujoco.MjData) -> int:
    """The most distinct geom pairs in contact that share one pair of geom types and go through
    Warp's convex collider."""
    geoms = np.sort(data.contact.geom[: data.ncon], axis=1)
    types = np.sort(model.geom_type[geoms], axis=1)
    convex = np.array([tuple(t) not in PRIMITIVE_PAIRS for t in types.tolist()], dtype=bool)
    if not convex.any():
        return 0
    pairs = np.unique(np.concatenate([types, geoms], axis=1)[convex], axis=0)
    _, counts = np.unique(pairs[:, :2], axis=0, return_counts=True)
    return int(counts.max())


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--tasks", nargs="+", default=sorted(ENV_POLICY_MAP))
    parser.add_argument("--episodes", type=int, default=3)
    parser.add_argument("--steps", type=int, default=300)
    args = parser.parse_args()
    date = datetime.date.today().isoformat()
    lines = [
        f"# Constraint rows and contacts per env under the reference experts and random actions "
        f"(MuJoCo C {mujoco.__version__})",
        "",
        f"`tools/reference_constraint_rows.py`, metaworld 3.1.1, seed 0, {args.episodes} episodes of "
        f"{args.steps} steps each of the expert and of random actions, after every substep, CPU, {date}.",
        "",
        "| task | scene | max rows, expert | max rows, random | max contacts | max CCD pairs |",
        "| --- | --- | ---: | ---: | ---: | ---: |",
    ]
    rng = np.random.default_rng(0)
    scenes: dict[str, dict] = {}
    for task in args.tasks:
        env = gym.make("Meta-World/MT1", env_name=task, seed=0)
        policy, unwrapped = ENV_POLICY_MAP[task](), env.unwrapped
        model, data = unwrapped.model, unwrapped.data
        most = {"expert": 0, "random": 0}
        seen = {"rows": 0, "contacts": 0, "ccd_pairs": 0}

        def stepped(ctrl, n_frames, model=model, data=data, seen=seen):  # gymnasium's, watched
            data.ctrl[:] = ctrl
            for _ in range(n_frames):
                mujoco.mj_step(model, data)
                seen["rows"] = max(seen["rows"], data.nefc)
                seen["contacts"] = max(seen["contacts"], data.ncon)
                seen["ccd_pairs"] = max(seen["ccd_pairs"], ccd_pairs(model, data))
            mujoco.mj_rnePostConstraint(model, data)

        unwrapped._step_mujoco_simulation = stepped
        for kind in most:
            seen["rows"] = 0
            for _ in range(args.episodes):
                obs, _ = env.reset()
                for _ in range(args.steps):
                    if kind == "expert":
                        obs, *_ = env.step(np.clip(policy.get_action(obs), -1.0, 1.0))
                    else:
                        obs, *_ = env.step(rng.uniform(-1.0, 1.0, 4))
            most[kind] = seen["rows"]
        contacts, ccd = seen["contacts"], seen["ccd_pairs"]
        scene = Path(unwrapped.model_name).name
        lines.append(f"| {task} | {scene} | {most['expert']} | {most['random']} | {contacts} | {ccd} |")
        print(lines[-1], flush=True)
        entry = scenes.setdefault(scene, {"max_rows": 0, "max_contacts": 0, "max_ccd_pairs": 0, "tasks": []})
        entry["max_rows"] = max(entry["max_rows"], *most.values())
        entry["max_contacts"] = max(entry["max_contacts"], contacts)
        entry["max_ccd_pairs"] = max(entry["max_ccd_pairs"], ccd)
        entry["tasks"].append(task)
    out = ROOT / "benchmarks" / "results" / "reference" / f"reference-constraint-rows-cpu-{date}.md"
    out.write_text("\n".join(lines) + "\n")
    table = ROOT / "mwjax" / "models" / "constraint_rows.json"
    source = f"tools/reference_constraint_rows.py, metaworld 3.1.1 on mujoco {mujoco.__version__}, {date}"
    table.write_text(json.dumps({"source": source, "scenes": dict(sorted(scenes.items()))}, indent=1) + "\n")
    print(f"-> {out}, {table}")


if __name__ == "__main__":
    main()
