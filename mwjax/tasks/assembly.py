"""assembly and disassemble: a ring (nut) on a peg that the reset moves."""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np

from mwjax.contracts import Frame, Placement
from mwjax.rewards_v1 import assembly as v1
from mwjax.rewards_v2 import assembly as v2
from mwjax.tasks.spec import TaskSpec, set_object_xyz

# Both tasks move the peg of their shared scene.
_MOVED = ("peg",)


def _nut(frame: Frame) -> tuple[jnp.ndarray, jnp.ndarray]:
    # The handle-end site "RoundNut-8" and the nut body's MuJoCo xquat (w, x, y, z).
    return frame.site_pos("RoundNut-8")[None], frame.body_quat("RoundNut")[None]


def _nut_peg_apart(vec: np.ndarray) -> bool:
    """The reference redraws until nut and goal are at least 10 cm apart in the plane."""
    return bool(np.linalg.norm(vec[:2] - vec[3:5]) >= 0.1)


def _max_placing_dist(
    obj_init_pos: jnp.ndarray, height_target: jnp.ndarray, target: jnp.ndarray
) -> jnp.ndarray:
    """V1's maxPlacingDist: from above the start (at height_target) to the goal, plus the lift."""
    lifted_start = jnp.concatenate([obj_init_pos[:2], height_target[None]])
    return jnp.linalg.norm(lifted_start - target) + height_target


def _place_assembly(rand_vec: jnp.ndarray, settled: Frame) -> Placement:
    # The nut keeps the settled quaternion (_set_obj_xyz writes its position and zeroes its velocity).
    qpos, qvel = set_object_xyz(settled, rand_vec[:3])
    target = rand_vec[3:]
    peg = target - jnp.array([0.0, 0.0, 0.05], rand_vec.dtype)
    return Placement(qpos=qpos, qvel=qvel, target_pos=target, moved_bodies={"peg": peg})


def _assembly_constants(frame: Frame, placement: Placement, settled: Frame) -> dict[str, jnp.ndarray]:
    obj_init_pos = placement.qpos[9:12]  # rand_vec's nut position, a live view of it in the reference
    # V1: the handle-end site's height once the nut is placed.
    obj_height = frame.site_pos("RoundNut-8")[2]
    height_target = obj_height + 0.1
    return {
        "obj_init_pos": obj_init_pos,
        "init_tcp": settled.tcp_center,
        "obj_height": obj_height,
        "height_target": height_target,
        "max_placing_dist": _max_placing_dist(obj_init_pos, height_target, placement.target_pos),
    }


def _place_disassemble(rand_vec: jnp.ndarray, settled: Frame) -> Placement:
    # The peg moves under the nut's start; the target is 15 cm above it. The nut keeps the settled
    # quaternion (see DISASSEMBLE).
    obj_init_pos = rand_vec[:3]
    qpos, qvel = set_object_xyz(settled, obj_init_pos)
    return Placement(
        qpos=qpos,
        qvel=qvel,
        target_pos=obj_init_pos + jnp.array([0.0, 0.0, 0.15], rand_vec.dtype),
        moved_bodies={"peg": obj_init_pos + jnp.array([0.0, 0.0, 0.03], rand_vec.dtype)},
    )


def _disassemble_constants(frame: Frame, placement: Placement, settled: Frame) -> dict[str, jnp.ndarray]:
    obj_init_pos = placement.qpos[9:12]
    # V1: the nut body's height once placed (= rand_vec's z).
    obj_height = frame.body_pos("RoundNut")[2]
    height_target = obj_height + 0.05
    return {
        "obj_init_pos": obj_init_pos,
        "init_tcp": settled.tcp_center,
        "obj_height": obj_height,
        "height_target": height_target,
        "max_placing_dist": _max_placing_dist(obj_init_pos, height_target, placement.target_pos),
    }


ASSEMBLY = TaskSpec(
    name="assembly-v3",
    scene="sawyer_assembly_peg.xml",
    hand_init_pos=(0.0, 0.6, 0.2),
    random_low=(0.0, 0.6, 0.02, -0.1, 0.75, 0.1),
    random_high=(0.0, 0.6, 0.02, 0.1, 0.85, 0.1),
    goal_low=(-0.1, 0.75, 0.1),
    goal_high=(0.1, 0.85, 0.1),
    place=_place_assembly,
    constants=_assembly_constants,
    objects=_nut,
    reward_v2=v2.assembly,
    reward_v1=v1.assembly,
    moved_bodies=_MOVED,
    rand_vec_valid=_nut_peg_apart,
)

# The nut settles during _reset_hand against the peg, already at this episode's goal, so its
# quaternion, which _set_obj_xyz keeps, depends on the goal (settled per goal). It is chaotic in
# the reference itself (docs/fidelity.md).
DISASSEMBLE = TaskSpec(
    name="disassemble-v3",
    settle_per_goal=True,
    scene="sawyer_assembly_peg.xml",
    hand_init_pos=(0.0, 0.4, 0.2),
    random_low=(0.0, 0.6, 0.025, -0.1, 0.6, 0.1699),
    random_high=(0.1, 0.75, 0.02501, 0.1, 0.75, 0.1701),
    # The goal space is the rand_vec goal box raised 5 mm.
    goal_low=(-0.1, 0.6, 0.1749),
    goal_high=(0.1, 0.75, 0.1751),
    place=_place_disassemble,
    constants=_disassemble_constants,
    objects=_nut,
    reward_v2=v2.disassemble,
    reward_v1=v1.disassemble,
    moved_bodies=_MOVED,
    rand_vec_valid=_nut_peg_apart,
)

TASKS: tuple[TaskSpec, ...] = (ASSEMBLY, DISASSEMBLE)
