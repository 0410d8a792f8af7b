"""Experts for the box_close family (see mwjax/tasks/box_close.py)."""

from __future__ import annotations

import jax
import jax.numpy as jnp

from mwjax.observation import Observation
from mwjax.policies.common import action, first_true, move, near, register, xy_dist

Array = jax.Array


@register("box-close-v3")
def box_close(obs: Array) -> Array:
    o = Observation(obs)
    lid = o.obj + jnp.array([0.0, 0.0, 0.02])  # the lid's handle
    box = o.goal.at[2].set(0.15)  # above the box; the goal's height is not used
    target = first_true(
        [
            (xy_dist(o.hand, lid) > 0.01, lid.at[2].set(0.2)),
            (jnp.abs(o.hand[2] - lid[2]) > 0.05, lid),
            (jnp.abs(o.hand[2] - box[2]) > 0.04, o.hand.at[2].set(box[2])),  # lift to carrying height
        ],
        box,
    )
    grab = jnp.where(near(o.hand, lid, 0.01, 0.13), 1.0, 0.5)
    return action(move(o.hand, target, p=25.0), grab)
