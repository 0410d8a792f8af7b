"""V2 reward kernels of the coffee-button, coffee-pull, coffee-push tasks (`mwjax/tasks/coffee.py`)."""

from __future__ import annotations

import jax.numpy as jnp

from mwjax.contracts import StepInputs
from mwjax.rewards_v2.articulated import button_press
from mwjax.rewards_v2.terms import grasp_place_info, gripper_caging, hamacher_product, within

Array = jnp.ndarray


def coffee_button(step: StepInputs) -> tuple[Array, dict[str, Array]]:
    """`SawyerCoffeeButtonEnvV3.compute_reward` (v2): button-press's reward (press along y,
    weights 2 and 8, success within 0.02); the press margin `obj_to_target_init` is the class's
    constant max_dist (0.03)."""
    return button_press(step)


def coffee_mug(step: StepInputs) -> tuple[Array, dict[str, Array]]:
    """coffee-pull's and coffee-push's (identical) v2 reward: cage the mug, slide it to the goal,
    x and y errors weighted twice."""
    obj, target = step.obs.obj, step.target_pos
    tcp_opened = step.obs.gripper
    scale = jnp.array([2.0, 2.0, 1.0])
    target_to_obj = jnp.linalg.norm((obj - target) * scale)
    in_place = within(target_to_obj, 0.05, jnp.linalg.norm((step.constants["obj_init_pos"] - target) * scale))
    tcp_to_obj = jnp.linalg.norm(obj - step.frame.tcp_center)
    object_grasped = gripper_caging(
        step,
        obj,
        obj_radius=0.02,
        pad_success_thresh=0.05,
        object_reach_radius=0.04,
        xz_thresh=0.05,
        desired_gripper_effort=0.7,
        medium_density=True,
    )
    reward = hamacher_product(object_grasped, in_place)
    reward = jnp.where((tcp_to_obj < 0.04) & (tcp_opened > 0), reward + 1.0 + 5.0 * in_place, reward)
    reward = jnp.where(target_to_obj < 0.05, 10.0, reward)
    # Success and obj_to_target use the unscaled distance.
    obj_to_target = jnp.linalg.norm(obj - target)
    return grasp_place_info(
        reward, obj_to_target, tcp_to_obj, object_grasped, in_place, success_radius=0.07, near_radius=0.03
    )
