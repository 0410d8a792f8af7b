"""Experts for the peg family (see mwjax/tasks/peg.py)."""

from __future__ import annotations

import jax
import jax.numpy as jnp

from mwjax.observation import Observation
from mwjax.policies.common import action, first_true, move, register, xy_dist

Array = jax.Array


@register("peg-insert-side-v3")
def peg_insert_side(obs: Array) -> Array:
    o = Observation(obs)
    # The hole: its y is the goal's; x overshoots the lowest goal x (harmless), z is fixed.
    hole = jnp.array([-0.35, o.goal[1], 0.16])
    target = first_true(
        [
            (xy_dist(o.hand, o.obj) > 0.04, o.obj + jnp.array([0.0, 0.0, 0.3])),
            (jnp.abs(o.hand[2] - o.obj[2]) > 0.025, o.obj),
            # Line the peg up with the hole (y and z) 40 cm in front of it, then push in along x.
            (jnp.linalg.norm(o.obj[1:] - hole[1:]) > 0.03, hole + jnp.array([0.4, 0.0, 0.0])),
        ],
        hole,
    )
    off_peg = (xy_dist(o.hand, o.obj) > 0.04) | (jnp.abs(o.hand[2] - o.obj[2]) > 0.15)
    return action(move(o.hand, target, p=25.0), jnp.where(off_peg, -1.0, 0.6))


@register("peg-unplug-side-v3")
def peg_unplug_side(obs: Array) -> Array:
    o = Observation(obs)
    peg = o.obj + jnp.array([-0.02, 0.0, 0.035])
    target = first_true(
        [
            (xy_dist(o.hand, peg) > 0.04, peg + jnp.array([0.0, 0.0, 0.2])),
            (jnp.abs(o.hand[2] - 0.15) > 0.02, peg.at[2].set(0.15)),  # descend to a fixed height
        ],
        o.hand + jnp.array([0.01, 0.0, 0.0]),  # pull the peg out along +x
    )
    off_peg = (xy_dist(o.hand, peg) > 0.04) | (jnp.abs(o.hand[2] - peg[2]) > 0.15)
    return action(move(o.hand, target, p=25.0), jnp.where(off_peg, -1.0, 0.1))
