"""V2 reward kernels of the peg-insert-side, peg-unplug-side tasks (`mwjax/tasks/peg.py`)."""

from __future__ import annotations

import jax.numpy as jnp

from mwjax.contracts import StepInputs
from mwjax.rewards_v2.terms import (
    grasp_place_info,
    gripper_caging,
    hamacher_product,
    rect_prism_tolerance,
    tolerance,
    within,
)

Array = jnp.ndarray


def peg_insert_side(step: StepInputs) -> tuple[Array, dict[str, Array]]:
    frame = step.frame
    obj = step.obs.obj
    tcp_opened = step.obs.gripper
    target = step.target_pos
    obj_head = frame.site_pos("pegHead")
    obj_init_pos = step.constants["obj_init_pos"]
    tcp_to_obj = jnp.linalg.norm(obj - frame.tcp_center)
    scale = jnp.array([1.0, 2.0, 2.0])
    obj_to_target = jnp.linalg.norm((obj_head - target) * scale)
    in_place = tolerance(
        obj_to_target,
        bounds=(0.0, 0.07),
        # peg_head_pos_init is the XML-default peg head (see peg.py), not this episode's.
        margin=jnp.linalg.norm((step.constants["peg_head_pos_init"] - target) * scale),
        sigmoid="long_tail",
    )
    collision_box_1 = rect_prism_tolerance(
        obj_head,
        zero=frame.site_pos("bottom_right_corner_collision_box_1"),
        one=frame.site_pos("top_left_corner_collision_box_1"),
    )
    collision_box_2 = rect_prism_tolerance(
        obj_head,
        zero=frame.site_pos("bottom_right_corner_collision_box_2"),
        one=frame.site_pos("top_left_corner_collision_box_2"),
    )
    in_place = hamacher_product(in_place, hamacher_product(collision_box_2, collision_box_1))
    object_grasped = gripper_caging(
        step,
        obj,
        obj_radius=0.0075,
        pad_success_thresh=0.03,
        object_reach_radius=0.01,
        xz_thresh=0.005,
        high_density=True,
    )
    lifted = (tcp_to_obj < 0.08) & (tcp_opened > 0) & (obj[2] - 0.01 > obj_init_pos[2])
    object_grasped = jnp.where(lifted, 1.0, object_grasped)
    reward = hamacher_product(object_grasped, in_place)
    reward = jnp.where(lifted, reward + 1.0 + 5.0 * in_place, reward)
    reward = jnp.where(obj_to_target <= 0.07, 10.0, reward)
    return grasp_place_info(
        reward, obj_to_target, tcp_to_obj, object_grasped, in_place, success_radius=0.07, near_radius=0.03
    )


def peg_unplug_side(step: StepInputs) -> tuple[Array, dict[str, Array]]:
    """`SawyerPegUnplugSideEnvV3.compute_reward` (v2): grasp the plug, pull it out sideways."""
    obj = step.obs.obj
    tcp_opened = step.obs.gripper
    target = step.target_pos
    obj_init_pos = step.constants["obj_init_pos"]
    tcp_to_obj = jnp.linalg.norm(obj - step.frame.tcp_center)
    obj_to_target = jnp.linalg.norm(obj - target)
    object_grasped = gripper_caging(
        step,
        obj,
        obj_radius=0.025,
        pad_success_thresh=0.05,
        object_reach_radius=0.01,
        xz_thresh=0.005,
        desired_gripper_effort=0.8,
        high_density=True,
    )
    in_place = within(obj_to_target, 0.05, jnp.linalg.norm(obj_init_pos - target))
    pulling = (tcp_opened > 0.5) & (obj[0] - obj_init_pos[0] > 0.015) & (tcp_to_obj < 0.035)
    reward = jnp.where(pulling, 1.0 + 2.0 * object_grasped + 5.0 * in_place, 2.0 * object_grasped)
    reward = jnp.where(obj_to_target <= 0.05, 10.0, reward)
    return grasp_place_info(
        reward, obj_to_target, tcp_to_obj, object_grasped, in_place, success_radius=0.07, near_radius=0.03
    )
