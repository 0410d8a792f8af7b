"""V1 reward kernels of the basketball, soccer tasks (`mwjax/tasks/ball.py`).

V1's tcp_to_obj is a hard-coded 0 in these tasks, so evaluate_state's near_object
(0 <= radius) is always 1.
"""

from __future__ import annotations

import jax.numpy as jnp

from mwjax.contracts import StepInputs
from mwjax.rewards_v1.terms import lift_and_place, place_v1
from mwjax.rewards_v2.terms import info_terms

Array = jnp.ndarray


def basketball(step: StepInputs) -> tuple[Array, dict[str, Array]]:
    reward, info = lift_and_place(step, pick_baseline=0.0)
    # Basketball's success radius is its TARGET_RADIUS, 8 cm (7 in pick-out-of-hole and shelf-place).
    return info_terms(
        reward,
        success=info["obj_to_target"] <= 0.08,
        near_object=info["near_object"],
        grasp_reward=info["grasp_reward"],
        in_place_reward=info["in_place_reward"],
        obj_to_target=info["obj_to_target"],
    )


def soccer(step: StepInputs) -> tuple[Array, dict[str, Array]]:
    obj = step.obs.obj
    reach_dist = jnp.linalg.norm(step.frame.tcp_center - obj)
    push_dist = jnp.linalg.norm(obj[:2] - step.target_pos[:2])
    push = jnp.where(reach_dist < 0.05, place_v1(push_dist, step.constants["max_push_dist"]), 0.0)
    return info_terms(
        -reach_dist + push,
        success=push_dist <= 0.07,
        near_object=1.0,
        grasp_reward=0.0,
        in_place_reward=0.0,
        obj_to_target=push_dist,
    )
