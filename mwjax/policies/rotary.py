"""Experts for the rotary family (see mwjax/tasks/rotary.py)."""

from __future__ import annotations

import jax
import jax.numpy as jnp

from mwjax.observation import Observation
from mwjax.policies.common import action, first_true, move, register, xy_dist

Array = jax.Array


@register("dial-turn-v3")
def dial_turn(obs: Array) -> Array:
    o = Observation(obs)
    knob = o.obj + jnp.array([0.05, 0.02, 0.09])
    target = first_true(
        [
            (xy_dist(o.hand, knob) > 0.02, jnp.stack([knob[0], knob[1], 0.2])),  # over the knob at z 0.2
            (jnp.abs(o.hand[2] - knob[2]) > 0.02, knob),
        ],
        knob + jnp.array([-0.05, 0.005, 0.0]),  # sweep the knob round
    )
    return action(move(o.hand, target, p=10.0), 1.0)


@register("lever-pull-v3")
def lever_pull(obs: Array) -> Array:
    o = Observation(obs)
    lever = o.obj + jnp.array([0.0, -0.055, 0.0])
    target = first_true(
        [
            (xy_dist(o.hand, lever) > 0.02, lever + jnp.array([0.0, 0.0, -0.1])),  # come in under the lever
            (jnp.abs(o.hand[2] - lever[2]) > 0.02, lever),
        ],
        lever + jnp.array([0.0, 0.08, 0.02]),  # lift it up and back
    )
    return action(move(o.hand, target, p=25.0), 1.0)


def _turn_faucet(obs: Array, side: float) -> Array:
    """Hover over the handle's `-side` x edge, drop to it, then push it round towards `side`."""
    o = Observation(obs)
    handle = o.obj + jnp.array([-0.04 * side, 0.0, 0.03])
    target = first_true(
        [
            (xy_dist(o.hand, handle) > 0.04, handle + jnp.array([0.0, 0.0, 0.1])),
            (jnp.abs(o.hand[2] - handle[2]) > 0.04, handle),
        ],
        handle + jnp.array([0.1 * side, 0.05, 0.0]),
    )
    return action(move(o.hand, target, p=25.0), 1.0)


@register("faucet-open-v3")
def faucet_open(obs: Array) -> Array:
    return _turn_faucet(obs, side=1.0)


@register("faucet-close-v3")
def faucet_close(obs: Array) -> Array:
    return _turn_faucet(obs, side=-1.0)
