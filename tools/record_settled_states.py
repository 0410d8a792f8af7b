"""Records each task's settled reset state with the reference stack (metaworld 3.1.1, mujoco 3.3.0).

Every reference reset first drives the mocap-welded hand to `hand_init_pos` for 50 x 5 physics steps
(`SawyerXYZEnv._reset_hand`), starting from `mj_resetData`. The arm is redundant and still moving
when that ends (joint speeds above 1 rad/s), so the settled state is chaotic in the engine version:
MuJoCo 3.17 lands arm links up to 9 cm away from 3.3.0. The state does not depend on the goal
variant, so we record it once per task with the reference's own engine and ship it
(`mwjax/tasks/settled_states.npz`); mwjax never re-runs the settling.

Run in a separate venv (metaworld pins mujoco 3.3.0):
    python3 -m venv .venv-ref && .venv-ref/bin/pip install metaworld==3.1.1
    .venv-ref/bin/python tools/record_settled_states.py
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import metaworld
import mujoco
import numpy as np
from metaworld.env_dict import ALL_V3_ENVIRONMENTS

# Arrays read from the settled data. Kinematic arrays are as mj_step leaves them (computed before
# the last substep's integration), which is exactly what reset_model reads after _reset_hand.
FIELDS = (
    "qpos",
    "qvel",
    "act",
    "qacc_warmstart",
    "ctrl",
    "mocap_pos",
    "mocap_quat",
    "xpos",
    "xquat",
    "site_xpos",
    "site_xmat",
    "geom_xpos",
    "geom_xmat",
)


def settle(env) -> mujoco.MjData:
    """SawyerXYZEnv._reset_hand on freshly reset data, as the second reset_model call sees it."""
    data = mujoco.MjData(env.model)
    mujoco.mj_resetData(env.model, data)
    for _ in range(50):
        data.mocap_pos[0] = env.hand_init_pos
        data.mocap_quat[0] = np.array([1, 0, 1, 0])
        data.ctrl[:] = [-1, 1]
        mujoco.mj_step(env.model, data, nstep=env.frame_skip)
        mujoco.mj_rnePostConstraint(env.model, data)
    return data


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default=str(Path(__file__).parents[1] / "mwjax/tasks/settled_states.npz"))
    args = parser.parse_args()
    arrays: dict[str, np.ndarray] = {}
    for name, cls in ALL_V3_ENVIRONMENTS.items():
        bench = metaworld.MT1(name, seed=0)
        env = cls()
        env.set_task(bench.train_tasks[0])
        env.reset()
        data = settle(env)
        # Cross-check against a real reset: the arm joints (qpos[:9]) are not touched after
        # _reset_hand, so they match bit for bit, except in the tasks whose reset_model steps the
        # physics again after placing objects (box-close, coffee-*, door-lock).
        if not np.array_equal(data.qpos[:9], env.data.qpos[:9]):
            print(
                f"{name}: reset_model steps after settling (arm moved on by "
                f"{np.abs(data.qpos[:9] - env.data.qpos[:9]).max():.3g} rad)"
            )
        for field in FIELDS:
            arrays[f"{name}/{field}"] = np.array(getattr(data, field), dtype=np.float64)
        env.close()
    arrays["meta"] = np.array(
        json.dumps(
            {
                "metaworld": metaworld.__version__ if hasattr(metaworld, "__version__") else "3.1.1",
                "mujoco": mujoco.__version__,
                "how": "tools/record_settled_states.py in a venv with metaworld==3.1.1",
            }
        )
    )
    np.savez_compressed(args.out, **arrays)
    print(f"wrote {args.out}: {len(ALL_V3_ENVIRONMENTS)} tasks")


if __name__ == "__main__":
    main()
