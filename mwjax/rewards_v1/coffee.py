"""V1 reward kernels of the coffee-button, coffee-pull, coffee-push tasks (`mwjax/tasks/coffee.py`)."""

from __future__ import annotations

import jax.numpy as jnp

from mwjax.contracts import StepInputs
from mwjax.rewards_v1.terms import fixture_reward, progress_once_reached
from mwjax.rewards_v2.terms import info_terms

Array = jnp.ndarray


def coffee_button(step: StepInputs) -> tuple[Array, dict[str, Array]]:
    """Press the button along y, reached with the left fingertip (as the front buttons do); maxDist
    is the reset's |buttonStart y - goal y|, success within 2 cm."""
    button = step.obs.obj
    press_dist = jnp.abs(button[1] - step.target_pos[1])
    reward = fixture_reward(
        button, step.frame.site_pos("leftEndEffector"), press_dist, step.constants["max_press_dist"]
    )
    # evaluate_state reads V1's zero tcp distance as near the object.
    return info_terms(reward, press_dist <= 0.02, 1.0, 0.0, 0.0, press_dist)


def _coffee_mug(step: StepInputs, reach_rew: Array, max_dist: Array) -> tuple[Array, dict[str, Array]]:
    """coffee-pull's and coffee-push's v1 progress of the mug toward the goal in the plane once
    the fingers are at it; success on the 3-d distance within 7 cm."""
    mug, target = step.obs.obj, step.target_pos
    reach_dist = jnp.linalg.norm(step.frame.tcp_center - mug)
    slide_rew = progress_once_reached(reach_dist, jnp.linalg.norm(mug[:2] - target[:2]), max_dist)
    # evaluate_state reads V1's zero tcp distance as near the object.
    obj_to_target = jnp.linalg.norm(mug - target)
    return info_terms(reach_rew + slide_rew, obj_to_target <= 0.07, 1.0, 0.0, 0.0, obj_to_target)


def coffee_pull(step: StepInputs) -> tuple[Array, dict[str, Array]]:
    mug = step.obs.obj
    reach_dist = jnp.linalg.norm(step.frame.tcp_center - mug)
    # Reference quirk: "reachDistxy" is the norm of the point (mug x, mug y, init_tcp z), not a
    # distance; it never drops below 0.05 on this table, so the reach term is -that norm.
    reach_dist_xy = jnp.linalg.norm(jnp.stack([mug[0], mug[1], step.constants["init_tcp"][2]]))
    grip_bonus = jnp.where(reach_dist < 0.05, jnp.maximum(step.action[-1], 0.0) / 50.0, 0.0)
    reach_rew = jnp.where(reach_dist_xy < 0.05, -reach_dist + 0.1 + grip_bonus, -reach_dist_xy)
    return _coffee_mug(step, reach_rew, step.constants["max_pull_dist"])


def coffee_push(step: StepInputs) -> tuple[Array, dict[str, Array]]:
    return _coffee_mug(
        step, -jnp.linalg.norm(step.frame.tcp_center - step.obs.obj), step.constants["max_push_dist"]
    )
