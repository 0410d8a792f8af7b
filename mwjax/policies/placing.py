"""Experts for the placing family (see mwjax/tasks/placing.py)."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from mwjax.observation import Observation
from mwjax.policies.common import action, first_true, move, near, register, xy_dist

Array = jax.Array

BIN = np.array([0.12, 0.7, 0.02], np.float32)  # where bin-picking drops the cube (the target bin's centre)


@register("pick-out-of-hole-v3")
def pick_out_of_hole(obs: Array) -> Array:
    o = Observation(obs)
    puck = o.obj + jnp.array([0.0, 0.0, 0.02])
    target = first_true(
        [
            (xy_dist(o.hand, puck) > 0.02, puck + jnp.array([0.0, 0.0, 0.15])),
            (jnp.abs(o.hand[2] - puck[2]) > 0.01, puck),
            (jnp.abs(o.hand[2] - o.goal[2]) > 0.04, o.hand.at[2].set(o.goal[2])),  # lift out first
        ],
        o.goal,
    )
    grab = jnp.where(near(o.hand, puck, 0.02, 0.15), 0.1, 0.0)
    return action(move(o.hand, target, p=25.0), grab)


@register("shelf-place-v3")
def shelf_place(obs: Array) -> Array:
    o = Observation(obs)
    block = o.obj + jnp.array([-0.005, 0.0, 0.015])
    shelf_x = o.goal[0]
    target = first_true(
        [
            (xy_dist(o.hand, block) > 0.04, block + jnp.array([0.0, 0.0, 0.3])),
            (jnp.abs(o.hand[2] - block[2]) > 0.04, block),
            # Line up with the shelf in x, rise to its height, then (default) move onto it.
            (jnp.abs(o.hand[0] - shelf_x) > 0.02, jnp.array([shelf_x, o.hand[1], 0.3])),
            (o.hand[2] < 0.30, o.hand + jnp.array([0.0, 0.0, 0.30])),
        ],
        o.hand + jnp.array([0.0, 0.05, 0.0]),
    )
    # The grip test uses the unshifted block.
    grab = jnp.where(near(o.hand, o.obj, 0.04, 0.15), 0.7, -1.0)
    return action(move(o.hand, target, p=25.0), grab)


@register("bin-picking-v3")
def bin_picking(obs: Array) -> Array:
    o = Observation(obs)
    # Aim as if the cube sat mid-bin in y: closing fingers then drag it off the edge, and they
    # cannot catch on the bin's wall.
    cube = o.obj + jnp.array([0.0, 0.0, 0.03])
    cube = cube.at[1].set(jnp.clip(cube[1], 0.675, 0.725))
    target = first_true(
        [
            (xy_dist(o.hand, cube) > 0.02, cube + jnp.array([0.0, 0.0, 0.15])),
            (jnp.abs(o.hand[2] - cube[2]) > 0.01, cube),
            ((xy_dist(o.hand, BIN) > 0.02) & (o.hand[2] < 0.15), o.hand + jnp.array([0.0, 0.0, 0.1])),  # lift
            (xy_dist(o.hand, BIN) > 0.02, jnp.asarray(BIN).at[2].set(0.18)),  # carry over the bin
        ],
        BIN,
    )
    grab = jnp.where(near(o.hand, cube, 0.02, 0.02), 0.6, -1.0)
    return action(move(o.hand, target, p=25.0), grab)
