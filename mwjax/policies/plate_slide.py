"""Experts for the plate_slide family (see mwjax/tasks/plate_slide.py)."""

from __future__ import annotations

import jax
import jax.numpy as jnp

from mwjax.observation import Observation
from mwjax.policies.common import action, first_true, move, register, xy_dist

Array = jax.Array


def _slide(o: Observation, contact: Array, xy_tol: float, hover: float, push_target: Array) -> Array:
    """The plate slides' shared plan: hover `hover` above the contact point beside the plate,
    descend onto it, then push toward `push_target`."""
    return first_true(
        [
            (xy_dist(o.hand, contact) > xy_tol, contact + jnp.array([0.0, 0.0, hover])),
            (jnp.abs(o.hand[2] - contact[2]) > 0.04, contact),
        ],
        push_target,
    )


@register("plate-slide-v3")
def plate_slide(obs: Array) -> Array:
    o = Observation(obs)
    contact = o.obj + jnp.array([0.0, -0.055, 0.03])  # in front of the plate (-y)
    # Push back (+y) to the goal's x, at the contact height.
    target = _slide(o, contact, 0.03, 0.1, jnp.array([o.goal[0], 0.9, contact[2]]))
    return action(move(o.hand, target, p=10.0), -1.0)


@register("plate-slide-side-v3")
def plate_slide_side(obs: Array) -> Array:
    o = Observation(obs)
    contact = o.obj + jnp.array([0.07, 0.0, -0.005])  # beside the plate (+x)
    # Push in -x (drifting to y = 0.6) until x = -0.2, then keep pushing relative to the plate.
    push_target = jnp.where(
        o.hand[0] > -0.2,
        jnp.array([o.hand[0] - 0.1, 0.6, o.hand[2]]),
        contact + jnp.array([-0.1, 0.0, 0.0]),
    )
    target = _slide(o, contact, 0.04, 0.1, push_target)
    return action(move(o.hand, target, p=25.0), 1.0)


@register("plate-slide-back-v3")
def plate_slide_back(obs: Array) -> Array:
    o = Observation(obs)
    contact = o.obj + jnp.array([0.0, -0.065, 0.025])  # in front of the plate (-y), pulling it back
    push_target = first_true(
        [
            (o.hand[1] > 0.7, o.hand + jnp.array([0.0, -0.1, 0.0])),
            (o.hand[1] > 0.6, jnp.array([0.15, 0.55, o.hand[2]])),
        ],
        jnp.array([o.hand[0] - 0.1, 0.55, o.hand[2]]),
    )
    target = _slide(o, contact, 0.01, 0.1, push_target)
    return action(move(o.hand, target, p=10.0), -1.0)


@register("plate-slide-back-side-v3")
def plate_slide_back_side(obs: Array) -> Array:
    o = Observation(obs)
    contact = o.obj + jnp.array([0.023, 0.0, 0.025])  # beside the plate (+x), pushing it in +x
    push_target = jnp.array([o.hand[0] + 0.1, 0.6, o.hand[2]])
    target = _slide(o, contact, 0.01, 0.07, push_target)
    return action(move(o.hand, target, p=10.0), 1.0)
