"""V1 reward kernels of the handle-press, handle-pull (and their side variants) tasks
(`mwjax/tasks/handles.py`).
"""

from __future__ import annotations

import jax.numpy as jnp

from mwjax.contracts import StepInputs
from mwjax.rewards_v1.terms import fixture_v1

Array = jnp.ndarray


def handle_press_side(step: StepInputs) -> tuple[Array, dict[str, Array]]:
    """Push the handle down to the goal's z with the left fingertip. maxDist is the reset's
    |handleStart z - goal z| (handle_init_pos is handleStart after set_state)."""
    max_dist = jnp.abs(step.constants["handle_init_pos"][2] - step.target_pos[2])
    press_dist = jnp.abs(step.obs.obj[2] - step.target_pos[2])
    return fixture_v1(step, press_dist, max_dist, success_radius=0.02, left_finger_only=True)


def handle_pull_side(step: StepInputs) -> tuple[Array, dict[str, Array]]:
    """Pull the handle up to the goal's z with the left fingertip; success within 8 cm.

    maxDist is the reset's |handleStart z - goal z|. Our constants keep handleCenter's reset
    position (obj_init_pos); both sites ride on the lever link, which only slides along z, so the
    reset's handleStart height is obj_init_pos's plus their current height difference."""
    frame = step.frame
    start_above_center = frame.site_pos("handleStart")[2] - frame.site_pos("handleCenter")[2]
    max_dist = jnp.abs(step.constants["obj_init_pos"][2] + start_above_center - step.target_pos[2])
    press_dist = jnp.abs(step.obs.obj[2] - step.target_pos[2])
    return fixture_v1(step, press_dist, max_dist, success_radius=0.08, left_finger_only=True)


# handle-press's V1 code is handle-press-side's, line for line.
handle_press = handle_press_side


def handle_pull(step: StepInputs) -> tuple[Array, dict[str, Array]]:
    """Lift the handle's right end to the goal's z, reached with the left fingertip; success within
    the base class's TARGET_RADIUS (5 cm)."""
    press_dist = jnp.abs(step.obs.obj[2] - step.target_pos[2])
    return fixture_v1(
        step, press_dist, step.constants["max_pull_dist"], success_radius=0.05, left_finger_only=True
    )
