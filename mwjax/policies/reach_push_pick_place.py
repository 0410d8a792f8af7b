"""Experts for reach, push, pick-place and their wall/back variants, sweep, sweep-into, hand-insert."""

from __future__ import annotations

import jax
import jax.numpy as jnp

from mwjax.policies.common import action, first_true, move, parse, register, xy_dist

Array = jax.Array


@register("reach-v3")
def reach(obs: Array) -> Array:
    o = parse(obs)
    return action(move(o.hand, o.goal, p=5.0), 0.0)


@register("pick-place-v3")
def pick_place(obs: Array) -> Array:
    o = parse(obs)
    puck = o.obj + jnp.array([-0.005, 0.0, 0.0])
    target = first_true(
        [
            (xy_dist(o.hand, puck) > 0.02, puck + jnp.array([0.0, 0.0, 0.1])),
            ((jnp.abs(o.hand[2] - puck[2]) > 0.05) & (puck[2] < 0.04), puck + jnp.array([0.0, 0.0, 0.03])),
            (o.gripper > 0.73, o.hand),  # wait for the gripper to close
        ],
        o.goal,
    )
    grab = jnp.where(jnp.linalg.norm(o.hand - o.obj) < 0.07, 1.0, 0.0)
    return action(move(o.hand, target, p=10.0), grab)
