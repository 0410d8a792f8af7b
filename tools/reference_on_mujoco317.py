#!/usr/bin/env python
"""The reference experts on the reference code, but on whatever mujoco this venv has.

Used to separate the engine version (MuJoCo 3.17 vs the reference's 3.3.0) from mwjax's own
differences. metaworld 3.1.1 pins mujoco 3.3.0, so this needs a scratch venv where it is forced:

    python3 -m venv /tmp/ref317 && /tmp/ref317/bin/pip install mujoco==3.17.0 numpy scipy \
        gymnasium==1.4.0 packaging imageio && /tmp/ref317/bin/pip install --no-deps metaworld==3.1.1
    # MuJoCo >= 3.8 has 12 eq_data slots: in metaworld/sawyer_xyz_env.py, reset_mocap_welds,
    # write `self.model.eq_data[i, :11] = ...` instead of `self.model.eq_data[i] = ...`.
    /tmp/ref317/bin/python tools/reference_on_mujoco317.py hand-insert-v3 soccer-v3

`--v330-defaults` puts back the engine defaults 3.3.0 had and 3.17 changed (multi-contact CCD
off, 50 CCD iterations, no constraint islands), as mwjax's scenes do.

Per task: MT1(task, seed=42), one episode per goal variant, up to 500 steps, success at any step.
"""

from __future__ import annotations

import sys
import warnings

import metaworld
import metaworld.policies as mw_policies
import mujoco
import numpy as np


def main() -> None:
    warnings.filterwarnings("ignore")
    v330 = "--v330-defaults" in sys.argv[1:]
    for task in (a for a in sys.argv[1:] if not a.startswith("--")):
        bench = metaworld.MT1(task, seed=42)
        env = bench.train_classes[task]()
        if v330:
            off = mujoco.mjtDisableBit
            env.model.opt.disableflags |= off.mjDSBL_MULTICCD | off.mjDSBL_ISLAND
            env.model.opt.ccd_iterations = 50
        policy = mw_policies.ENV_POLICY_MAP[task]()
        failed = []
        for index, goal in enumerate(bench.train_tasks):
            env.set_task(goal)
            obs, _ = env.reset()
            solved = False
            for _ in range(500):
                obs, _, _, _, info = env.step(np.clip(policy.get_action(obs), -1, 1))
                if info["success"]:
                    solved = True
                    break
            if not solved:
                failed.append(index)
        rate = 1 - len(failed) / len(bench.train_tasks)
        defaults = "3.3.0's engine defaults" if v330 else "its own defaults"
        print(
            f"mujoco {mujoco.__version__} ({defaults}) {task} success {rate:.2f} failed goals {failed}",
            flush=True,
        )


if __name__ == "__main__":
    main()
