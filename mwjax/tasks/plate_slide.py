"""plate-slide and its side, back and back-side variants: a plate on two slide joints, pushed
into (or out of) a goal net."""

from __future__ import annotations

from collections.abc import Sequence

import jax.numpy as jnp

from mwjax.contracts import Frame, Placement
from mwjax.rewards_v1 import plate_slide as v1
from mwjax.rewards_v2 import plate_slide as v2
from mwjax.tasks.spec import ConstantsFn, PlaceFn, TaskSpec, quat_from_xmat

HAND_INIT = (0.0, 0.6, 0.2)
# Every variant lists the goal net body of its scene, moved or not, so scene-mates agree.
_MOVED = ("puck_goal",)


def _plate(frame: Frame) -> tuple[jnp.ndarray, jnp.ndarray]:
    # The plate geom's position and scipy's (x, y, z, w) quaternion of its rotation.
    return frame.geom_pos("puck")[None], quat_from_xmat(frame.geom_xmat("puck"))[None]


def _place(slide: Sequence[float], net_pos: Sequence[float] | None) -> PlaceFn:
    """`_set_obj_xyz(slide)` (qpos[9:11] only, qvel kept) and the goal net at `net_pos`, or at the
    goal (`rand_vec[3:]`) when None."""

    def place(rand_vec: jnp.ndarray, settled: Frame) -> Placement:
        qpos = settled.qpos.at[9:11].set(jnp.asarray(slide, settled.qpos.dtype))
        target = rand_vec[3:]
        net = target if net_pos is None else jnp.asarray(net_pos, rand_vec.dtype)
        return Placement(qpos=qpos, qvel=settled.qvel, target_pos=target, moved_bodies={"puck_goal": net})

    return place


def _constants(obj_init_pos: Sequence[float]) -> ConstantsFn:
    def constants(frame: Frame, placement: Placement, settled: Frame) -> dict[str, jnp.ndarray]:
        # obj_init_pos is rand_vec[:3] (obj_low == obj_high, so a constant), not the plate's
        # actual position, which V1's maxDist reads; init_tcp is taken at the end of _reset_hand.
        return {
            "obj_init_pos": jnp.asarray(obj_init_pos, jnp.float32),
            "init_tcp": settled.tcp_center,
            "plate_init_pos": frame.geom_pos("puck"),
        }

    return constants


PLATE_SLIDE = TaskSpec(
    name="plate-slide-v3",
    scene="sawyer_plate_slide.xml",
    hand_init_pos=HAND_INIT,
    random_low=(0.0, 0.6, 0.0, -0.1, 0.85, 0.0),
    random_high=(0.0, 0.6, 0.0, 0.1, 0.9, 0.0),
    goal_low=(-0.1, 0.85, 0.0),
    goal_high=(0.1, 0.9, 0.0),
    place=_place((0.0, 0.0), None),
    constants=_constants((0.0, 0.6, 0.0)),
    objects=_plate,
    reward_v2=v2.plate_slide,
    reward_v1=v1.plate_slide,
    moved_bodies=_MOVED,
)

PLATE_SLIDE_SIDE = TaskSpec(
    name="plate-slide-side-v3",
    scene="sawyer_plate_slide_sideway.xml",
    hand_init_pos=HAND_INIT,
    random_low=(0.0, 0.6, 0.0, -0.3, 0.54, 0.0),
    random_high=(0.0, 0.6, 0.0, -0.25, 0.66, 0.0),
    goal_low=(-0.3, 0.54, 0.0),
    goal_high=(-0.25, 0.66, 0.0),
    # Quirk: the reference writes data.body("puck_goal").xpos, which mj_forward overwrites, so
    # the net stays at the scene's position.
    place=_place((0.0, 0.0), (-0.3, 0.6, 0.0)),
    constants=_constants((0.0, 0.6, 0.0)),
    objects=_plate,
    reward_v2=v2.plate_slide_side,
    reward_v1=v1.plate_slide,
    moved_bodies=_MOVED,
)

PLATE_SLIDE_BACK = TaskSpec(
    name="plate-slide-back-v3",
    scene="sawyer_plate_slide.xml",
    hand_init_pos=HAND_INIT,
    random_low=(0.0, 0.85, 0.0, -0.1, 0.6, 0.015),
    random_high=(0.0, 0.85, 0.0, 0.1, 0.6, 0.015),
    goal_low=(-0.1, 0.6, 0.015),
    goal_high=(0.1, 0.6, 0.015),
    # Quirk: the net write goes to data.xpos (overwritten by mj_forward); it stays in the scene.
    place=_place((0.0, 0.15), (0.0, 0.85, 0.0)),
    constants=_constants((0.0, 0.85, 0.0)),
    objects=_plate,
    reward_v2=v2.plate_slide_side,
    reward_v1=v1.plate_slide_back,
    moved_bodies=_MOVED,
)

PLATE_SLIDE_BACK_SIDE = TaskSpec(
    name="plate-slide-back-side-v3",
    scene="sawyer_plate_slide_sideway.xml",
    hand_init_pos=HAND_INIT,
    random_low=(-0.25, 0.6, 0.0, -0.05, 0.6, 0.015),
    random_high=(-0.25, 0.6, 0.0, 0.15, 0.6, 0.015),
    goal_low=(-0.05, 0.6, 0.015),
    goal_high=(0.15, 0.6, 0.015),
    # The net moves to the plate's start (obj_init_pos = rand_vec[:3], constant), not the goal.
    place=_place((-0.15, 0.0), (-0.25, 0.6, 0.0)),
    constants=_constants((-0.25, 0.6, 0.0)),
    objects=_plate,
    reward_v2=v2.plate_slide_side,
    reward_v1=v1.plate_slide_back,
    moved_bodies=_MOVED,
)

TASKS = (PLATE_SLIDE, PLATE_SLIDE_SIDE, PLATE_SLIDE_BACK, PLATE_SLIDE_BACK_SIDE)
