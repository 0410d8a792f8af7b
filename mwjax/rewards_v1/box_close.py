"""V1 reward kernels of the box-close task (`mwjax/tasks/box_close.py`)."""

from __future__ import annotations

import jax.numpy as jnp

from mwjax.contracts import StepInputs
from mwjax.rewards_v1.terms import dropped_v1, pick_v1, place_v1, reach_v1
from mwjax.rewards_v2.terms import info_terms

Array = jnp.ndarray


def box_close(step: StepInputs) -> tuple[Array, dict[str, Array]]:
    """`SawyerBoxCloseEnvV3.compute_reward` (v1): reach the lid, lift it to heightTarget, carry it
    to the box. Markov: pickCompleted is recomputed from the current lid height every step."""
    c = step.constants
    lid, target = step.obs.obj, step.target_pos
    placing_dist = jnp.linalg.norm(lid - target)
    reach_rew, reach_dist = reach_v1(step, lid, c["init_tcp"][2], 0.05, 2.0, 0.05)
    height_target, obj_height = c["height_target"], c["obj_height"]
    pick_completed = lid[2] >= height_target - 0.01
    # On the table, away from both the goal and the gripper.
    dropped = dropped_v1(lid[2], obj_height, placing_dist, reach_dist)
    pick_rew = pick_v1(pick_completed & ~dropped, lid[2], height_target, obj_height, reach_dist, 0.1)
    placing = pick_completed & (reach_dist < 0.1) & ~dropped
    place_rew = jnp.where(placing, place_v1(placing_dist, c["max_placing_dist"]), 0.0)
    reward = reach_rew + pick_rew + place_rew
    # V1's compute_reward reports zeros for every info term but success.
    return info_terms(reward, placing_dist < 0.08, 0.0, 0.0, 0.0, 0.0)
