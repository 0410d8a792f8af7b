"""V1 reward kernels of the faucet, dial-turn, lever-pull tasks (`mwjax/tasks/rotary.py`)."""

from __future__ import annotations

import jax.numpy as jnp

from mwjax.contracts import StepInputs
from mwjax.rewards_v1.terms import fixture_reward, fixture_v1
from mwjax.rewards_v2.terms import info_terms

Array = jnp.ndarray


def _faucet_v1(step: StepInputs) -> tuple[Array, dict[str, Array]]:
    # Turn the handle end (`obs.obj`, without V2's offset) to the goal; maxPullDist is the reset's
    # |goal - faucet base|. Success within 7 cm.
    pull_dist = jnp.linalg.norm(step.obs.obj - step.target_pos)
    max_dist = jnp.linalg.norm(step.target_pos - step.constants["obj_init_pos"])
    return fixture_v1(step, pull_dist, max_dist, success_radius=0.07)


faucet_open = _faucet_v1


faucet_close = _faucet_v1


def dial_turn(step: StepInputs) -> tuple[Array, dict[str, Array]]:
    """Turn the dial's rim point to the goal's y; success within TARGET_RADIUS 0.07.

    maxPullDist is |goal y - obj_init_pos y| with obj_init_pos = rand_vec, where the dial body
    stays (a fixed body the reset moves). Quirk: dial-turn's exponentials are 10x narrower."""
    pull_dist = jnp.abs(step.obs.obj[1] - step.target_pos[1])
    max_dist = jnp.abs(step.target_pos[1] - step.frame.body_pos("dial")[1])
    return fixture_v1(step, pull_dist, max_dist, success_radius=0.07, c2=0.001, c3=0.0001)


def lever_pull(step: StepInputs) -> tuple[Array, dict[str, Array]]:
    """Reach the lever's end, pull it to the goal above the axis (maxPullDist: |goal - lever base|)."""
    lever = step.obs.obj
    pull_dist = jnp.linalg.norm(lever - step.target_pos)
    reward = fixture_reward(lever, step.frame.tcp_center, pull_dist, step.constants["max_pull_dist"])
    # Quirk: evaluate_state reads V1's pull distance as lever_error, so success is
    # pull_dist <= pi/24 (a distance against an angle threshold); its zero shoulder distance
    # counts as near the object and is reported as obj_to_target.
    return info_terms(reward, pull_dist <= jnp.pi / 24.0, 1.0, 0.0, 0.0, 0.0)
