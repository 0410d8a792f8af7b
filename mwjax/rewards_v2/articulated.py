"""V2 reward kernels of the door, drawer, button-press, window, door-close, door-lock, door-unlock tasks
(`mwjax/tasks/articulated.py`).
"""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np

from mwjax.contracts import StepInputs
from mwjax.rewards_v2.terms import (
    TARGET_RADIUS,
    above_floor_term,
    button_info,
    button_reach_press,
    button_terms,
    funnel_floor,
    grasp_place_info,
    hamacher_product,
    info_terms,
    tolerance,
    within,
)

Array = jnp.ndarray


def door_open(step: StepInputs) -> tuple[Array, dict[str, Array]]:
    """`SawyerDoorEnvV3.compute_reward` (v2): get above a funnel floor near the handle, then
    swing the hinge open."""
    hand = step.obs.hand
    door = step.obs.obj + jnp.array([-0.05, 0.0, 0.0])
    theta = step.frame.joint_qpos("doorjoint")
    reward_grab = (jnp.clip(step.action[3], -1.0, 1.0) + 1.0) / 2.0

    threshold = 0.12
    floor = funnel_floor(jnp.linalg.norm(hand[:2] - door[:2]), threshold, 0.04, 0.4)
    above_floor = above_floor_term(hand[2], floor, margin=floor / 2.0)
    in_place = within(jnp.linalg.norm(hand - door - jnp.array([0.05, 0.03, -0.01])), threshold / 2.0, 0.5)
    ready_to_open = hamacher_product(above_floor, in_place)

    door_angle = -theta
    opened = 0.2 * (theta < -jnp.pi / 90.0) + 0.8 * within(
        jnp.pi / 2.0 + jnp.pi / 6 - door_angle, 0.5, jnp.pi / 3.0
    )
    reward = 2.0 * hamacher_product(ready_to_open, reward_grab) + 8.0 * opened
    # Success and the reward override look only at the handle's x against the goal's x.
    success = jnp.abs(step.obs.obj[0] - step.target_pos[0]) <= 0.08
    reward = jnp.where(success, 10.0, reward)
    return info_terms(
        reward,
        success=success,
        near_object=ready_to_open,  # the reference reports the readiness term as near_object
        grasp_reward=reward_grab,
        in_place_reward=opened,
        obj_to_target=0.0,  # the reference hard-codes 0
    )


def drawer_open(step: StepInputs) -> tuple[Array, dict[str, Array]]:
    """`SawyerDrawerOpenEnvV3.compute_reward` (v2): reach the handle, pull it to the goal."""
    max_dist = 0.2
    gripper = step.obs.hand  # quirk: the hand body position, while the init term uses init_tcp
    handle = step.obs.obj
    target = step.target_pos
    handle_error = jnp.linalg.norm(handle - target)
    reward_for_opening = within(handle_error, 0.02, max_dist)
    handle_pos_init = target + jnp.array([0.0, max_dist, 0.0])
    scale = jnp.array([3.0, 3.0, 1.0])
    gripper_error = (handle - gripper) * scale
    gripper_error_init = (handle_pos_init - step.constants["init_tcp"]) * scale
    reward_for_caging = within(jnp.linalg.norm(gripper_error), 0.01, jnp.linalg.norm(gripper_error_init))
    reward = 5.0 * (reward_for_caging + reward_for_opening)
    return info_terms(
        reward,
        success=handle_error <= 0.03,
        near_object=jnp.linalg.norm(handle - gripper) <= 0.03,
        grasp_reward=reward_for_caging,
        in_place_reward=reward_for_opening,
        obj_to_target=handle_error,
    )


def drawer_close(step: StepInputs) -> tuple[Array, dict[str, Array]]:
    """`SawyerDrawerCloseEnvV3.compute_reward` (v2): reach the handle with a closed gripper, push
    the drawer shut."""
    # Quirk: the class sets _TARGET_RADIUS = 0.04 but reads the base class's TARGET_RADIUS (0.05).
    radius = TARGET_RADIUS
    obj = step.obs.obj
    tcp = step.frame.tcp_center
    target = step.target_pos
    obj_init_pos, init_tcp = step.constants["obj_init_pos"], step.constants["init_tcp"]
    # The handle point sits 5 cm above the goal's z, so target_to_obj never drops below 0.05.
    target_to_obj = jnp.linalg.norm(obj - target)
    target_to_obj_init = jnp.linalg.norm(obj_init_pos - target)
    in_place = within(target_to_obj, radius, jnp.abs(target_to_obj_init - radius))
    handle_reach_radius = 0.005
    tcp_to_obj = jnp.linalg.norm(obj - tcp)
    tcp_to_obj_init = jnp.linalg.norm(obj_init_pos - init_tcp)
    reach = tolerance(
        tcp_to_obj,
        bounds=(0.0, handle_reach_radius),
        margin=jnp.abs(tcp_to_obj_init - handle_reach_radius),
        sigmoid="gaussian",
    )
    gripper_closed = jnp.minimum(jnp.maximum(0.0, step.action[-1]), 1.0)
    reach = hamacher_product(reach, gripper_closed)
    reward = hamacher_product(reach, in_place)
    success = target_to_obj <= radius + 0.015
    reward = 10.0 * jnp.where(success, 1.0, reward)
    return info_terms(
        reward,
        success=success,
        near_object=tcp_to_obj <= 0.01,
        grasp_reward=reach,
        in_place_reward=in_place,
        obj_to_target=target_to_obj,
    )


def button_press_topdown(step: StepInputs) -> tuple[Array, dict[str, Array]]:
    return button_reach_press(step, 2, 0.01, 1.0 - step.obs.gripper, (5.0, 5.0), 0.03, 0.024)


def button_press_topdown_wall(step: StepInputs) -> tuple[Array, dict[str, Array]]:
    # Quirk: the wall variant's "tcp_closed" is max(opening, 0), topdown's 1 - opening.
    return button_reach_press(step, 2, 0.01, jnp.maximum(step.obs.gripper, 0.0), (5.0, 5.0), 0.03, 0.024)


def button_press(step: StepInputs) -> tuple[Array, dict[str, Array]]:
    # Quirk: "tcp_closed" is max(opening, 0): the gripper's opening, not its closing.
    return button_reach_press(step, 1, 0.05, jnp.maximum(step.obs.gripper, 0.0), (2.0, 8.0), 0.05, 0.02)


def button_press_wall(step: StepInputs) -> tuple[Array, dict[str, Array]]:
    terms = button_terms(step, 1, 0.01)
    tcp_to_obj, _, near_button, button_pressed = terms
    far = 2.0 * hamacher_product((1.0 - step.obs.gripper) / 2.0, near_button)
    near = 2.0 + 2.0 * (1.0 + step.obs.gripper) + 4.0 * button_pressed**2
    reward = jnp.where(tcp_to_obj > 0.07, far, near)
    return button_info(reward, 0.03, terms)


def _window(
    step: StepInputs, handle_site: str, target_to_obj_init: Array, reach_sigmoid: str
) -> tuple[Array, dict[str, Array]]:
    """The shared V2 window reward: slide the handle to the target's x while reaching it."""
    obj = step.frame.site_pos(handle_site)
    tcp = step.frame.tcp_center
    target_to_obj = jnp.abs(obj[0] - step.target_pos[0])
    in_place = within(target_to_obj, TARGET_RADIUS, jnp.abs(target_to_obj_init - TARGET_RADIUS))
    handle_radius = 0.02
    tcp_to_obj = jnp.linalg.norm(obj - tcp)
    tcp_to_obj_init = jnp.linalg.norm(step.constants["window_handle_pos_init"] - step.constants["init_tcp"])
    reach = tolerance(
        tcp_to_obj,
        bounds=(0.0, handle_radius),
        margin=jnp.abs(tcp_to_obj_init - handle_radius),
        sigmoid=reach_sigmoid,
    )
    reward = 10.0 * hamacher_product(reach, in_place)
    return grasp_place_info(
        reward, target_to_obj, tcp_to_obj, reach, in_place, success_radius=TARGET_RADIUS, near_radius=0.05
    )


def window_open(step: StepInputs) -> tuple[Array, dict[str, Array]]:
    # Quirk: the initial distance is from the window body's x (obj_init_pos), not the handle's,
    # so the in-place margin is always |0.2 - 0.05|.
    target_to_obj_init = jnp.abs(step.constants["obj_init_pos"][0] - step.target_pos[0])
    return _window(step, "handleOpenStart", target_to_obj_init, reach_sigmoid="long_tail")


def window_close(step: StepInputs) -> tuple[Array, dict[str, Array]]:
    target_to_obj_init = jnp.abs(step.constants["window_handle_pos_init"][0] - step.target_pos[0])
    # Quirk: window-close's reach term uses a gaussian sigmoid where window-open uses long_tail.
    return _window(step, "handleCloseStart", target_to_obj_init, reach_sigmoid="gaussian")


def door_close(step: StepInputs) -> tuple[Array, dict[str, Array]]:
    """`SawyerDoorCloseEnvV3.compute_reward` (v2): bring the hand to the goal while the handle
    swings there."""
    obj, target = step.obs.obj, step.target_pos
    tcp_to_target = jnp.linalg.norm(step.frame.tcp_center - target)
    obj_to_target = jnp.linalg.norm(obj - target)
    in_place = tolerance(
        obj_to_target,
        bounds=(0.0, TARGET_RADIUS),
        margin=jnp.linalg.norm(step.constants["obj_init_pos"] - target),
        sigmoid="gaussian",
    )
    # Quirk: the hand term's margin runs from the nominal hand_init_pos to the current handle.
    hand_margin = jnp.linalg.norm(step.constants["hand_init_pos"] - obj) + 0.1
    hand_in_place = tolerance(
        tcp_to_target, bounds=(0.0, 0.25 * TARGET_RADIUS), margin=hand_margin, sigmoid="gaussian"
    )
    reward = jnp.where(obj_to_target < TARGET_RADIUS, 10.0, 3.0 * hand_in_place + 6.0 * in_place)
    # The reference reports constants for near_object and grasp_reward, and the hand term as
    # in_place_reward.
    return info_terms(
        reward,
        success=obj_to_target <= 0.08,
        near_object=0.0,
        grasp_reward=1.0,
        in_place_reward=hand_in_place,
        obj_to_target=obj_to_target,
    )


_LOCK_LENGTH = 0.1  # the lock tasks' `_lock_length`: the in-place margin


_LOCK_SCALE = np.array([0.25, 1.0, 0.5], np.float32)  # x counts least, z half, in the reach distances


def door_lock(step: StepInputs) -> tuple[Array, dict[str, Array]]:
    """`SawyerDoorLockEnvV3.compute_reward` (v2): left pad to the lock, push it down to the goal z."""
    obj = step.obs.obj
    tcp_to_obj = jnp.linalg.norm((obj - step.frame.left_pad) * _LOCK_SCALE)
    # Reference quirk: init_left_pad is a live view of the left pad's xpos, so the "initial"
    # distance is the current one and the reach margin shrinks with the distance itself.
    tcp_to_obj_init = tcp_to_obj
    obj_to_target = jnp.abs(step.target_pos[2] - obj[2])
    near_lock = within(tcp_to_obj, 0.01, tcp_to_obj_init)
    lock_pressed = within(obj_to_target, 0.005, _LOCK_LENGTH)
    tcp_opened = jnp.maximum(step.obs.gripper, 0.0)
    reward = 2.0 * hamacher_product(tcp_opened, near_lock) + 8.0 * lock_pressed
    return info_terms(
        reward,
        success=obj_to_target <= 0.02,
        near_object=tcp_to_obj <= 0.05,
        grasp_reward=near_lock,
        in_place_reward=lock_pressed,
        obj_to_target=obj_to_target,
    )


def door_unlock(step: StepInputs) -> tuple[Array, dict[str, Array]]:
    """`SawyerDoorUnlockEnvV3.compute_reward` (v2): the gripper's "shoulder" (hand + offset) to the
    lock, push it sideways to the goal x."""
    hand, lock = step.obs.hand, step.obs.obj
    shoulder_offset = jnp.array([0.0, 0.055, 0.07])
    shoulder_to_lock = jnp.linalg.norm((hand + shoulder_offset - lock) * _LOCK_SCALE)
    # Reference quirk: obj_init_pos is a live view of lock_link's xpos (the lock's hinge, which
    # stays put), read here from the current frame.
    lock_hinge = step.frame.body_pos("lock_link")
    shoulder_to_lock_init = jnp.linalg.norm(
        (step.constants["init_tcp"] + shoulder_offset - lock_hinge) * _LOCK_SCALE
    )
    ready_to_push = within(shoulder_to_lock, 0.02, shoulder_to_lock_init)
    obj_to_target = jnp.abs(step.target_pos[0] - lock[0])
    pushed = within(obj_to_target, 0.005, _LOCK_LENGTH)
    reward = 2.0 * ready_to_push + 8.0 * pushed
    return info_terms(
        reward,
        success=obj_to_target <= 0.02,
        near_object=shoulder_to_lock <= 0.05,
        grasp_reward=ready_to_push,
        in_place_reward=pushed,
        obj_to_target=obj_to_target,
    )
