"""Experts for the handles family (see mwjax/tasks/handles.py)."""

from __future__ import annotations

import jax
import jax.numpy as jnp

from mwjax.observation import Observation
from mwjax.policies.common import action, first_true, move, register, xy_dist

Array = jax.Array


def _press(obs: Array, handle_dy: float, grab: float) -> Array:
    """Hover over the handle (shifted `handle_dy` along y), then push it down hard."""
    o = Observation(obs)
    handle = o.obj + jnp.array([0.0, handle_dy, 0.0])
    target = jnp.where(
        xy_dist(o.hand, handle) > 0.02,
        handle + jnp.array([0.0, 0.0, 0.2]),
        handle + jnp.array([0.0, 0.0, -0.5]),
    )
    return action(move(o.hand, target, p=25.0), grab)


@register("handle-press-side-v3")
def handle_press_side(obs: Array) -> Array:
    return _press(obs, handle_dy=0.0, grab=1.0)


@register("handle-press-v3")
def handle_press(obs: Array) -> Array:
    return _press(obs, handle_dy=-0.02, grab=-1.0)


@register("handle-pull-side-v3")
def handle_pull_side(obs: Array) -> Array:
    o = Observation(obs)
    target = first_true(
        [
            (xy_dist(o.hand, o.obj) > 0.04, o.obj + jnp.array([0.0, 0.0, 0.1])),
            (jnp.abs(o.hand[2] - o.obj[2]) > 0.03, o.obj),
        ],
        o.obj + jnp.array([0.0, 0.0, 1.0]),  # pull up
    )
    off_handle = (xy_dist(o.hand, o.obj) > 0.04) | (jnp.abs(o.hand[2] - o.obj[2]) > 0.04)
    return action(move(o.hand, target, p=25.0), jnp.where(off_handle, 0.0, 0.6))


@register("handle-pull-v3")
def handle_pull(obs: Array) -> Array:
    o = Observation(obs)
    handle = o.obj + jnp.array([0.0, -0.04, 0.0])
    target = first_true(
        [
            (xy_dist(o.hand, handle) > 0.02, handle),
            # Reference quirk: this branch returns the bare height, so the hand heads for
            # (z, z, z) on all three axes.
            (jnp.abs(o.hand[2] - handle[2]) > 0.02, jnp.full(3, handle[2])),
        ],
        handle + jnp.array([0.0, 0.0, 0.1]),
    )
    return action(move(o.hand, target, p=25.0), 1.0)
