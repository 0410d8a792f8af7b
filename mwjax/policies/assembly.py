"""Experts for the assembly family (see mwjax/tasks/assembly.py)."""

from __future__ import annotations

import jax
import jax.numpy as jnp

from mwjax.observation import Observation
from mwjax.policies.common import action, first_true, move, register, xy_dist

Array = jax.Array


@register("assembly-v3")
def assembly(obs: Array) -> Array:
    o = Observation(obs)
    wrench = o.obj + jnp.array([-0.02, 0.0, 0.0])  # the wrench's handle
    peg = o.goal + jnp.array([0.12, 0.0, 0.14])  # where the hand holds the wrench's ring over the peg
    target = first_true(
        [
            (xy_dist(o.hand, wrench) > 0.02, wrench + jnp.array([0.0, 0.0, 0.1])),
            # Checked before the descent onto the wrench: once over the peg, drop the ring on it.
            (xy_dist(o.hand, peg) <= 0.02, peg + jnp.array([0.0, 0.0, -0.2])),
            (jnp.abs(o.hand[2] - wrench[2]) > 0.05, wrench + jnp.array([0.0, 0.0, 0.03])),
            (jnp.abs(o.hand[2] - peg[2]) > 0.04, o.hand.at[2].set(peg[2])),  # lift to the peg's height
        ],
        peg,
    )
    off_wrench = (xy_dist(o.hand, wrench) > 0.02) | (jnp.abs(o.hand[2] - wrench[2]) > 0.12)
    return action(move(o.hand, target, p=10.0), jnp.where(off_wrench, 0.0, 0.6))


@register("disassemble-v3")
def disassemble(obs: Array) -> Array:
    o = Observation(obs)
    wrench = o.obj + jnp.array([-0.02, 0.0, 0.01])
    target = first_true(
        [
            (xy_dist(o.hand, wrench) > 0.02, wrench + jnp.array([0.0, 0.0, 0.1])),
            (jnp.abs(o.hand[2] - wrench[2]) > 0.03, wrench),
        ],
        o.hand + jnp.array([0.0, 0.0, 0.1]),  # lift the wrench off the peg
    )
    off_wrench = (xy_dist(o.hand, wrench) > 0.02) | (jnp.abs(o.hand[2] - wrench[2]) > 0.07)
    return action(move(o.hand, target, p=10.0), jnp.where(off_wrench, 0.0, 0.8))
