"""V1 reward kernels of the door, drawer, button-press, window, door-close, door-lock, door-unlock tasks
(`mwjax/tasks/articulated.py`).
"""

from __future__ import annotations

import jax.numpy as jnp

from mwjax.contracts import StepInputs
from mwjax.rewards_v1.terms import fixture_reward, fixture_v1
from mwjax.rewards_v2.terms import info_terms

Array = jnp.ndarray


def door_open(step: StepInputs) -> tuple[Array, dict[str, Array]]:
    """Pull the handle to the goal in xy (max_pull_dist: the closed handle's xy distance to the goal
    at reset). evaluate_state keeps V2's success (handle x within 8 cm of the goal's) and reports
    V1's zeros for the other terms."""
    obj, target = step.obs.obj, step.target_pos
    pull_dist = jnp.linalg.norm(obj[:2] - target[:2])
    reward = fixture_reward(obj, step.frame.tcp_center, pull_dist, step.constants["max_pull_dist"])
    return info_terms(
        reward,
        success=jnp.abs(obj[0] - target[0]) <= 0.08,
        near_object=0.0,
        grasp_reward=0.0,
        in_place_reward=0.0,
        obj_to_target=0.0,
    )


def drawer_open(step: StepInputs) -> tuple[Array, dict[str, Array]]:
    pull_dist = jnp.abs(step.obs.obj[1] - step.target_pos[1])
    return fixture_v1(step, pull_dist, max_dist=0.2, success_radius=0.03)


def drawer_close(step: StepInputs) -> tuple[Array, dict[str, Array]]:
    pull_dist = jnp.abs(step.obs.obj[1] - step.target_pos[1])
    # Reference quirk: success is TARGET_RADIUS + 0.015 with the base class's TARGET_RADIUS 0.05
    # (the class sets _TARGET_RADIUS = 0.04, which evaluate_state never reads).
    return fixture_v1(step, pull_dist, max_dist=0.15, success_radius=0.065)


def _button_v1(
    step: StepInputs, axis: int, success_radius: float, left_finger_only: bool
) -> tuple[Array, dict[str, Array]]:
    # maxDist is the reset's |buttonStart - hole| along the press axis: obj_to_target_init.
    press_dist = jnp.abs(step.obs.obj[axis] - step.target_pos[axis])
    return fixture_v1(
        step, press_dist, step.constants["obj_to_target_init"], success_radius, left_finger_only
    )


def button_press_topdown(step: StepInputs) -> tuple[Array, dict[str, Array]]:
    return _button_v1(step, axis=2, success_radius=0.024, left_finger_only=False)


def button_press_topdown_wall(step: StepInputs) -> tuple[Array, dict[str, Array]]:
    return _button_v1(step, axis=2, success_radius=0.024, left_finger_only=False)


def button_press(step: StepInputs) -> tuple[Array, dict[str, Array]]:
    # Quirk: the front buttons are reached with the left fingertip, not the tcp.
    return _button_v1(step, axis=1, success_radius=0.02, left_finger_only=True)


def button_press_wall(step: StepInputs) -> tuple[Array, dict[str, Array]]:
    """Reference quirk: maxDist is |buttonStart - hole| along z, though the button is pressed along
    y: 0, as both sites sit on the box at one height. Both are fixed on the box, so the current
    frame gives the reset's value."""
    frame = step.frame
    max_dist = jnp.abs(frame.site_pos("buttonStart")[2] - step.target_pos[2])
    press_dist = jnp.abs(step.obs.obj[1] - step.target_pos[1])
    return fixture_v1(step, press_dist, max_dist, success_radius=0.03, left_finger_only=True)


def _window_v1(step: StepInputs) -> tuple[Array, dict[str, Array]]:
    # Slide the handle to the goal's x; maxPullDist is 0.2 and, unlike the other tasks, the
    # progress term is not clipped at 0. Success: TARGET_RADIUS 0.05.
    pull_dist = jnp.abs(step.obs.obj[0] - step.target_pos[0])
    return fixture_v1(step, pull_dist, max_dist=0.2, success_radius=0.05, clip=False)


window_open = _window_v1


window_close = _window_v1


def door_close(step: StepInputs) -> tuple[Array, dict[str, Array]]:
    """Swing the handle to the goal in xy (door-open's reward); success within 8 cm."""
    obj, target = step.obs.obj, step.target_pos
    pull_dist = jnp.linalg.norm(obj[:2] - target[:2])
    reward = fixture_reward(obj, step.frame.tcp_center, pull_dist, step.constants["max_pull_dist"])
    # evaluate_state reports constants for near_object and grasp_reward, and V1's 0 as in place.
    return info_terms(
        reward,
        success=pull_dist <= 0.08,
        near_object=0.0,
        grasp_reward=1.0,
        in_place_reward=0.0,
        obj_to_target=pull_dist,
    )


def door_lock(step: StepInputs) -> tuple[Array, dict[str, Array]]:
    """door-lock and door-unlock: move the lock point to the goal; success within 2 cm."""
    pull_dist = jnp.linalg.norm(step.obs.obj - step.target_pos)
    return fixture_v1(step, pull_dist, step.constants["max_pull_dist"], success_radius=0.02)


door_unlock = door_lock
