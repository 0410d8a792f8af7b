"""The coffee machine: coffee-button, coffee-pull, coffee-push."""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np

from mwjax.contracts import Frame, Placement
from mwjax.rewards_v1 import coffee as v1
from mwjax.rewards_v2 import coffee as v2
from mwjax.tasks.spec import ConstantsFn, TaskSpec, quat_from_xmat

# All three tasks move the machine of the shared scene, so they list the same moved bodies.
_MOVED = ("coffee_machine",)
_HAND_INIT = (0.0, 0.4, 0.2)
# The mug sits 22 cm in front of the machine (under its spout); the button face is 30 cm up.
_SPOUT = np.array([0.0, -0.22, 0.0], np.float32)
# coffee-button's press depth (the class's max_dist) and the button face above the spout.
_BUTTON_TRAVEL = 0.03
_BUTTON_FACE = np.array([0.0, -0.22 + _BUTTON_TRAVEL, 0.3], np.float32)


def _place_mug(settled: Frame, mug: jnp.ndarray, machine: jnp.ndarray, target: jnp.ndarray) -> Placement:
    """The coffee tasks' own `_set_obj_xyz`: the mug's position (qpos[0:3]) written.

    Reference quirk: it zeroes qvel[9:15], the base class's object slots, which in this scene are
    arm joints 3-6 and both fingers; the mug keeps its settled velocity and orientation.
    """
    qpos = settled.qpos.at[0:3].set(mug)
    qvel = settled.qvel.at[9:15].set(0.0)
    return Placement(qpos=qpos, qvel=qvel, target_pos=target, moved_bodies={"coffee_machine": machine})


def _mug(frame: Frame) -> tuple[jnp.ndarray, jnp.ndarray]:
    # scipy's as_quat of the mug geom's rotation: (x, y, z, w).
    return frame.body_pos("obj")[None], quat_from_xmat(frame.geom_xmat("mug"))[None]


def _mug_apart(vec: np.ndarray) -> bool:
    """The reference redraws until the mug's start and goal are at least 15 cm apart in the plane."""
    return bool(np.linalg.norm(vec[:2] - vec[3:5]) >= 0.15)


# ---- coffee-button -------------------------------------------------------------------------------


def _place_button(rand_vec: jnp.ndarray, settled: Frame) -> Placement:
    # rand_vec is the machine's position; the goal is the pressed-in button face.
    return _place_mug(settled, rand_vec + _SPOUT, rand_vec, rand_vec + _BUTTON_FACE)


def _button(frame: Frame) -> tuple[jnp.ndarray, jnp.ndarray]:
    pos = frame.site_pos("buttonStart")
    # Reference: a constant identity quaternion.
    return pos[None], jnp.array([[1.0, 0.0, 0.0, 0.0]], pos.dtype)


def _button_constants(frame: Frame, placement: Placement, settled: Frame) -> dict[str, jnp.ndarray]:
    return {
        "init_tcp": settled.tcp_center,
        # V2's press margin is the class constant max_dist.
        "obj_to_target_init": jnp.asarray(_BUTTON_TRAVEL, jnp.float32),
        # V1's maxDist is measured on the placed scene (after set_state's mj_forward).
        "max_press_dist": jnp.abs(frame.site_pos("buttonStart")[1] - placement.target_pos[1]),
    }


COFFEE_BUTTON = TaskSpec(
    name="coffee-button-v3",
    scene="sawyer_coffee.xml",
    hand_init_pos=_HAND_INIT,
    random_low=(-0.1, 0.8, -0.001),
    random_high=(0.1, 0.9, 0.001),
    goal_low=(-0.101, 0.61, 0.298),
    goal_high=(0.101, 0.71, 0.302),
    place=_place_button,
    constants=_button_constants,
    objects=_button,
    reward_v2=v2.coffee_button,
    reward_v1=v1.coffee_button,
    moved_bodies=_MOVED,
)

# ---- coffee-pull, coffee-push --------------------------------------------------------------------


def _place_pull(rand_vec: jnp.ndarray, settled: Frame) -> Placement:
    # The mug starts under the spout and is pulled out to the goal.
    mug, target = rand_vec[:3], rand_vec[3:6]
    return _place_mug(settled, mug, mug - _SPOUT, target)


def _place_push(rand_vec: jnp.ndarray, settled: Frame) -> Placement:
    # The goal is under the spout; the mug starts in front.
    mug, target = rand_vec[:3], rand_vec[3:6]
    return _place_mug(settled, mug, target - _SPOUT, target)


def _mug_constants(max_dist_name: str) -> ConstantsFn:
    """obj_init_pos is rand_vec's mug position; V1's max distance (named as the task does) is
    the mug's start-to-goal distance in the plane."""

    def constants(frame: Frame, placement: Placement, settled: Frame) -> dict[str, jnp.ndarray]:
        obj_init_pos = placement.qpos[0:3]
        return {
            "obj_init_pos": obj_init_pos,
            "init_tcp": settled.tcp_center,
            max_dist_name: jnp.linalg.norm(obj_init_pos[:2] - placement.target_pos[:2]),
        }

    return constants


COFFEE_PULL = TaskSpec(
    name="coffee-pull-v3",
    scene="sawyer_coffee.xml",
    hand_init_pos=_HAND_INIT,
    random_low=(-0.05, 0.7, -0.001, -0.1, 0.55, -0.001),
    random_high=(0.05, 0.75, 0.001, 0.1, 0.65, 0.001),
    goal_low=(-0.1, 0.55, -0.001),
    goal_high=(0.1, 0.65, 0.001),
    place=_place_pull,
    constants=_mug_constants("max_pull_dist"),
    objects=_mug,
    reward_v2=v2.coffee_mug,
    reward_v1=v1.coffee_pull,
    moved_bodies=_MOVED,
    rand_vec_valid=_mug_apart,
)

COFFEE_PUSH = TaskSpec(
    name="coffee-push-v3",
    scene="sawyer_coffee.xml",
    hand_init_pos=_HAND_INIT,
    random_low=(-0.1, 0.55, -0.001, -0.05, 0.7, -0.001),
    random_high=(0.1, 0.65, 0.001, 0.05, 0.75, 0.001),
    goal_low=(-0.05, 0.7, -0.001),
    goal_high=(0.05, 0.75, 0.001),
    place=_place_push,
    constants=_mug_constants("max_push_dist"),
    objects=_mug,
    reward_v2=v2.coffee_mug,
    reward_v1=v1.coffee_push,
    moved_bodies=_MOVED,
    rand_vec_valid=_mug_apart,
)

TASKS: tuple[TaskSpec, ...] = (COFFEE_BUTTON, COFFEE_PULL, COFFEE_PUSH)
