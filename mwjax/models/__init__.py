"""Meta-World v3 scenes (vendored from metaworld 3.1.1, MIT; see PROVENANCE.md) and their loader."""

from __future__ import annotations

import functools
import json
import math
from pathlib import Path

import mujoco
import numpy as np

MODELS_DIR = Path(__file__).resolve().parent
SCENES_DIR = MODELS_DIR / "sawyer_xyz"

# SawyerMocapBase.reset_mocap_welds rewrites every weld at construction: anchor 0, relative pose
# identity up to sign (quat -1,0,0,0), torquescale 5. MuJoCo >= 3.8 appends a 12th eq_data slot
# that metaworld's 11-value write never reached, so it keeps the compiled default.
_REFERENCE_WELD_DATA = np.array([0.0, 0.0, 0.0, 0.0, 0.0, 0.0, -1.0, 0.0, 0.0, 0.0, 5.0])

# The scenes set none of these, so the reference runs MuJoCo 3.3.0's defaults, which later
# versions changed: one contact per convex pair (multi-contact CCD was opt-in, `mjENBL_MULTICCD`;
# 3.17 has it on unless `mjDSBL_MULTICCD`), 50 CCD iterations (3.17: 35), and no constraint
# islands (opt-in then, on by default in 3.17). Several contacts per pair also let MJX-Warp's
# GJK/EPA produce phantom deep contacts between a mug's cylinder and the table box, which threw
# the mug in coffee-pull.
_REFERENCE_DISABLE_FLAGS = mujoco.mjtDisableBit.mjDSBL_MULTICCD | mujoco.mjtDisableBit.mjDSBL_ISLAND
_REFERENCE_CCD_ITERATIONS = 50


def scene_names() -> list[str]:
    return sorted(p.name for p in SCENES_DIR.glob("*.xml"))


def load_scene(scene: str, mocap_bodies: tuple[str, ...] = (), visual_meshes: bool = True) -> mujoco.MjModel:
    """Compiles `sawyer_xyz/<scene>` as the reference sees it after construction.

    `mocap_bodies` names fixed world children that a task moves at reset (the reference writes
    `model.body_pos`). They become mocap bodies in our copy so that their pose is per-env state
    (`data.mocap_pos`) instead of a model field shared by every env of a batch. Their index in
    `mocap_pos` follows body order; the hand's mocap stays index 0.

    `visual_meshes=False` gives the physics-only copy a device runs (see `_without_visual_meshes`).
    """
    path = SCENES_DIR / scene
    if not path.is_file():
        raise ValueError(f"unknown scene {scene!r}; known: {', '.join(scene_names())}")
    spec = _with_assets_in_memory(mujoco.MjSpec.from_file(str(path)))
    for name in mocap_bodies:
        body = spec.body(name)
        if body is None:
            raise ValueError(f"scene {scene!r} has no body {name!r}")
        if body.parent.name != "world" or body.first_joint() is not None:
            raise ValueError(f"body {name!r} of {scene!r} is not a fixed child of the world")
        body.mocap = True
    _exclude_resting_plate(spec)
    model = spec.compile() if visual_meshes else _without_visual_meshes(spec)
    _weld_mocap_bodies_to_world(model)
    model.opt.disableflags |= _REFERENCE_DISABLE_FLAGS
    model.opt.ccd_iterations = _REFERENCE_CCD_ITERATIONS
    weld = model.eq_type == mujoco.mjtEq.mjEQ_WELD
    model.eq_data[weld, : len(_REFERENCE_WELD_DATA)] = _REFERENCE_WELD_DATA
    if model.body_mocapid[model.body("mocap").id] != 0:
        raise AssertionError(f"{scene}: the hand's mocap body must be mocap index 0")
    return model


def _with_assets_in_memory(spec: mujoco.MjSpec) -> mujoco.MjSpec:
    """`spec` with its mesh and texture files read into its assets, under their names relative to
    the scene file. The compiled model then records those relative names (`model.paths`) instead
    of absolute paths, whose length (`npaths`, and the buffer size that counts it) MJX-Warp embeds
    in every program: an install at a path of another length would miss JAX's persistent cache."""
    if spec.meshdir or spec.texturedir:
        raise AssertionError("the scenes name their asset files relative to the scene file")
    files = [item.file for items in (spec.meshes, spec.textures, spec.hfields, spec.skins) for item in items]
    directory = Path(spec.modelfiledir)
    spec.assets = {name: (directory / name).read_bytes() for name in dict.fromkeys(files) if name}
    spec.modelfiledir = ""
    return spec


def _exclude_resting_plate(spec: mujoco.MjSpec) -> None:
    """Leaves out the plate-slide plate's contact with the table, which never acts in the reference.

    The plate (geom `puck`) slides on two horizontal joints with its bottom face exactly on the
    table top, so their distance is 0 at every step. MuJoCo C computes 0.0 and excludes the
    contact (active only below the margin, 0); MJX-Warp's float32 box-box collider computes about
    -1.4e-8, so four contacts act whose normal rows cannot move the plate (it has no vertical
    freedom) while their friction drags it: Warp pushed the plate 20-35% less far than C. The
    exclusion leaves MuJoCo C's trajectories bit for bit as they were (docs/fidelity.md)."""
    plate = spec.geom("puck")
    if plate is None:
        return
    body = plate.parent
    body.name = body.name or "plate"  # an exclusion names bodies; the scenes leave this one unnamed
    spec.add_exclude(bodyname1="tablelink", bodyname2=body.name)


def _weld_mocap_bodies_to_world(model: mujoco.MjModel) -> None:
    """Gives mocap bodies, and the bodies welded to them, the world's weld id, as MuJoCo 3.3.0
    compiled them (later versions give a mocap body its own). Collision filtering reads it: two
    bodies with nonzero weld ids, one the other's weld parent, never collide. The reference's
    fixtures are static world children (weld id 0), so a door, button or lever collides with its
    frame; as mocap bodies of their own weld, ours would pass through it."""
    for body in np.flatnonzero(model.body_mocapid >= 0):
        model.body_weldid[model.body_weldid == body] = 0


def _without_visual_meshes(spec: mujoco.MjSpec) -> mujoco.MjModel:
    """The scene with each mesh geom that collides with nothing (the arm's and the objects'
    looks) turned into a point-sized sphere at the same frame, and the meshes left unused
    dropped. Three quarters of a scene's mesh data is such looks, and MJX-Warp embeds every
    mesh array in the compiled step as a constant, once per scene. Masses, inertias and every
    frame are checked to be bit-identical to the full scene's."""
    full = spec.compile()
    colliding_meshes = set()
    for geom in spec.geoms:
        if geom.type != mujoco.mjtGeom.mjGEOM_MESH:
            continue
        if geom.contype or geom.conaffinity:
            colliding_meshes.add(geom.meshname)
            continue
        # MuJoCo moved the geom's frame to its mesh's inertial frame; keep that frame.
        geom.pos, geom.quat = full.geom_pos[geom.id], full.geom_quat[geom.id]
        geom.alt.type = mujoco.mjtOrientation.mjORIENTATION_QUAT  # not euler/axisangle over it
        geom.type, geom.meshname, geom.size = mujoco.mjtGeom.mjGEOM_SPHERE, "", [1e-6, 0.0, 0.0]
    for mesh in list(spec.meshes):
        if mesh.name not in colliding_meshes:
            spec.delete(mesh)
    model = spec.compile()
    for field in ("body_mass", "body_inertia", "body_ipos", "body_iquat", "geom_pos", "geom_quat", "qpos0"):
        if not np.array_equal(getattr(model, field), getattr(full, field)):
            raise AssertionError(f"dropping visual meshes changed {field}")
    return model


# Head room over the stress corpus's peak: the corpus saw ~1.5M env steps per task; rarer states
# may need more rows, and a row short of them is a dropped contact.
STRESS_MARGIN = 1.25


def constraint_rows(scene: str) -> int:
    """Constraint rows to allocate per env of `scene`, in multiples of 32, at least 128: twice the
    most MuJoCo C reached in it under the reference's experts and random actions
    (`constraint_rows.json`, `tools/reference_constraint_rows.py`), or a quarter more than the
    most any env needed under the stress policies of `benchmarks/stress_buffers.py` (whole
    episodes at 1,024 envs per task: `stress_rows.json`), whichever is larger. Warp launches much
    of its constraint work over every allocated row, used or not, and drops rows that overflow."""
    recorded = _recorded(scene, "constraint rows", "constraints_per_env")
    stressed = _recorded_stress_rows().get(scene, {}).get("peak_rows", 0)
    return max(128, 32 * math.ceil(max(2 * recorded["max_rows"], STRESS_MARGIN * stressed) / 32))


def _recorded(scene: str, what: str, setting: str) -> dict:
    """The scene's entry in `constraint_rows.json`; a scene without one needs `setting` set."""
    table = _recorded_constraint_rows()
    if scene not in table:
        raise ValueError(f"no recorded {what} for scene {scene!r}; set {setting}")
    return table[scene]


@functools.cache
def _recorded_stress_rows() -> dict[str, dict]:
    path = MODELS_DIR / "stress_rows.json"
    return json.loads(path.read_text())["scenes"] if path.exists() else {}


@functools.cache
def _recorded_constraint_rows() -> dict[str, dict]:
    return json.loads((MODELS_DIR / "constraint_rows.json").read_text())["scenes"]
