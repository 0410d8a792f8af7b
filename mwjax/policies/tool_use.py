"""Experts for the tool_use family (see mwjax/tasks/tool_use.py)."""

from __future__ import annotations

import jax
import jax.numpy as jnp

from mwjax.observation import Observation
from mwjax.policies.common import action, first_true, move, register, xy_dist

Array = jax.Array


def _stick_to_thermos(obs: Array, stick_dx: float, thermos_offset: Array, goal: Array, p: float) -> Array:
    """Grasp the stick, bring its tip in line with the thermos (y, then z), push into it; once the
    stick is within 4 cm of the thermos along x, head for `goal` (stick push and pull)."""
    o = Observation(obs)
    stick = o.obj + jnp.array([stick_dx, 0.0, 0.03])
    thermos = o.obj2 + thermos_offset
    to_thermos = first_true(
        [
            (xy_dist(o.hand, stick) > 0.02, stick + jnp.array([0.0, 0.0, 0.1])),
            (jnp.abs(o.hand[2] - stick[2]) > 0.02, stick),
            (jnp.abs(stick[1] - thermos[1]) > 0.02, stick.at[1].set(thermos[1])),
            (jnp.abs(stick[2] - thermos[2]) > 0.02, thermos.at[0].set(stick[0])),
        ],
        thermos,
    )
    target = jnp.where(jnp.abs(stick[0] - thermos[0]) > 0.04, to_thermos, goal)
    off_stick = (xy_dist(o.hand, stick) > 0.02) | (jnp.abs(o.hand[2] - stick[2]) > 0.1)
    return action(move(o.hand, target, p=p), jnp.where(off_stick, -1.0, 0.7))


@register("stick-push-v3")
def stick_push(obs: Array) -> Array:
    goal = Observation(obs).goal + jnp.array([0.0, 0.0, 0.132])
    return _stick_to_thermos(obs, stick_dx=0.015, thermos_offset=jnp.zeros(3), goal=goal, p=10.0)


@register("stick-pull-v3")
def stick_pull(obs: Array) -> Array:
    goal = Observation(obs).goal + jnp.array([-0.05, 0.0, 0.0])
    thermos_offset = jnp.array([-0.015, 0.0, 0.03])
    return _stick_to_thermos(obs, stick_dx=-0.015, thermos_offset=thermos_offset, goal=goal, p=25.0)


@register("hammer-v3")
def hammer(obs: Array) -> Array:
    o = Observation(obs)
    grip = o.obj + jnp.array([-0.04, 0.0, -0.01])  # the hammer's handle
    # The reference ignores the observed goal: a fixed point in front of the nail.
    strike = jnp.array([0.24 - 0.19, 0.71, 0.11 + 0.05])
    xz = jnp.array([0, 2])
    target = first_true(
        [
            (xy_dist(o.hand, grip) > 0.04, grip + jnp.array([0.0, 0.0, 0.1])),
            (
                (jnp.abs(o.hand[2] - grip[2]) > 0.05) & (grip[2] < 0.03),
                grip + jnp.array([0.0, 0.0, 0.03]),
            ),
            # Swing over to the nail's x and z first, keeping y, then move in along y.
            (jnp.linalg.norm(o.hand[xz] - strike[xz]) > 0.02, strike.at[1].set(o.hand[1])),
        ],
        strike,
    )
    off_hammer = (xy_dist(o.hand, grip) > 0.04) | (jnp.abs(o.hand[2] - grip[2]) > 0.1)
    return action(move(o.hand, target, p=10.0), jnp.where(off_hammer, 0.0, 0.8))
