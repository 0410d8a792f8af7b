"""Pick an object and place it: pick-out-of-hole, shelf-place, bin-picking."""

from __future__ import annotations

from collections.abc import Callable

import jax.numpy as jnp
import numpy as np

from mwjax.contracts import Frame, Placement, StepInputs
from mwjax.rewards_v1 import placing as v1
from mwjax.rewards_v2 import placing as v2
from mwjax.tasks.spec import TaskSpec, quat_from_xmat, set_object_xyz

HAND_INIT = (0.0, 0.6, 0.2)


def _apart(min_dist: float) -> Callable[[np.ndarray], bool]:
    def valid(vec: np.ndarray) -> bool:
        """The reference redraws until object and goal are `min_dist` apart in the plane."""
        return bool(np.linalg.norm(vec[:2] - vec[3:5]) >= min_dist)

    return valid


def _block_body(frame: Frame) -> tuple[jnp.ndarray, jnp.ndarray]:
    # The object body's position and its MuJoCo xquat (w, x, y, z).
    return frame.body_pos("obj")[None], frame.body_quat("obj")[None]


def _lift_constants(
    obj_init_pos: jnp.ndarray, obj_height: jnp.ndarray, lift: float, target: jnp.ndarray, planar: bool = False
) -> dict[str, jnp.ndarray]:
    """V1's heights and maxPlacingDist: from the start raised to height_target to the goal (in the
    plane only when `planar`), plus height_target."""
    height_target = obj_height + lift
    if planar:
        to_goal = jnp.linalg.norm(obj_init_pos[:2] - target[:2])
    else:
        to_goal = jnp.linalg.norm(jnp.concatenate([obj_init_pos[:2], height_target[None]]) - target)
    return {
        "obj_height": obj_height,
        "height_target": height_target,
        "max_placing_dist": to_goal + height_target,
    }


# ---- pick-out-of-hole ---------------------------------------------------------------------------


def _place_pick_out_of_hole(rand_vec: jnp.ndarray, settled: Frame) -> Placement:
    qpos, qvel = set_object_xyz(settled, rand_vec[:3])
    return Placement(qpos=qpos, qvel=qvel, target_pos=rand_vec[3:])


def _pick_out_of_hole_constants(frame: Frame, placement: Placement, settled: Frame) -> dict[str, jnp.ndarray]:
    obj_init_pos = placement.qpos[9:12]  # rand_vec's object position (a live view of it)
    return {
        "obj_init_pos": obj_init_pos,
        "init_tcp": settled.tcp_center,
        **_lift_constants(obj_init_pos, frame.geom_pos("objGeom")[2], 0.11, placement.target_pos),
    }


PICK_OUT_OF_HOLE = TaskSpec(
    name="pick-out-of-hole-v3",
    scene="sawyer_pick_out_of_hole.xml",
    hand_init_pos=HAND_INIT,
    random_low=(0.0, 0.75, 0.02, -0.1, 0.5, 0.15),
    random_high=(0.0, 0.75, 0.02, 0.1, 0.6, 0.3),
    goal_low=(-0.1, 0.5, 0.15),
    goal_high=(0.1, 0.6, 0.3),
    # The hand may go 5 cm below the table top, into the hole.
    hand_low=(-0.5, 0.40, -0.05),
    place=_place_pick_out_of_hole,
    constants=_pick_out_of_hole_constants,
    objects=_block_body,
    reward_v2=v2.pick_out_of_hole,
    reward_v1=v1.pick_out_of_hole,
    rand_vec_valid=_apart(0.15),
)

# ---- shelf-place --------------------------------------------------------------------------------

# The goal site's height above the shelf body origin.
_SHELF_GOAL = (0.0, 0.0, 0.3)


def _block_geom_quat(frame: Frame) -> tuple[jnp.ndarray, jnp.ndarray]:
    # The block body's position and scipy's (x, y, z, w) quaternion of its geom's rotation.
    return frame.body_pos("obj")[None], quat_from_xmat(frame.geom_xmat("objGeom"))[None]


def _place_shelf(rand_vec: jnp.ndarray, settled: Frame) -> Placement:
    # Quirk: the block's z is `adjust_initObjPos`'s, the settled block body z; rand_vec's block z is
    # ignored. The shelf goes 30 cm below rand_vec's goal, the goal site 30 cm above the shelf.
    obj_init_pos = jnp.concatenate([rand_vec[:2], settled.body_pos("obj")[2][None]])
    qpos, qvel = set_object_xyz(settled, obj_init_pos)
    shelf = rand_vec[3:6] - jnp.asarray(_SHELF_GOAL, rand_vec.dtype)
    return Placement(
        qpos=qpos,
        qvel=qvel,
        target_pos=shelf + jnp.asarray(_SHELF_GOAL, rand_vec.dtype),
        moved_bodies={"shelf": shelf},
    )


def _shelf_constants(frame: Frame, placement: Placement, settled: Frame) -> dict[str, jnp.ndarray]:
    obj_init_pos = placement.qpos[9:12]
    return {
        "obj_init_pos": obj_init_pos,
        "init_tcp": settled.tcp_center,
        **_lift_constants(obj_init_pos, frame.geom_pos("objGeom")[2], 0.04, placement.target_pos),
    }


SHELF_PLACE = TaskSpec(
    name="shelf-place-v3",
    scene="sawyer_shelf_placing.xml",
    hand_init_pos=HAND_INIT,
    random_low=(-0.1, 0.5, 0.019, -0.1, 0.8, 0.299),
    random_high=(0.1, 0.6, 0.021, 0.1, 0.9, 0.301),
    goal_low=(-0.1, 0.8, 0.299),
    goal_high=(0.1, 0.9, 0.301),
    place=_place_shelf,
    constants=_shelf_constants,
    objects=_block_geom_quat,
    reward_v2=v2.shelf_place,
    reward_v1=v1.shelf_place,
    moved_bodies=("shelf",),
    rand_vec_valid=_apart(0.1),
)

# ---- bin-picking --------------------------------------------------------------------------------


def _place_bin(rand_vec: jnp.ndarray, settled: Frame) -> Placement:
    # The cube's z is the settled cube body z (rand_vec's z and goal half are unused); the goal is
    # the fixed goal bin's body origin (a live view of it in the reference; it never moves).
    obj_init_pos = jnp.concatenate([rand_vec[:2], settled.body_pos("obj")[2][None]])
    qpos, qvel = set_object_xyz(settled, obj_init_pos)
    return Placement(qpos=qpos, qvel=qvel, target_pos=settled.body_pos("bin_goal"))


def _bin_constants(frame: Frame, placement: Placement, settled: Frame) -> dict[str, jnp.ndarray]:
    obj_init_pos = placement.qpos[9:12]
    return {
        "obj_init_pos": obj_init_pos,
        "init_tcp": settled.tcp_center,
        # V2: a placeholder, set on the episode's first step (see _latch_target_to_obj_init).
        "target_to_obj_init": jnp.zeros((), jnp.float32),
        **_lift_constants(obj_init_pos, frame.body_pos("obj")[2], 0.1, placement.target_pos, planar=True),
    }


def _latch_target_to_obj_init(step: StepInputs) -> dict[str, jnp.ndarray]:
    """V2's in-place margin is the cube-goal distance at the episode's first compute_reward."""
    return {"target_to_obj_init": jnp.linalg.norm(step.obs.obj - step.target_pos)}


BIN_PICKING = TaskSpec(
    name="bin-picking-v3",
    scene="sawyer_bin_picking.xml",
    hand_init_pos=HAND_INIT,
    random_low=(-0.21, 0.65, 0.02, 0.1199, 0.699, -0.001),
    random_high=(-0.03, 0.75, 0.02, 0.1201, 0.701, 0.001),
    goal_low=(0.1199, 0.699, -0.001),
    goal_high=(0.1201, 0.701, 0.001),
    hand_low=(-0.5, 0.40, 0.07),
    place=_place_bin,
    constants=_bin_constants,
    objects=_block_body,
    reward_v2=v2.bin_picking,
    reward_v1=v1.bin_picking,
    latch=_latch_target_to_obj_init,
)

TASKS: tuple[TaskSpec, ...] = (PICK_OUT_OF_HOLE, SHELF_PLACE, BIN_PICKING)
