#!/usr/bin/env python
"""bin-picking's cube started inside a bin wall: how far MuJoCo 3.17 and 3.3.0 part in 10 steps.

bin-picking's reset puts the 4 cm cube at any x in [-0.21, -0.03]; the bin's side walls have their
inner faces at -0.21 and -0.03, so a cube at x < -0.19 or x > -0.05 starts inside one, by up to
2 cm. This replays the reference code from one recorded reset state (a `tools/record_reference.py`
fixture's first reset, 3.3.0's engine defaults as `tools/reference_baseline.py` restores them) with
the cube's x swept over the overlap, the fixture's first recorded actions, and writes the
observations; run it in the reference venv (MuJoCo 3.3.0) and in the engine-only baseline's venv
(MuJoCo 3.17, `tools/reference_on_mujoco317.py`), then compare the two outputs in any venv:

    .venv-ref/bin/python tools/bin_wall_overlap.py run --fixtures /tmp/ref_seed11 --out /tmp/bw330.npz
    /tmp/ref317/bin/python tools/bin_wall_overlap.py run --fixtures /tmp/ref_seed11 --out /tmp/bw317.npz
    python tools/bin_wall_overlap.py compare /tmp/bw330.npz /tmp/bw317.npz

Per x: the penetration the engine's box-box collider reports at the start (3.3.0: half the
overlap; 3.17: all of it) and the largest difference between the engines in the cube's observed
position (obs[4:7]) and quaternion (obs[7:11]), and in the hand (obs[0:4]), over the 10 steps.
"""

from __future__ import annotations

import argparse
import json
import os
import sys

import numpy as np

TASK = "bin-picking-v3"
STEPS = 10


def run(fixtures: str, out: str, step_mm: float) -> None:
    import metaworld
    import mujoco

    sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
    import record_reference
    from reference_baseline import v330_defaults

    with np.load(os.path.join(fixtures, f"{TASK}.npz")) as z:
        fixture = {k: z[k] for k in z.files}
    seed = int(json.loads(str(fixture["meta"]))["seed"])
    bench = metaworld.MT1(TASK, seed=seed)
    env = record_reference.make_env(bench.train_classes[TASK], "v2")
    v330_defaults(env.model)
    n = round(20 / step_mm) + 1
    xs = np.concatenate([np.linspace(-0.21, -0.19, n), np.linspace(-0.05, -0.03, n)])
    obs = np.zeros((len(xs), STEPS, 39))
    depth = np.zeros(len(xs))
    for i, x in enumerate(xs):
        record_reference.set_task_fully_observable(env, bench.train_tasks[0])
        env.reset()
        qpos = fixture["reset_qpos"][0].copy()
        qpos[9] = x  # the cube's free joint starts at qpos[9]
        env.set_state(qpos, fixture["reset_qvel"][0])
        env.data.qacc_warmstart[:] = fixture["reset_qacc_warmstart"][0]
        env._prev_obs = np.asarray(fixture["reset_obs"][0][:18], np.float64).copy()
        contacts = env.data.contact[: env.data.ncon]
        depth[i] = -min((c.dist for c in contacts), default=0.0)
        for t in range(STEPS):
            obs[i, t] = env.step(np.array(fixture["action"][0, t], np.float32))[0]
    np.savez(out, obs=obs, xs=xs, depth=depth, mujoco=mujoco.__version__)
    print(f"MuJoCo {mujoco.__version__}: {len(xs)} cube positions -> {out}")


def compare(a_path: str, b_path: str) -> None:
    a, b = np.load(a_path), np.load(b_path)
    assert np.array_equal(a["xs"], b["xs"])
    gap = np.abs(a["obs"] - b["obs"])
    va, vb = str(a["mujoco"]), str(b["mujoco"])
    print(f"| cube x | depth {va} | depth {vb} | cube position | cube quaternion | hand |")
    print("| ---: | ---: | ---: | ---: | ---: | ---: |")
    for i, x in enumerate(a["xs"]):
        pos, quat, hand = (gap[i][:, cols].max() for cols in (np.r_[4:7], np.r_[7:11], np.r_[0:4]))
        print(
            f"| {x:.4f} | {a['depth'][i]:.4f} | {b['depth'][i]:.4f} | {pos:.2e} | {quat:.2e} | {hand:.2e} |"
        )
    print(
        f"\nlargest: cube position {gap[..., 4:7].max():.3g}, quaternion {gap[..., 7:11].max():.3g}, "
        f"hand {gap[..., 0:4].max():.3g}"
    )


def main() -> None:
    formatter = argparse.RawDescriptionHelpFormatter
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=formatter)
    sub = parser.add_subparsers(dest="command", required=True)
    p_run = sub.add_parser("run")
    p_run.add_argument("--fixtures", required=True, help="a tools/record_reference.py output dir")
    p_run.add_argument("--out", required=True)
    p_run.add_argument("--step-mm", type=float, default=0.1, help="sweep step of the cube's x")
    p_cmp = sub.add_parser("compare")
    p_cmp.add_argument("a")
    p_cmp.add_argument("b")
    args = parser.parse_args()
    if args.command == "run":
        run(args.fixtures, args.out, args.step_mm)
    else:
        compare(args.a, args.b)


if __name__ == "__main__":
    main()
