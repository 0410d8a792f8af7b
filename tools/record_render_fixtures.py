#!/usr/bin/env python
"""Record reference images of Meta-World states (metaworld==3.1.1, its own OpenGL renderer).

Runs in the SEPARATE reference venv (`.venv-ref`, see tools/README_reference.md) and never
imports mwjax. It needs an OpenGL backend for MuJoCo: on a machine with Mesa's EGL
(`libegl1 libegl-mesa0 libgl1-mesa-dri`, present on Debian with any desktop GL) run it as

    LIBGL_ALWAYS_SOFTWARE=1 MUJOCO_GL=egl .venv-ref/bin/python tools/record_render_fixtures.py

(`LIBGL_ALWAYS_SOFTWARE=1` makes Mesa's EGL use its software rasteriser, llvmpipe, when the
machine has no GPU; with OSMesa installed, `MUJOCO_GL=osmesa` works too).

For each task it builds `metaworld.MT1(task, seed)`, the env with `render_mode="rgb_array"`
and the reference's rendering kwargs, sets the first train goal, resets, and records:
  - state 0: the reset state;
  - state 1: the state after `--steps` steps of the scripted expert (the arm has moved).
For each state and camera, the image exactly as `env.render()` returns it (gymnasium's
`MujocoRenderer`: OpenGL, 4x MSAA from the scene's `offsamples`, flipped to top-down rows), and
the physics state mwjax needs to render the same scene: qpos, qvel, mocap pose, and the
model's `body_pos` / `body_quat` (reset moves fixed bodies by writing them into the model).

Output: one compressed `<out>/<task>.npz` per task (~50 KB at 64 px):
  qpos (S, nq), qvel (S, nv), mocap_pos (S, nmocap, 3), mocap_quat (S, nmocap, 4),
  body_pos (S, nbody, 3), body_quat (S, nbody, 4), site_xpos (S, nsite, 3) (sites are drawn
  where `data.site_xpos` says, which tasks overwrite for their goal marker), free_lookat (S, 3)
  (the default camera's look-at point, which gymnasium fixes at the viewer's first render),
  rgb/<camera> (S, H, W, 3) uint8, depth/<camera> (S, H, W) float32 (the raw depth buffer that `render_mode=
  "depth_array"` returns), meta (JSON).
Camera "free" is the reference's default camera (no camera_name / camera_id: camera_id -1).
"""

from __future__ import annotations

import argparse
import json
import os
import shlex
import sys
import warnings
from importlib import metadata as importlib_metadata

import metaworld
import metaworld.policies as mw_policies
import mujoco
import numpy as np

DEFAULT_TASKS = ["reach-v3", "pick-place-v3", "door-open-v3", "drawer-close-v3"]
CAMERAS = ["corner", "topview", "behindGripper", "free"]
# Rendered for the first task's reset state only: the remaining cameras of the scenes.
EXTRA_CAMERAS = ["corner2", "corner3", "corner4", "gripperPOV"]
DEPTH_CAMERAS = ["corner", "topview"]


def find_policy(task: str):
    base = task[: -len("-v3")] if task.endswith("-v3") else task
    cand = "Sawyer" + "".join(p.capitalize() for p in base.split("-")) + "V3Policy"
    cls = getattr(mw_policies, cand, None)
    return cls if cls is not None else mw_policies.ENV_POLICY_MAP[task]


def render(env, camera: str, mode: str) -> np.ndarray:
    """`env.render()` with the env's renderer pointed at `camera` ("free" = the default, -1)."""
    renderer = env.unwrapped.mujoco_renderer
    renderer.camera_id = (
        -1 if camera == "free" else mujoco.mj_name2id(env.unwrapped.model, mujoco.mjtObj.mjOBJ_CAMERA, camera)
    )
    if renderer.camera_id == -2 or (camera != "free" and renderer.camera_id < 0):
        raise ValueError(f"no camera {camera!r}")
    return np.array(renderer.render(mode), copy=True)


def record_task(task: str, seed: int, size: int, steps: int, extra: bool) -> dict:
    bench = metaworld.MT1(task, seed=seed)
    cls = bench.train_classes[task]
    env = cls(render_mode="rgb_array", width=size, height=size)
    env.set_task(bench.train_tasks[0])
    env._partially_observable = False
    obs, _ = env.reset()
    policy = find_policy(task)()
    model, data = env.model, env.data
    out: dict[str, list] = {}

    def put(key, value):
        out.setdefault(key, []).append(value)

    cameras = CAMERAS + (EXTRA_CAMERAS if extra else [])
    for state in range(2):
        if state == 1:
            for _ in range(steps):
                with warnings.catch_warnings():
                    warnings.simplefilter("ignore")
                    action = np.clip(policy.get_action(obs), -1, 1).astype(np.float32)
                obs, *_ = env.step(action)
        put("qpos", data.qpos.copy())
        put("qvel", data.qvel.copy())
        put("mocap_pos", data.mocap_pos.copy())
        put("mocap_quat", data.mocap_quat.copy())
        put("body_pos", model.body_pos.copy())
        put("body_quat", model.body_quat.copy())
        put("site_xpos", data.site_xpos.copy())
        for camera in cameras if state == 0 else CAMERAS:
            put(f"rgb/{camera}", render(env, camera, "rgb_array"))
        for camera in DEPTH_CAMERAS:
            put(f"depth/{camera}", render(env, camera, "depth_array").astype(np.float32))
        viewer = env.unwrapped.mujoco_renderer._get_viewer("rgb_array")
        put("free_lookat", np.array(viewer.cam.lookat, copy=True))
        free = viewer.cam
        free_params = {"distance": free.distance, "azimuth": free.azimuth, "elevation": free.elevation}
    env.close()
    arrays = {}
    for key, values in out.items():
        value = np.stack(values)
        if value.dtype == np.float64:
            value = value.astype(np.float32) if key.startswith("depth") else value
        arrays[key] = value
    arrays["free_params"] = np.array(json.dumps(free_params))
    return arrays


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--tasks", nargs="+", default=DEFAULT_TASKS)
    p.add_argument("--out", default="tests/fixtures/render")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--size", type=int, default=64, help="image width and height")
    p.add_argument("--steps", type=int, default=40, help="expert steps before the second state")
    args = p.parse_args(argv)
    os.makedirs(args.out, exist_ok=True)
    how = "python tools/record_render_fixtures.py " + " ".join(
        shlex.quote(a) for a in (sys.argv[1:] if argv is None else argv)
    )
    versions = {
        name: importlib_metadata.version(name) for name in ("metaworld", "mujoco", "gymnasium", "numpy")
    }
    for i, task in enumerate(args.tasks):
        arrays = record_task(task, args.seed, args.size, args.steps, extra=i == 0)
        meta = {
            "task": task,
            "seed": args.seed,
            "size": args.size,
            "expert_steps": args.steps,
            "states": ["reset", f"after {args.steps} expert steps"],
            "versions": versions,
            "MUJOCO_GL": os.environ.get("MUJOCO_GL"),
            "how": how.strip(),
        }
        arrays["meta"] = np.array(json.dumps(meta, sort_keys=True))
        path = os.path.join(args.out, f"{task}.npz")
        np.savez_compressed(path, **arrays)
        print(f"{task:20s} {os.path.getsize(path) / 1024:6.1f} KiB", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
