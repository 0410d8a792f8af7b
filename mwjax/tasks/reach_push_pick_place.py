"""reach, push and pick-place: a puck on the table and a goal in space."""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np

from mwjax.contracts import Frame, Placement
from mwjax.rewards_v1 import reach_push_pick_place as v1
from mwjax.rewards_v2 import reach_push_pick_place as v2
from mwjax.tasks.spec import TaskSpec, quat_from_xmat, set_object_xyz


def _puck(frame: Frame) -> tuple[jnp.ndarray, jnp.ndarray]:
    return frame.body_pos("obj")[None], quat_from_xmat(frame.geom_xmat("objGeom"))[None]


def _puck_geom(frame: Frame) -> tuple[jnp.ndarray, jnp.ndarray]:
    """The wall and push-back variants report the puck geom's position, not the body origin."""
    return frame.geom_pos("objGeom")[None], quat_from_xmat(frame.geom_xmat("objGeom"))[None]


def _goal_apart(vec: np.ndarray) -> bool:
    """The reference redraws until object and goal are at least 15 cm apart in the plane."""
    return bool(np.linalg.norm(vec[:2] - vec[3:5]) >= 0.15)


def _place_pick_place(rand_vec: jnp.ndarray, settled: Frame) -> Placement:
    qpos, qvel = set_object_xyz(settled, rand_vec[:3])
    return Placement(qpos=qpos, qvel=qvel, target_pos=rand_vec[3:])


def _puck_constants(frame: Frame, placement: Placement, settled: Frame) -> dict[str, jnp.ndarray]:
    return {"obj_init_pos": placement.qpos[9:12], "init_tcp": settled.tcp_center}


def _place_reach(rand_vec: jnp.ndarray, settled: Frame) -> Placement:
    # The puck is placed at rand_vec[:3] although reach never uses it; the goal is rand_vec[3:].
    qpos, qvel = set_object_xyz(settled, rand_vec[:3])
    return Placement(qpos=qpos, qvel=qvel, target_pos=rand_vec[3:])


def _reach_constants(frame: Frame, placement: Placement, settled: Frame) -> dict[str, jnp.ndarray]:
    # The V2 in-place margin is measured from hand_init_pos; V1's maxReachDist from init_tcp.
    return {"hand_init_pos": jnp.asarray(REACH.hand_init_pos, jnp.float32), "init_tcp": settled.tcp_center}


def _place_push(rand_vec: jnp.ndarray, settled: Frame) -> Placement:
    # Quirk: both heights are `fix_extreme_obj_pos`'s z, the puck body z of the settled
    # (pre-placement, one substep stale) state; rand_vec's object and goal z are ignored.
    puck_z = settled.body_pos("obj")[2]
    obj_init_pos = jnp.concatenate([rand_vec[:2], puck_z[None]])
    qpos, qvel = set_object_xyz(settled, obj_init_pos)
    return Placement(qpos=qpos, qvel=qvel, target_pos=jnp.concatenate([rand_vec[3:5], puck_z[None]]))


def _place_push_geom_z(rand_vec: jnp.ndarray, settled: Frame) -> Placement:
    # Quirk: both heights are `adjust_initObjPos`'s z, the puck geom z of the settled (one
    # substep stale) state; rand_vec's object and goal z are ignored.
    geom_z = settled.geom_pos("objGeom")[2]
    obj_init_pos = jnp.concatenate([rand_vec[:2], geom_z[None]])
    qpos, qvel = set_object_xyz(settled, obj_init_pos)
    return Placement(qpos=qpos, qvel=qvel, target_pos=jnp.concatenate([rand_vec[3:5], geom_z[None]]))


REACH = TaskSpec(
    name="reach-v3",
    scene="sawyer_reach_v3.xml",
    hand_init_pos=(0.0, 0.6, 0.2),
    random_low=(-0.1, 0.6, 0.02, -0.1, 0.8, 0.05),
    random_high=(0.1, 0.7, 0.02, 0.1, 0.9, 0.3),
    goal_low=(-0.1, 0.8, 0.05),
    goal_high=(0.1, 0.9, 0.3),
    place=_place_reach,
    constants=_reach_constants,
    objects=_puck,
    reward_v2=v2.reach,
    reward_v1=v1.reach,
    rand_vec_valid=_goal_apart,
)

PUSH = TaskSpec(
    name="push-v3",
    scene="sawyer_push_v3.xml",
    hand_init_pos=(0.0, 0.6, 0.2),
    random_low=(-0.1, 0.6, 0.02, -0.1, 0.8, 0.01),
    random_high=(0.1, 0.7, 0.02, 0.1, 0.9, 0.02),
    goal_low=(-0.1, 0.8, 0.01),
    goal_high=(0.1, 0.9, 0.02),
    place=_place_push,
    constants=_puck_constants,
    objects=_puck,
    reward_v2=v2.push,
    reward_v1=v1.push,
    rand_vec_valid=_goal_apart,
)


PICK_PLACE = TaskSpec(
    name="pick-place-v3",
    scene="sawyer_pick_place_v3.xml",
    hand_init_pos=(0.0, 0.6, 0.2),
    random_low=(-0.1, 0.6, 0.02, -0.1, 0.8, 0.05),
    random_high=(0.1, 0.7, 0.02, 0.1, 0.9, 0.3),
    goal_low=(-0.1, 0.8, 0.05),
    goal_high=(0.1, 0.9, 0.3),
    place=_place_pick_place,
    constants=_puck_constants,
    objects=_puck,
    reward_v2=v2.pick_place,
    reward_v1=v1.pick_place,
    rand_vec_valid=_goal_apart,
)

REACH_WALL = TaskSpec(
    name="reach-wall-v3",
    scene="sawyer_reach_wall_v3.xml",
    hand_init_pos=(0.0, 0.6, 0.2),
    random_low=(-0.05, 0.6, 0.015, -0.05, 0.85, 0.05),
    random_high=(0.05, 0.65, 0.015, 0.05, 0.9, 0.3),
    goal_low=(-0.05, 0.85, 0.05),
    goal_high=(0.05, 0.9, 0.3),
    place=_place_reach,
    constants=_reach_constants,
    objects=_puck,
    reward_v2=v2.reach_wall,
    reward_v1=v1.reach_wall,
    rand_vec_valid=_goal_apart,
)

PUSH_WALL = TaskSpec(
    name="push-wall-v3",
    scene="sawyer_push_wall_v3.xml",
    hand_init_pos=(0.0, 0.6, 0.2),
    random_low=(-0.05, 0.6, 0.015, -0.05, 0.85, 0.01),
    random_high=(0.05, 0.65, 0.015, 0.05, 0.9, 0.02),
    goal_low=(-0.05, 0.85, 0.01),
    goal_high=(0.05, 0.9, 0.02),
    place=_place_push_geom_z,
    constants=_puck_constants,
    objects=_puck_geom,
    reward_v2=v2.push_wall,
    reward_v1=v1.push_wall,
    rand_vec_valid=_goal_apart,
)

PICK_PLACE_WALL = TaskSpec(
    name="pick-place-wall-v3",
    scene="sawyer_pick_place_wall_v3.xml",
    hand_init_pos=(0.0, 0.6, 0.2),
    random_low=(-0.05, 0.6, 0.015, -0.05, 0.85, 0.05),
    random_high=(0.05, 0.65, 0.015, 0.05, 0.9, 0.3),
    goal_low=(-0.05, 0.85, 0.05),
    goal_high=(0.05, 0.9, 0.3),
    place=_place_pick_place,
    constants=_puck_constants,
    objects=_puck_geom,
    reward_v2=v2.pick_place_wall,
    reward_v1=v1.pick_place_wall,
    rand_vec_valid=_goal_apart,
)

PUSH_BACK = TaskSpec(
    name="push-back-v3",
    scene="sawyer_push_back_v3.xml",
    hand_init_pos=(0.0, 0.6, 0.2),
    random_low=(-0.1, 0.8, 0.02, -0.1, 0.6, 0.0199),
    random_high=(0.1, 0.85, 0.02, 0.1, 0.7, 0.0201),
    goal_low=(-0.1, 0.6, 0.0199),
    goal_high=(0.1, 0.7, 0.0201),
    place=_place_push_geom_z,
    constants=_puck_constants,
    objects=_puck_geom,
    reward_v2=v2.push_back,
    reward_v1=v1.push_back,
    rand_vec_valid=_goal_apart,
)


def _puck_body(frame: Frame) -> tuple[jnp.ndarray, jnp.ndarray]:
    """sweep reports the puck body's own `xquat` (w, x, y, z)."""
    return frame.body_pos("obj")[None], frame.body_quat("obj")[None]


def _place_sweep(rand_vec: jnp.ndarray, settled: Frame) -> Placement:
    # The puck z is init_config's 0.02; the goal is the fixed (0.5, ., 0.01) with rand_vec's y.
    obj_init_pos = jnp.concatenate([rand_vec[:2], jnp.array([0.02], rand_vec.dtype)])
    qpos, qvel = set_object_xyz(settled, obj_init_pos)
    target_pos = jnp.stack([jnp.asarray(0.5, rand_vec.dtype), rand_vec[1], jnp.asarray(0.01, rand_vec.dtype)])
    return Placement(qpos=qpos, qvel=qvel, target_pos=target_pos)


_SWEEP_INTO_GOAL = (0.0, 0.84, 0.02)


def _place_sweep_into(rand_vec: jnp.ndarray, settled: Frame) -> Placement:
    # Quirk: the puck z is the settled (one substep stale) puck body z; the goal is the fixed
    # `self.goal`, rand_vec's goal half is ignored.
    obj_init_pos = jnp.concatenate([rand_vec[:2], settled.body_pos("obj")[2][None]])
    qpos, qvel = set_object_xyz(settled, obj_init_pos)
    return Placement(qpos=qpos, qvel=qvel, target_pos=jnp.asarray(_SWEEP_INTO_GOAL, rand_vec.dtype))


def _away_from_sweep_into_goal(vec: np.ndarray) -> bool:
    """The reference redraws until the puck is at least 15 cm from the fixed goal in the plane."""
    return bool(np.linalg.norm(vec[:2] - np.asarray(_SWEEP_INTO_GOAL[:2])) >= 0.15)


SWEEP = TaskSpec(
    name="sweep-v3",
    scene="sawyer_sweep_v3.xml",
    hand_init_pos=(0.0, 0.6, 0.2),
    random_low=(-0.1, 0.6, 0.02),
    random_high=(0.1, 0.7, 0.02),
    goal_low=(0.49, 0.6, 0.0),
    goal_high=(0.51, 0.7, 0.02),
    place=_place_sweep,
    constants=_puck_constants,
    objects=_puck_body,
    reward_v2=v2.sweep,
    reward_v1=v1.sweep,
)

SWEEP_INTO = TaskSpec(
    name="sweep-into-v3",
    scene="sawyer_table_with_hole.xml",
    hand_init_pos=(0.0, 0.6, 0.2),
    random_low=(-0.1, 0.6, 0.02, -0.001, 0.8399, 0.0199),
    random_high=(0.1, 0.7, 0.02, 0.001, 0.8401, 0.0201),
    goal_low=(-0.001, 0.8399, 0.0199),
    goal_high=(0.001, 0.8401, 0.0201),
    place=_place_sweep_into,
    constants=_puck_constants,
    objects=_puck,
    reward_v2=v2.sweep_into,
    reward_v1=v1.sweep_into,
    rand_vec_valid=_away_from_sweep_into_goal,
)


def _place_hand_insert(rand_vec: jnp.ndarray, settled: Frame) -> Placement:
    # The block's height is init_config's 0.05 (rand_vec's z range is that single value), which
    # leaves it 2 cm inside the 5 cm table top: the reference places it so, and the contact pushes
    # it up over the first steps. The goal is rand_vec's.
    obj_init_pos = jnp.concatenate([rand_vec[:2], jnp.asarray([0.05], rand_vec.dtype)])
    qpos, qvel = set_object_xyz(settled, obj_init_pos)
    return Placement(qpos=qpos, qvel=qvel, target_pos=rand_vec[3:])


def _hand_insert_constants(frame: Frame, placement: Placement, settled: Frame) -> dict[str, jnp.ndarray]:
    # V1's maxReachDist: the height of the nominal hand position (hand_init_pos) above the goal.
    hand_z = jnp.asarray(0.2, jnp.float32)
    return {
        **_puck_constants(frame, placement, settled),
        "max_reach_dist": jnp.abs(hand_z - placement.target_pos[2]),
    }


HAND_INSERT = TaskSpec(
    name="hand-insert-v3",
    scene="sawyer_table_with_hole.xml",
    hand_init_pos=(0.0, 0.6, 0.2),
    hand_low=(-0.5, 0.40, -0.15),
    hand_high=(0.5, 1.0, 0.5),
    random_low=(-0.1, 0.6, 0.05, -0.04, 0.8, -0.0201),
    random_high=(0.1, 0.7, 0.05, 0.04, 0.88, -0.0199),
    goal_low=(-0.04, 0.8, -0.0201),
    goal_high=(0.04, 0.88, -0.0199),
    place=_place_hand_insert,
    constants=_hand_insert_constants,
    objects=_puck_body,
    reward_v2=v2.hand_insert,
    reward_v1=v1.hand_insert,
    rand_vec_valid=_goal_apart,
)


TASKS = (
    REACH,
    PUSH,
    PICK_PLACE,
    REACH_WALL,
    PUSH_WALL,
    PICK_PLACE_WALL,
    PUSH_BACK,
    SWEEP,
    SWEEP_INTO,
    HAND_INSERT,
)
