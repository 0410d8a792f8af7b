"""Meta-World v3 scenes (vendored from metaworld 3.1.1, MIT; see PROVENANCE.md) and their loader."""

from __future__ import annotations

from pathlib import Path

import mujoco
import numpy as np

MODELS_DIR = Path(__file__).resolve().parent
SCENES_DIR = MODELS_DIR / "sawyer_xyz"

# SawyerMocapBase.reset_mocap_welds rewrites every weld at construction: anchor 0, relative pose
# identity up to sign (quat -1,0,0,0), torquescale 5. MuJoCo >= 3.8 appends a 12th eq_data slot
# that metaworld's 11-value write never reached, so it keeps the compiled default.
_REFERENCE_WELD_DATA = np.array([0.0, 0.0, 0.0, 0.0, 0.0, 0.0, -1.0, 0.0, 0.0, 0.0, 5.0])


def scene_names() -> list[str]:
    return sorted(p.name for p in SCENES_DIR.glob("*.xml"))


def load_scene(scene: str, mocap_bodies: tuple[str, ...] = ()) -> mujoco.MjModel:
    """Compiles `sawyer_xyz/<scene>` as the reference sees it after construction.

    `mocap_bodies` names fixed world children that a task moves at reset (the reference writes
    `model.body_pos`). They become mocap bodies in our copy so that their pose is per-env state
    (`data.mocap_pos`) instead of a model field shared by every env of a batch. Their index in
    `mocap_pos` follows body order; the hand's mocap stays index 0.
    """
    path = SCENES_DIR / scene
    if not path.is_file():
        raise ValueError(f"unknown scene {scene!r}; known: {', '.join(scene_names())}")
    spec = mujoco.MjSpec.from_file(str(path))
    for name in mocap_bodies:
        body = spec.body(name)
        if body is None:
            raise ValueError(f"scene {scene!r} has no body {name!r}")
        if body.parent.name != "world" or body.first_joint() is not None:
            raise ValueError(f"body {name!r} of {scene!r} is not a fixed child of the world")
        body.mocap = True
    model = spec.compile()
    weld = model.eq_type == mujoco.mjtEq.mjEQ_WELD
    model.eq_data[weld, : len(_REFERENCE_WELD_DATA)] = _REFERENCE_WELD_DATA
    if model.body_mocapid[model.body("mocap").id] != 0:
        raise AssertionError(f"{scene}: the hand's mocap body must be mocap index 0")
    return model
