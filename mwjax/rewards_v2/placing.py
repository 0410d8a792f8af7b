"""V2 reward kernels of the pick-out-of-hole, shelf-place, bin-picking tasks (`mwjax/tasks/placing.py`)."""

from __future__ import annotations

import jax.numpy as jnp

from mwjax.contracts import StepInputs
from mwjax.rewards_v2.terms import (
    TARGET_RADIUS,
    above_floor_term,
    funnel_floor,
    grasp_place_info,
    gripper_caging,
    hamacher_product,
    info_terms,
    tolerance,
    within,
)

Array = jnp.ndarray


def pick_out_of_hole(step: StepInputs) -> tuple[Array, dict[str, Array]]:
    """`SawyerPickOutOfHoleEnvV3.compute_reward` (v2): grasp the peg in the hole, lift it out to
    the goal while the tcp stays above a funnel around the hole."""
    obj = step.obs.obj
    tcp = step.frame.tcp_center
    target = step.target_pos
    obj_init_pos = step.constants["obj_init_pos"]
    obj_to_target = jnp.linalg.norm(obj - target)
    tcp_to_obj = jnp.linalg.norm(obj - tcp)
    floor = funnel_floor(jnp.linalg.norm(tcp[:2] - obj_init_pos[:2]), 0.03, 0.015, 0.15)
    above_floor = above_floor_term(tcp[2], floor, margin=0.02)
    object_grasped = gripper_caging(
        step,
        obj,
        obj_radius=0.015,
        pad_success_thresh=0.02,
        object_reach_radius=0.01,
        xz_thresh=0.03,
        desired_gripper_effort=0.1,
        high_density=True,
    )
    in_place = within(obj_to_target, 0.02, jnp.linalg.norm(obj_init_pos - target))
    reward = hamacher_product(object_grasped, in_place)
    # Near, lifted 2 cm, and the fingers not pinched shut on nothing.
    grasped = (tcp_to_obj < 0.04) & (obj[2] - 0.02 > obj_init_pos[2]) & (step.obs.gripper >= 0.33)
    reward = jnp.where(grasped, reward + 1.0 + 5.0 * hamacher_product(in_place, above_floor), reward)
    # Quirk: the override reads the base class's TARGET_RADIUS (0.05), not the class's 0.02.
    reward = jnp.where(obj_to_target < TARGET_RADIUS, 10.0, reward)
    return grasp_place_info(
        reward, obj_to_target, tcp_to_obj, object_grasped, in_place, success_radius=0.07, near_radius=0.03
    )


def shelf_place(step: StepInputs) -> tuple[Array, dict[str, Array]]:
    """`SawyerShelfPlaceEnvV3.compute_reward` (v2): pick the block, place it on the shelf, with
    the in-place term withdrawn below the shelf board."""
    obj = step.obs.obj
    tcp_opened = step.obs.gripper
    target = step.target_pos
    obj_init_pos = step.constants["obj_init_pos"]
    obj_to_target = jnp.linalg.norm(obj - target)
    tcp_to_obj = jnp.linalg.norm(obj - step.frame.tcp_center)
    in_place = within(obj_to_target, TARGET_RADIUS, jnp.linalg.norm(obj_init_pos - target))
    object_grasped = gripper_caging(
        step,
        obj,
        obj_radius=0.02,
        pad_success_thresh=0.05,
        object_reach_radius=0.01,
        xz_thresh=0.01,
    )
    reward = hamacher_product(object_grasped, in_place)
    # Below the board (z in (0, 0.24)) and within the shelf's width: in front of it the in-place
    # term loses a penalty growing toward the board; past the goal's y (inside) it is zeroed.
    under_board = (0.0 < obj[2]) & (obj[2] < 0.24) & (target[0] - 0.15 < obj[0]) & (obj[0] < target[0] + 0.15)
    front_edge = target[1] - 3 * TARGET_RADIUS
    in_front = under_board & (front_edge < obj[1]) & (obj[1] < target[1])
    bound_loss = hamacher_product((obj[1] - front_edge) / (3 * TARGET_RADIUS), (0.24 - obj[2]) / 0.24)
    in_place = jnp.where(in_front, jnp.clip(in_place - bound_loss, 0.0, 1.0), in_place)
    in_place = jnp.where(under_board & (obj[1] > target[1]), 0.0, in_place)
    lifted = (tcp_to_obj < 0.025) & (tcp_opened > 0) & (obj[2] - 0.01 > obj_init_pos[2])
    reward = jnp.where(lifted, reward + 1.0 + 5.0 * in_place, reward)
    reward = jnp.where(obj_to_target < TARGET_RADIUS, 10.0, reward)
    return grasp_place_info(
        reward, obj_to_target, tcp_to_obj, object_grasped, in_place, success_radius=0.07, near_radius=0.03
    )


def bin_picking(step: StepInputs) -> tuple[Array, dict[str, Array]]:
    """`SawyerBinPickingEnvV3.compute_reward` (v2): carry the cube from its bin to the goal bin,
    the hand kept above funnels around both bins."""
    hand = step.obs.hand
    obj = step.obs.obj
    target = step.target_pos
    obj_init_pos = step.constants["obj_init_pos"]
    target_to_obj = jnp.linalg.norm(obj - target)
    in_place = tolerance(
        target_to_obj,
        bounds=(0.0, TARGET_RADIUS),
        # Latched on the episode's first step (see TaskSpec.latch), not at reset.
        margin=step.constants["target_to_obj_init"],
        sigmoid="long_tail",
    )
    floor = jnp.minimum(
        funnel_floor(jnp.linalg.norm(hand[:2] - obj_init_pos[:2]), 0.03, 0.02, 0.2),
        funnel_floor(jnp.linalg.norm(hand[:2] - target[:2]), 0.03, 0.02, 0.2),
    )
    above_floor = above_floor_term(hand[2], floor, margin=0.05)
    object_grasped = gripper_caging(
        step,
        obj,
        obj_radius=0.015,
        pad_success_thresh=0.05,
        object_reach_radius=0.01,
        xz_thresh=0.01,
        desired_gripper_effort=0.7,
        high_density=True,
    )
    reward = hamacher_product(object_grasped, in_place)
    # Quirk: "near" is measured from the hand body, not the tcp.
    near_object = jnp.linalg.norm(obj - hand) < 0.04
    grasped = near_object & (obj[2] - 0.02 > obj_init_pos[2]) & (step.obs.gripper >= 0.43)
    reward = jnp.where(grasped, reward + 1.0 + 5.0 * hamacher_product(above_floor, in_place), reward)
    reward = jnp.where(target_to_obj < TARGET_RADIUS, 10.0, reward)
    return info_terms(
        reward,
        success=target_to_obj <= 0.05,
        near_object=near_object,
        grasp_reward=object_grasped,
        in_place_reward=in_place,
        obj_to_target=target_to_obj,
    )
