"""Tasks where a grasped tool acts on another object: stick-push, stick-pull, hammer."""

from __future__ import annotations

import functools

import jax.numpy as jnp
import mujoco
import numpy as np

from mwjax.contracts import Frame, Placement
from mwjax.models import load_scene
from mwjax.rewards_v1 import tool_use as v1
from mwjax.rewards_v2 import tool_use as v2
from mwjax.tasks.spec import ObjectsFn, PlaceFn, TaskSpec, quat_from_xmat, set_object_xyz

# ---- stick-push, stick-pull: a stick (free joint) and a thermos on two slide joints --------------

_STICK_SCENE = "sawyer_stick_obj.xml"
_STICK_Z = 0.02  # init_config's stick height; rand_vec's object z is ignored
# The reference's hard-coded indices of the thermos slides (obj_slidex, obj_slidey).
_THERMOS_QPOS = 16
_THERMOS_QVEL_SLIDE_Y = 16


def _stick_contact_geometry() -> dict[str, np.ndarray | float]:
    """Half sizes of the stick's collision box and of a finger pad box, and the pads' contact
    margin, as compiled in the scene (stick-push's grasp test, `v2.pads_touching_box`)."""
    model = load_scene(_STICK_SCENE)
    pad = model.geom("leftpad_geom")
    if not np.array_equal(pad.size, model.geom("rightpad_geom").size):
        raise AssertionError("the finger pads differ in size")
    stick = model.geom("objGeom")
    if stick.type[0] != mujoco.mjtGeom.mjGEOM_BOX or pad.type[0] != mujoco.mjtGeom.mjGEOM_BOX:
        raise AssertionError("the stick grasp test assumes box geoms")
    return {
        "stick_half_size": np.asarray(stick.size, np.float32),
        "pad_half_size": np.asarray(pad.size, np.float32),
        "contact_margin": float(pad.margin[0]),
    }


def _stick_apart_from_goal(vec: np.ndarray) -> bool:
    """The reference redraws until stick and goal are at least 10 cm apart in the plane."""
    return bool(np.linalg.norm(vec[:2] - vec[3:5]) >= 0.1)


def _stick_objects(offset: tuple[float, float, float]) -> ObjectsFn:
    def objects(frame: Frame) -> tuple[jnp.ndarray, jnp.ndarray]:
        # The stick body and the thermos's insertion site (shifted by `offset`); scipy's (x, y,
        # z, w) quaternion of the stick body's rotation (its collision box shares it), and an
        # all-zero quaternion for the thermos.
        pos = jnp.stack([frame.body_pos("stick"), frame.site_pos("insertion") + jnp.asarray(offset)])
        quat = jnp.stack([quat_from_xmat(frame.geom_xmat("objGeom")), jnp.zeros(4)])
        return pos, quat

    return objects


def _place_stick(thermos_qpos: tuple[float, float], goal_z: str | float) -> PlaceFn:
    """`_set_stick_xyz` then `_set_obj_xyz(obj_init_qpos)`; the goal is rand_vec's x and y at
    `goal_z` (a height, or a site of the settled scene)."""

    def place(rand_vec: jnp.ndarray, settled: Frame) -> Placement:
        stick_init_pos = jnp.concatenate([rand_vec[:2], jnp.asarray([_STICK_Z], rand_vec.dtype)])
        qpos, qvel = set_object_xyz(settled, stick_init_pos)
        qpos = qpos.at[_THERMOS_QPOS : _THERMOS_QPOS + 2].set(jnp.asarray(thermos_qpos, qpos.dtype))
        # Quirk: `qvel[16:18] = 0` on a 17-dof model zeroes only obj_slidey's velocity.
        qvel = qvel.at[_THERMOS_QVEL_SLIDE_Y].set(0.0)
        if isinstance(goal_z, str):
            z = settled.site_pos(goal_z)[2]
        else:
            z = jnp.asarray(goal_z, rand_vec.dtype)
        return Placement(qpos=qpos, qvel=qvel, target_pos=jnp.concatenate([rand_vec[3:5], z[None]]))

    return place


def _stick_constants(frame: Frame, placement: Placement, settled: Frame) -> dict[str, jnp.ndarray]:
    # obj_init_pos is the thermos's fixed outer body (the slide joints move a child body).
    obj_init_pos = frame.body_pos("object")
    stick_init_pos = placement.qpos[9:12]
    target = placement.target_pos
    stick_height = frame.body_pos("stick")[2]
    height_target = stick_height + 0.04  # liftThresh
    above_thermos = jnp.concatenate([obj_init_pos[:2], height_target[None]])
    return {
        "obj_init_pos": obj_init_pos,
        "stick_init_pos": stick_init_pos,
        "init_tcp": settled.tcp_center,
        "stick_height": stick_height,
        "height_target": height_target,
        "max_place_dist": jnp.linalg.norm(above_thermos - stick_init_pos) + height_target,
        # stick-push's maxPushDist, stick-pull's maxPullDist.
        "max_goal_dist": jnp.linalg.norm(obj_init_pos[:2] - target[:2]),
    }


STICK_PUSH = TaskSpec(
    name="stick-push-v3",
    scene=_STICK_SCENE,
    hand_init_pos=(0.0, 0.6, 0.2),
    random_low=(-0.08, 0.58, 0.000, 0.399, 0.55, 0.1319),
    random_high=(-0.03, 0.62, 0.001, 0.401, 0.6, 0.1321),
    goal_low=(0.399, 0.55, 0.1319),
    goal_high=(0.401, 0.6, 0.1321),
    # The goal's height is the insertion site's, read after _reset_hand (before the placement).
    place=_place_stick((0.0, 0.0), goal_z="insertion"),
    constants=_stick_constants,
    # The thermos is observed 9 cm past its insertion site in y.
    objects=_stick_objects((0.0, 0.09, 0.0)),
    reward_v2=functools.partial(v2.stick_push, **_stick_contact_geometry()),
    reward_v1=v1.stick_push,
    rand_vec_valid=_stick_apart_from_goal,
)

STICK_PULL = TaskSpec(
    name="stick-pull-v3",
    scene=_STICK_SCENE,
    hand_init_pos=(0.0, 0.6, 0.2),
    hand_low=(-0.5, 0.35, 0.05),
    hand_high=(0.5, 1.0, 0.5),
    random_low=(-0.1, 0.55, 0.000, 0.35, 0.45, 0.0199),
    random_high=(0.0, 0.65, 0.001, 0.45, 0.55, 0.0201),
    goal_low=(0.35, 0.45, 0.0199),
    goal_high=(0.45, 0.55, 0.0201),
    # The thermos starts 9 cm along y; the goal is at the stick's height.
    place=_place_stick((0.0, 0.09), goal_z=_STICK_Z),
    constants=_stick_constants,
    objects=_stick_objects((0.0, 0.0, 0.0)),
    reward_v2=v2.stick_pull,
    reward_v1=v1.stick_pull,
    rand_vec_valid=_stick_apart_from_goal,
)


# ---- hammer ------------------------------------------------------------------------------------


def _hammer_objects(frame: Frame) -> tuple[jnp.ndarray, jnp.ndarray]:
    # MuJoCo's xquat (w, x, y, z) of the hammer and of the nail.
    pos = jnp.stack([frame.body_pos("hammer"), frame.body_pos("nail_link")])
    return pos, jnp.stack([frame.body_quat("hammer"), frame.body_quat("nail_link")])


def _place_hammer(rand_vec: jnp.ndarray, settled: Frame) -> Placement:
    # The hammer goes to rand_vec itself (z = 0); the nail box stays at its XML position (the
    # reference rewrites the same value), and the goal is its "goal" site.
    qpos, qvel = set_object_xyz(settled, rand_vec[:3])
    return Placement(qpos=qpos, qvel=qvel, target_pos=settled.site_pos("goal"))


def _hammer_constants(frame: Frame, placement: Placement, settled: Frame) -> dict[str, jnp.ndarray]:
    hammer_init_pos = placement.qpos[9:12]
    hammer_height = frame.body_pos("hammer")[2]
    height_target = hammer_height + 0.09  # liftThresh
    above_start = jnp.concatenate([hammer_init_pos[:2], height_target[None]])
    # obj_init_pos is hammer_init_pos, so the first distance is just height_target's height.
    max_hammer_dist = (
        jnp.linalg.norm(above_start - hammer_init_pos)
        + height_target
        + jnp.abs(hammer_init_pos[1] - placement.target_pos[1])
    )
    return {
        "obj_init_pos": hammer_init_pos,
        "init_tcp": settled.tcp_center,
        "hammer_height": hammer_height,
        "height_target": height_target,
        "max_hammer_dist": max_hammer_dist,
    }


HAMMER = TaskSpec(
    name="hammer-v3",
    scene="sawyer_hammer.xml",
    hand_init_pos=(0.0, 0.4, 0.2),
    random_low=(-0.1, 0.4, 0.0),
    random_high=(0.1, 0.5, 0.0),
    goal_low=(0.2399, 0.7399, 0.109),
    goal_high=(0.2401, 0.7401, 0.111),
    place=_place_hammer,
    constants=_hammer_constants,
    objects=_hammer_objects,
    reward_v2=v2.hammer,
    reward_v1=v1.hammer,
)

TASKS: tuple[TaskSpec, ...] = (STICK_PUSH, STICK_PULL, HAMMER)
