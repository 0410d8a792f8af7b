"""V2 reward kernels of the box-close task (`mwjax/tasks/box_close.py`)."""

from __future__ import annotations

import jax.numpy as jnp

from mwjax.contracts import StepInputs
from mwjax.rewards_v2.terms import above_floor_term, funnel_floor, hamacher_product, info_terms, within

Array = jnp.ndarray


def box_close(step: StepInputs) -> tuple[Array, dict[str, Array]]:
    """`SawyerBoxCloseEnvV3.compute_reward` (v2): reach the lid's handle from above with the
    gripper closing, put the lid on the box, all scaled by how upright the lid is."""
    obs, target = step.obs, step.target_pos
    hand = obs.hand
    lid = obs.obj + jnp.array([0.0, 0.0, 0.02])
    reward_grab = jnp.clip((jnp.clip(step.action[3], -1.0, 1.0) + 1.0) / 2.0, 0.0, 1.0)
    # The lid's xquat (w, x, y, z) against the upright (0.707, 0, 0, 0.707), linearly.
    upright = jnp.maximum(
        1.0 - jnp.linalg.norm(obs.obj_quat - jnp.array([0.707, 0.0, 0.0, 0.707])) / 0.2, 0.0
    )
    floor = funnel_floor(jnp.linalg.norm(hand[:2] - lid[:2]), 0.02, 0.04, 0.4)
    above_floor = above_floor_term(hand[2], floor, margin=floor / 2.0)
    in_place = within(jnp.linalg.norm(hand - lid), 0.02, 0.5)
    ready_to_lift = hamacher_product(above_floor, in_place)
    placed = within(jnp.linalg.norm((target - lid) * jnp.array([1.0, 1.0, 3.0])), 0.05, 0.25)
    lifted = 0.2 * (lid[2] > 0.04) + 0.8 * placed
    reward = 2.0 * hamacher_product(reward_grab, ready_to_lift) + 8.0 * lifted
    success = jnp.linalg.norm(obs.obj - target) < 0.08
    # The success override comes before the orientation scaling, so a tilted lid scores below 10.
    reward = jnp.where(success, 10.0, reward) * upright
    return info_terms(
        reward,
        success=success,
        near_object=ready_to_lift,  # the reference reports the readiness term as near_object
        grasp_reward=reward_grab,
        in_place_reward=lifted,
        obj_to_target=0.0,  # the reference hard-codes 0
    )
