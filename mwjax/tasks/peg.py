"""peg-insert-side and peg-unplug-side: a peg (plug) and a box with a hole that the reset moves."""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np

from mwjax.contracts import Frame, Placement
from mwjax.rewards_v1 import peg as v1
from mwjax.rewards_v2 import peg as v2
from mwjax.tasks.spec import TaskSpec, quat_from_xmat, set_object_xyz

# The goal (hole) is this far from the box body origin; the goal space is shifted by it too.
_HOLE_OFFSET = (0.03, 0.0, 0.13)
_BOX_LOW, _BOX_HIGH = (-0.35, 0.4, -0.001), (-0.25, 0.7, 0.001)


def _peg(frame: Frame) -> tuple[jnp.ndarray, jnp.ndarray]:
    return frame.site_pos("pegGrasp")[None], quat_from_xmat(frame.site_xmat("pegGrasp"))[None]


def _peg_box_apart(vec: np.ndarray) -> bool:
    """The reference redraws until peg and box are at least 10 cm apart in the plane."""
    return bool(np.linalg.norm(vec[:2] - vec[3:5]) >= 0.1)


def _place(rand_vec: jnp.ndarray, settled: Frame) -> Placement:
    pos_peg, pos_box = rand_vec[:3], rand_vec[3:6]
    qpos, qvel = set_object_xyz(settled, pos_peg)
    return Placement(
        qpos=qpos,
        qvel=qvel,
        target_pos=pos_box + jnp.asarray(_HOLE_OFFSET, rand_vec.dtype),
        moved_bodies={"box": pos_box},
    )


def _constants(frame: Frame, placement: Placement, settled: Frame) -> dict[str, jnp.ndarray]:
    return {
        # rand_vec's peg position itself (z = 0.02), not the placed peg's body or grasp site.
        "obj_init_pos": placement.qpos[9:12],
        "init_tcp": settled.tcp_center,
        # Quirk: read before `_set_obj_xyz` moves the peg, so it is the peg head at the XML's
        # default peg position, whatever the episode's peg position.
        "peg_head_pos_init": settled.site_pos("pegHead"),
    }


PEG_INSERT_SIDE = TaskSpec(
    name="peg-insert-side-v3",
    scene="sawyer_peg_insertion_side.xml",
    hand_init_pos=(0.0, 0.6, 0.2),
    random_low=(0.0, 0.5, 0.02, *_BOX_LOW),
    random_high=(0.2, 0.7, 0.02, *_BOX_HIGH),
    goal_low=tuple(lo + d for lo, d in zip(_BOX_LOW, _HOLE_OFFSET, strict=True)),
    goal_high=tuple(hi + d for hi, d in zip(_BOX_HIGH, _HOLE_OFFSET, strict=True)),
    place=_place,
    constants=_constants,
    objects=_peg,
    reward_v2=v2.peg_insert_side,
    reward_v1=v1.peg_insert_side,
    moved_bodies=("box",),
    rand_vec_valid=_peg_box_apart,
)

# ---- peg-unplug-side ------------------------------------------------------------------------------

# The plug sits this far from the box body origin, and the goal 15 cm further along x.
_PLUG_OFFSET = (0.044, 0.0, 0.131)
_UNPLUG_DISTANCE = 0.15
_UNPLUG_BOX_LOW, _UNPLUG_BOX_HIGH = (-0.25, 0.6, -0.001), (-0.15, 0.8, 0.001)


def _plug(frame: Frame) -> tuple[jnp.ndarray, jnp.ndarray]:
    # The plug's end site and the plug body's MuJoCo xquat (w, x, y, z).
    return frame.site_pos("pegEnd")[None], frame.body_quat("plug1")[None]


def _place_unplug(rand_vec: jnp.ndarray, settled: Frame) -> Placement:
    pos_box = rand_vec[:3]
    pos_plug = pos_box + jnp.asarray(_PLUG_OFFSET, rand_vec.dtype)
    # The task's own _set_obj_xyz: plug position and identity orientation, linear velocity zeroed.
    # Reference quirk: its angular velocity (qvel[12:15]) is kept from the settled state.
    qpos = settled.qpos.at[9:12].set(pos_plug).at[12:16].set(jnp.array([1.0, 0.0, 0.0, 0.0]))
    qvel = settled.qvel.at[9:12].set(0.0)
    target = pos_plug + jnp.array([_UNPLUG_DISTANCE, 0.0, 0.0], rand_vec.dtype)
    return Placement(qpos=qpos, qvel=qvel, target_pos=target, moved_bodies={"box": pos_box})


def _unplug_constants(frame: Frame, placement: Placement, settled: Frame) -> dict[str, jnp.ndarray]:
    obj_init_pos = frame.site_pos("pegEnd")  # read after the placement's mj_forward
    return {
        "obj_init_pos": obj_init_pos,
        "init_tcp": settled.tcp_center,
        # V1: its reach term measures the tcp height change from the nominal hand_init_pos.
        "hand_init_pos": jnp.asarray(PEG_UNPLUG_SIDE.hand_init_pos, jnp.float32),
        "max_placing_dist": jnp.linalg.norm(placement.target_pos - obj_init_pos),
    }


# The plug settles during _reset_hand jammed against the box, already at this episode's goal, so
# the angular velocity that the reset keeps depends on the goal (settled per goal). It is chaotic
# in the reference itself (docs/fidelity.md).
PEG_UNPLUG_SIDE = TaskSpec(
    name="peg-unplug-side-v3",
    settle_per_goal=True,
    scene="sawyer_peg_unplug_side.xml",
    hand_init_pos=(0.0, 0.6, 0.2),
    random_low=_UNPLUG_BOX_LOW,
    random_high=_UNPLUG_BOX_HIGH,
    # The goal space is the box space shifted to the goal (plug offset + unplug distance in x).
    goal_low=tuple(lo + d for lo, d in zip(_UNPLUG_BOX_LOW, (0.194, 0.0, 0.131), strict=True)),
    goal_high=tuple(hi + d for hi, d in zip(_UNPLUG_BOX_HIGH, (0.194, 0.0, 0.131), strict=True)),
    place=_place_unplug,
    constants=_unplug_constants,
    objects=_plug,
    reward_v2=v2.peg_unplug_side,
    reward_v1=v1.peg_unplug_side,
    moved_bodies=("box",),
)

TASKS: tuple[TaskSpec, ...] = (PEG_INSERT_SIDE, PEG_UNPLUG_SIDE)
