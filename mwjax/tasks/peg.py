"""peg-insert-side: a peg to grasp and push into a hole in a box the reset moves."""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np

from mwjax import rewards_v2
from mwjax.tasks.spec import Frame, Placement, TaskSpec, quat_from_xmat, set_object_xyz

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
    reward_v2=rewards_v2.peg_insert_side,
    moved_bodies=("box",),
    rand_vec_valid=_peg_box_apart,
)

TASKS: tuple[TaskSpec, ...] = (PEG_INSERT_SIDE,)
