"""V2 reward kernels of the basketball, soccer tasks (`mwjax/tasks/ball.py`)."""

from __future__ import annotations

import jax.numpy as jnp

from mwjax.contracts import StepInputs
from mwjax.rewards_v2.terms import (
    grasp_place_info,
    gripper_caging,
    hamacher_product,
    pad_gripping_caging,
    within,
)

Array = jnp.ndarray


def basketball(step: StepInputs) -> tuple[Array, dict[str, Array]]:
    radius = 0.08  # the class's TARGET_RADIUS
    obj = step.obs.obj
    tcp_opened = step.obs.gripper
    obj_init_pos = step.constants["obj_init_pos"]
    # Aim slightly above the hoop, and count height errors double.
    target = step.target_pos.at[2].set(0.3)
    scale = jnp.array([1.0, 1.0, 2.0])
    target_to_obj = jnp.linalg.norm((obj - target) * scale)
    in_place = within(target_to_obj, radius, jnp.linalg.norm((obj_init_pos - target) * scale))
    tcp_to_obj = jnp.linalg.norm(obj - step.frame.tcp_center)
    object_grasped = gripper_caging(
        step,
        obj,
        obj_radius=0.025,
        pad_success_thresh=0.06,
        object_reach_radius=0.01,
        xz_thresh=0.005,
        high_density=True,
    )
    lifted = (tcp_to_obj < 0.035) & (tcp_opened > 0) & (obj[2] - 0.01 > obj_init_pos[2])
    object_grasped = jnp.where(lifted, 1.0, object_grasped)
    reward = hamacher_product(object_grasped, in_place)
    reward = jnp.where(lifted, reward + 1.0 + 5.0 * in_place, reward)
    reward = jnp.where(target_to_obj < radius, 10.0, reward)
    return grasp_place_info(
        reward, target_to_obj, tcp_to_obj, object_grasped, in_place, success_radius=radius, near_radius=0.05
    )


def soccer(step: StepInputs) -> tuple[Array, dict[str, Array]]:
    radius = 0.07  # the class's TARGET_RADIUS
    obj = step.obs.obj
    target = step.target_pos
    scale = jnp.array([3.0, 1.0, 1.0])  # x errors count triple
    tcp_to_obj = jnp.linalg.norm(obj - step.frame.tcp_center)
    target_to_obj = jnp.linalg.norm((obj - target) * scale)
    # Quirk: the "initial" distance is from the ball to its start position, so the margin is how far
    # the ball has moved (0 before it moves: a step function).
    moved = jnp.linalg.norm((obj - step.constants["obj_init_pos"]) * scale)
    in_place = within(target_to_obj, radius, moved)
    # Past the line 10 cm before the goal but more than 10 cm off its x, in place decays.
    goal_line = target[1] - 0.1
    wide = (obj[1] > goal_line) & (jnp.abs(obj[0] - target[0]) > 0.10)
    penalised = jnp.clip(in_place - 2.0 * ((obj[1] - goal_line) / (1.0 - goal_line)), 0.0, 1.0)
    in_place = jnp.where(wide, penalised, in_place)
    obj_radius = 0.013  # the class's OBJ_RADIUS
    object_grasped = pad_gripping_caging(step, obj, obj_radius, obj_radius + 0.01, x_z_success_margin=0.005)
    reward = 3.0 * object_grasped + 6.5 * in_place
    reward = jnp.where(target_to_obj < radius, 10.0, reward)
    # Success and the reported distance are unscaled.
    obj_to_target = jnp.linalg.norm(obj - target)
    return grasp_place_info(
        reward, obj_to_target, tcp_to_obj, object_grasped, in_place, success_radius=0.07, near_radius=0.03
    )
