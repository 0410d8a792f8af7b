"""V1 reward kernels of the pick-out-of-hole, shelf-place, bin-picking tasks (`mwjax/tasks/placing.py`)."""

from __future__ import annotations

import jax.numpy as jnp

from mwjax.contracts import StepInputs
from mwjax.rewards_v1.terms import dropped_v1, lift_and_place, pick_v1, place_v1, reach_v1
from mwjax.rewards_v2.terms import info_terms

Array = jnp.ndarray


def pick_out_of_hole(step: StepInputs) -> tuple[Array, dict[str, Array]]:
    # Heights count from 2 cm below the start height (the hole's depth), not from 0.
    return lift_and_place(step, pick_baseline=step.constants["obj_height"] - 0.02)


def shelf_place(step: StepInputs) -> tuple[Array, dict[str, Array]]:
    return lift_and_place(step, pick_baseline=0.0)


def bin_picking(step: StepInputs) -> tuple[Array, dict[str, Array]]:
    c = step.constants
    obj = step.obs.obj
    goal = step.target_pos
    height_target, obj_height = c["height_target"], c["obj_height"]
    reach, reach_dist = reach_v1(step, obj, c["init_tcp"][2], 0.06, 1.0, 0.05)
    placing_dist = jnp.linalg.norm(obj[:2] - goal[:2])
    picked = obj[2] >= height_target - 0.01
    dropped = dropped_v1(obj[2], obj_height, placing_dist, reach_dist)
    over_bin = (jnp.abs(obj[0] - goal[0]) < 0.05) & (jnp.abs(obj[1] - goal[1]) < 0.05)
    placed = over_bin & (obj[2] < obj_height + 0.05)
    pick = pick_v1(placed | (picked & ~dropped), obj[2], height_target, obj_height, reach_dist, 0.1)
    place = place_v1(placing_dist, c["max_placing_dist"])
    # Over the goal bin, opening the gripper (negative action) earns up to 200.
    release = -200.0 * step.action[-1]
    carrying = picked & (reach_dist < 0.1) & ~dropped
    place_term = jnp.where(carrying, jnp.where(over_bin, release + place, place), 0.0)
    # Placed (in the goal bin, low), the reward is only release + place: reach and pick drop out.
    reward = jnp.where(placed, release + place, reach + pick + place_term)
    return info_terms(
        reward,
        success=placing_dist <= 0.05,
        near_object=0.0,
        grasp_reward=0.0,
        in_place_reward=0.0,
        obj_to_target=placing_dist,
    )
