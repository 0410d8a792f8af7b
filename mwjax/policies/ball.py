"""Experts for the ball family (see mwjax/tasks/ball.py)."""

from __future__ import annotations

import jax
import jax.numpy as jnp

from mwjax.observation import Observation
from mwjax.policies.common import action, first_true, move, register, xy_dist

Array = jax.Array


@register("basketball-v3")
def basketball(obs: Array) -> Array:
    o = Observation(obs)
    ball = o.obj + jnp.array([0.0, 0.0, 0.01])
    # The hoop's x comes from the goal; its y varies in [0.85, 0.9] (the reference takes the middle)
    # and its height is fixed.
    hoop = jnp.array([o.goal[0], 0.875, 0.35])
    target = first_true(
        [
            (xy_dist(o.hand, ball) > 0.04, ball + jnp.array([0.0, 0.0, 0.3])),
            (jnp.abs(o.hand[2] - ball[2]) > 0.025, ball),
            (jnp.abs(ball[2] - hoop[2]) > 0.025, o.hand.at[2].set(hoop[2])),  # lift straight up
        ],
        hoop,
    )
    # The grip tests the ball's own centre, not the raised grasp point.
    off_ball = (xy_dist(o.hand, o.obj) > 0.04) | (jnp.abs(o.hand[2] - o.obj[2]) > 0.15)
    return action(move(o.hand, target, p=25.0), jnp.where(off_ball, -1.0, 0.6))


@register("soccer-v3")
def soccer(obs: Array) -> Array:
    o = Observation(obs)
    ball = o.obj + jnp.array([0.0, 0.0, 0.03])
    offset = 0.03
    # Push from the side facing away from the goal: from -y, or from -x / +x when the ball is
    # more than 5 cm to the left / right of the goal.
    dx = ball[0] - o.goal[0]
    push_from = first_true(
        [(dx < -0.05, jnp.array([-offset, 0.0, 0.0])), (dx > 0.05, jnp.array([offset, 0.0, 0.0]))],
        jnp.array([0.0, -offset, 0.0]),
    )
    # Hover higher when right above the ball, so as not to knock it.
    push_z = jnp.where(xy_dist(o.hand, ball) < 0.02, 0.1, 0.03)
    push_location = (ball + push_from).at[2].set(push_z)
    target = jnp.where(jnp.linalg.norm(o.hand - push_location) > 0.01, push_location, ball)
    return action(move(o.hand, target, p=25.0), 1.0)
