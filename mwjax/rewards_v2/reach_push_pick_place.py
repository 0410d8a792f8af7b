"""V2 reward kernels of the reach, push, pick-place (and their walls), push-back, sweep,
sweep-into and hand-insert tasks (`mwjax/tasks/reach_push_pick_place.py`).
"""

from __future__ import annotations

import jax.numpy as jnp

from mwjax.contracts import StepInputs
from mwjax.rewards_v2.terms import (
    TARGET_RADIUS,
    grasp_place_info,
    gripper_caging,
    hamacher_product,
    info_terms,
    pad_gripping_caging,
    pick_place_caging,
    tolerance,
    within,
)

Array = jnp.ndarray


def pick_place(step: StepInputs) -> tuple[Array, dict[str, Array]]:
    obj = step.obs.obj
    tcp_opened = step.obs.gripper
    tcp = step.frame.tcp_center
    target = step.target_pos
    obj_init_pos = step.constants["obj_init_pos"]
    obj_to_target = jnp.linalg.norm(obj - target)
    tcp_to_obj = jnp.linalg.norm(obj - tcp)
    in_place = within(obj_to_target, TARGET_RADIUS, jnp.linalg.norm(obj_init_pos - target))
    object_grasped = pick_place_caging(step, obj)
    reward = hamacher_product(object_grasped, in_place)
    lifted = (tcp_to_obj < 0.02) & (tcp_opened > 0) & (obj[2] - 0.01 > obj_init_pos[2])
    reward = jnp.where(lifted, reward + 1.0 + 5.0 * in_place, reward)
    reward = jnp.where(obj_to_target < TARGET_RADIUS, 10.0, reward)
    return grasp_place_info(
        reward, obj_to_target, tcp_to_obj, object_grasped, in_place, success_radius=0.07, near_radius=0.03
    )


def _reach(step: StepInputs) -> tuple[Array, Array, Array]:
    """reach's V2 reward (shared by reach-wall): `(reward, tcp_to_target, in_place)`."""
    tcp_to_target = jnp.linalg.norm(step.frame.tcp_center - step.target_pos)
    in_place = tolerance(
        tcp_to_target,
        bounds=(0.0, TARGET_RADIUS),
        # Margin from the nominal hand_init_pos, not the settled init_tcp.
        margin=jnp.linalg.norm(step.constants["hand_init_pos"] - step.target_pos),
        sigmoid="long_tail",
    )
    return 10.0 * in_place, tcp_to_target, in_place


def reach(step: StepInputs) -> tuple[Array, dict[str, Array]]:
    reward, tcp_to_target, in_place = _reach(step)
    # Quirk: reach reports the raw tcp-goal distance as near_object and grasp_reward.
    return info_terms(
        reward,
        success=tcp_to_target <= 0.05,
        near_object=tcp_to_target,
        grasp_reward=tcp_to_target,
        in_place_reward=in_place,
        obj_to_target=tcp_to_target,
    )


def reach_wall(step: StepInputs) -> tuple[Array, dict[str, Array]]:
    reward, tcp_to_target, in_place = _reach(step)
    # reach-wall reports near_object and grasp_reward as constant 0.
    return info_terms(
        reward,
        success=tcp_to_target <= 0.05,
        near_object=0.0,
        grasp_reward=0.0,
        in_place_reward=in_place,
        obj_to_target=tcp_to_target,
    )


def _in_place(step: StepInputs, obj: Array, target: Array) -> tuple[Array, Array]:
    """The object's distance to `target` and its long-tail tolerance, whose margin is the distance
    the object started at (push, hand-insert, sweep)."""
    obj_to_target = jnp.linalg.norm(obj - target)
    in_place = within(obj_to_target, TARGET_RADIUS, jnp.linalg.norm(step.constants["obj_init_pos"] - target))
    return obj_to_target, in_place


def _push_terms(step: StepInputs) -> tuple[Array, Array, Array, Array]:
    """push's and hand-insert's shared terms: object-to-target distance, in place, the
    high-density caging of a 1.5 cm object, and the hand-to-object distance."""
    obj = step.obs.obj
    target_to_obj, in_place = _in_place(step, obj, step.target_pos)
    object_grasped = gripper_caging(
        step,
        obj,
        obj_radius=0.015,
        pad_success_thresh=0.05,
        object_reach_radius=0.01,
        xz_thresh=0.005,
        high_density=True,
    )
    return target_to_obj, in_place, object_grasped, jnp.linalg.norm(obj - step.frame.tcp_center)


def push(step: StepInputs) -> tuple[Array, dict[str, Array]]:
    tcp_opened = step.obs.gripper
    target_to_obj, in_place, object_grasped, tcp_to_obj = _push_terms(step)
    reward = 2.0 * object_grasped
    # Quirk: `reward += 1.0 + reward + 5.0 * in_place` adds the caging term a second time.
    near = (tcp_to_obj < 0.02) & (tcp_opened > 0)
    reward = jnp.where(near, reward + 1.0 + reward + 5.0 * in_place, reward)
    reward = jnp.where(target_to_obj < TARGET_RADIUS, 10.0, reward)
    return grasp_place_info(
        reward,
        target_to_obj,
        tcp_to_obj,
        object_grasped,
        in_place,
        success_radius=TARGET_RADIUS,
        near_radius=0.03,
    )


def _around_wall(
    step: StepInputs,
    midpoint: Array,
    in_place_scaling: Array,
    pick: bool,
) -> tuple[Array, dict[str, Array]]:
    """push-wall and pick-place-wall: in place at a midpoint past the wall, then at the goal.

    The base is `2 * caging` for push-wall (high density caging) and `hamacher(caging, in_place
    at midpoint)` for pick-place-wall (plain caging), whose bonus also needs the puck lifted.
    """
    obj = step.obs.obj
    tcp_opened = step.obs.gripper
    target = step.target_pos
    obj_init_pos = step.constants["obj_init_pos"]
    tcp_to_obj = jnp.linalg.norm(obj - step.frame.tcp_center)
    obj_to_midpoint = jnp.linalg.norm((obj - midpoint) * in_place_scaling)
    obj_to_midpoint_init = jnp.linalg.norm((obj_init_pos - midpoint) * in_place_scaling)
    obj_to_target = jnp.linalg.norm(obj - target)
    in_place_part1 = within(obj_to_midpoint, TARGET_RADIUS, obj_to_midpoint_init)
    in_place_part2 = within(obj_to_target, TARGET_RADIUS, jnp.linalg.norm(obj_init_pos - target))
    object_grasped = gripper_caging(
        step,
        obj,
        obj_radius=0.015,
        pad_success_thresh=0.05,
        object_reach_radius=0.01,
        xz_thresh=0.005,
        high_density=not pick,
    )
    base = hamacher_product(object_grasped, in_place_part1) if pick else 2.0 * object_grasped
    near = (tcp_to_obj < 0.02) & (tcp_opened > 0)
    if pick:
        near = near & (obj[2] - 0.015 > obj_init_pos[2])
    reward = jnp.where(near, base + 1.0 + 4.0 * in_place_part1, base)
    reward = jnp.where(near & (obj[1] > 0.75), base + 1.0 + 4.0 + 3.0 * in_place_part2, reward)
    reward = jnp.where(obj_to_target < TARGET_RADIUS, 10.0, reward)
    return info_terms(
        reward,
        success=obj_to_target <= 0.07,
        near_object=tcp_to_obj <= 0.03,
        grasp_reward=object_grasped,
        in_place_reward=in_place_part2,
        obj_to_target=obj_to_target,
    )


def push_wall(step: StepInputs) -> tuple[Array, dict[str, Array]]:
    # The midpoint's z follows the puck (so only x and y count).
    midpoint = jnp.stack([-0.05, 0.77, step.obs.obj[2]])
    return _around_wall(step, midpoint, jnp.array([3.0, 1.0, 1.0]), pick=False)


def pick_place_wall(step: StepInputs) -> tuple[Array, dict[str, Array]]:
    midpoint = jnp.stack([step.target_pos[0], 0.77, 0.25])
    return _around_wall(step, midpoint, jnp.array([1.0, 1.0, 3.0]), pick=True)


def push_back(step: StepInputs) -> tuple[Array, dict[str, Array]]:
    obj = step.obs.obj
    tcp_opened = step.obs.gripper
    target = step.target_pos
    tcp_to_obj = jnp.linalg.norm(obj - step.frame.tcp_center)
    target_to_obj = jnp.linalg.norm(obj - target)
    target_to_obj_init = jnp.linalg.norm(step.constants["obj_init_pos"] - target)
    in_place = within(target_to_obj, TARGET_RADIUS, target_to_obj_init)
    object_grasped = pad_gripping_caging(
        step, obj, obj_radius=0.007, grip_success_margin=0.007 + 0.003, x_z_success_margin=0.01
    )
    reward = hamacher_product(object_grasped, in_place)
    pushing = (tcp_to_obj < 0.01) & (0 < tcp_opened) & (tcp_opened < 0.55)
    pushing = pushing & (target_to_obj_init - target_to_obj > 0.01)
    reward = jnp.where(pushing, reward + 1.0 + 5.0 * in_place, reward)
    reward = jnp.where(target_to_obj < TARGET_RADIUS, 10.0, reward)
    return grasp_place_info(
        reward, target_to_obj, tcp_to_obj, object_grasped, in_place, success_radius=0.07, near_radius=0.03
    )


def _sweep_reward(
    step: StepInputs, target: Array, grip_success_margin: float, x_z_success_margin: float
) -> tuple[Array, dict[str, Array]]:
    obj = step.obs.obj
    obj_to_target, in_place = _in_place(step, obj, target)
    tcp_to_obj = jnp.linalg.norm(obj - step.frame.tcp_center)
    object_grasped = pad_gripping_caging(step, obj, 0.02, grip_success_margin, x_z_success_margin)
    reward = 2.0 * object_grasped + 6.0 * hamacher_product(object_grasped, in_place)
    reward = jnp.where(obj_to_target < TARGET_RADIUS, 10.0, reward)
    return grasp_place_info(
        reward, obj_to_target, tcp_to_obj, object_grasped, in_place, success_radius=0.05, near_radius=0.03
    )


def sweep(step: StepInputs) -> tuple[Array, dict[str, Array]]:
    return _sweep_reward(step, step.target_pos, grip_success_margin=0.03, x_z_success_margin=0.005)


def sweep_into(step: StepInputs) -> tuple[Array, dict[str, Array]]:
    # The target's z follows the puck (so only x and y count), margin included.
    target = jnp.stack([step.target_pos[0], step.target_pos[1], step.obs.obj[2]])
    return _sweep_reward(step, target, grip_success_margin=0.025, x_z_success_margin=0.01)


def hand_insert(step: StepInputs) -> tuple[Array, dict[str, Array]]:
    tcp_opened = step.obs.gripper
    target_to_obj, in_place, object_grasped, tcp_to_obj = _push_terms(step)
    reward = hamacher_product(object_grasped, in_place)
    reward = jnp.where((tcp_to_obj < 0.02) & (tcp_opened > 0), reward + 1.0 + 7.0 * in_place, reward)
    reward = jnp.where(target_to_obj < TARGET_RADIUS, 10.0, reward)
    return grasp_place_info(
        reward, target_to_obj, tcp_to_obj, object_grasped, in_place, success_radius=0.05, near_radius=0.03
    )
