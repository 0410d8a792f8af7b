"""Experts for the coffee family (see mwjax/tasks/coffee.py)."""

from __future__ import annotations

import jax
import jax.numpy as jnp

from mwjax.observation import Observation
from mwjax.policies.common import action, first_true, move, register, xy_dist

Array = jax.Array


@register("coffee-button-v3")
def coffee_button(obs: Array) -> Array:
    o = Observation(obs)
    button = o.obj + jnp.array([0.0, 0.0, -0.07])
    xz_error = jnp.linalg.norm(o.hand[jnp.array([0, 2])] - button[jnp.array([0, 2])])
    target = jnp.where(
        xz_error > 0.02,
        button.at[1].set(o.hand[1]),  # line up in front of the button
        button + jnp.array([0.0, 0.2, 0.0]),  # then push in along +y
    )
    return action(move(o.hand, target, p=10.0), -1.0)


def _carry_mug(obs: Array, grasp_dx: float, approach_height: float, destination: Array, grip: float) -> Array:
    """Hover over the mug, descend to it, then carry it to `destination` (coffee pull and push).

    The hand aims `grasp_dx` along x from the mug; the grip test always uses +0.01."""
    o = Observation(obs)
    grasp = o.obj + jnp.array([grasp_dx, 0.0, 0.05])
    target = first_true(
        [
            (xy_dist(o.hand, grasp) > 0.06, grasp + jnp.array([0.0, 0.0, approach_height])),
            (jnp.abs(o.hand[2] - grasp[2]) > 0.02, grasp),
        ],
        destination,
    )
    handle = o.obj + jnp.array([0.01, 0.0, 0.05])
    off_mug = (xy_dist(o.hand, handle) > 0.06) | (jnp.abs(o.hand[2] - handle[2]) > 0.1)
    return action(move(o.hand, target, p=10.0), jnp.where(off_mug, -1.0, grip))


@register("coffee-pull-v3")
def coffee_pull(obs: Array) -> Array:
    goal = Observation(obs).goal
    return _carry_mug(obs, grasp_dx=-0.005, approach_height=0.15, destination=goal, grip=0.7)


@register("coffee-push-v3")
def coffee_push(obs: Array) -> Array:
    goal = Observation(obs).goal
    return _carry_mug(obs, grasp_dx=0.01, approach_height=0.2, destination=goal.at[2].set(0.1), grip=0.5)
