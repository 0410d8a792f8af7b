"""Experts for the articulated family (see mwjax/tasks/articulated.py)."""

from __future__ import annotations

import jax
import jax.numpy as jnp

from mwjax.observation import Observation
from mwjax.policies.common import action, first_true, move, register, xy_dist

Array = jax.Array


@register("door-open-v3")
def door_open(obs: Array) -> Array:
    o = Observation(obs)
    # The reference shifts the handle in place (`pos_door[0] -= 0.05`); nothing later reads it.
    handle = o.obj - jnp.array([0.05, 0.0, 0.0])
    front_edge = handle + jnp.array([0.06, 0.02, 0.0])
    target = first_true(
        [
            (xy_dist(o.hand, handle) > 0.12, front_edge + jnp.array([0.0, 0.0, 0.2])),
            (jnp.abs(o.hand[2] - handle[2]) > 0.04, front_edge),  # drop down in front of the handle
        ],
        handle,  # then pull the handle's front edge towards its centre
    )
    return action(move(o.hand, target, p=25.0), 1.0)


@register("door-close-v3")
def door_close(obs: Array) -> Array:
    o = Observation(obs)
    handle = o.obj + jnp.array([0.05, 0.12, 0.1])
    beside = o.hand[0] > handle[0]  # still on the hinge side of the handle
    target = first_true(
        [
            (beside & (o.hand[2] < handle[2] + 0.2), jnp.stack([o.hand[0], o.hand[1], handle[2] + 0.25])),
            (beside, jnp.stack([handle[0] - 0.02, handle[1], o.hand[2]])),  # across, high above the door
            (jnp.abs(o.hand[2] - handle[2]) > 0.04, handle + jnp.array([-0.02, 0.0, 0.0])),
        ],
        o.goal,  # then push the door shut
    )
    return action(move(o.hand, target, p=25.0), 1.0)


@register("drawer-open-v3")
def drawer_open(obs: Array) -> Array:
    o = Observation(obs)
    handle = o.obj + jnp.array([0.0, 0.0, -0.02])
    # The gain changes part-way: the final pull behind the handle uses a stiffer one.
    delta = first_true(
        [
            (xy_dist(o.hand, handle) > 0.06, move(o.hand, handle + jnp.array([0.0, 0.0, 0.3]), p=4.0)),
            (jnp.abs(o.hand[2] - handle[2]) > 0.04, move(o.hand, handle, p=4.0)),
        ],
        move(o.hand, handle + jnp.array([0.0, -0.06, 0.0]), p=50.0),
    )
    return action(delta, -1.0)


@register("drawer-close-v3")
def drawer_close(obs: Array) -> Array:
    o = Observation(obs)
    handle = o.obj + jnp.array([0.0, 0.0, -0.02])
    front = handle + jnp.array([0.0, -0.075, 0.0])
    behind = o.hand[1] > handle[1]  # beyond the handle: climb over it back to its front
    target = first_true(
        [
            (behind & (o.hand[2] < handle[2] + 0.23), jnp.stack([o.hand[0], o.hand[1], handle[2] + 0.5])),
            (behind, front + jnp.array([0.0, 0.0, 0.23])),
            (jnp.abs(o.hand[2] - handle[2]) > 0.04, front),
        ],
        handle,  # then push the drawer in
    )
    return action(move(o.hand, target, p=25.0), 1.0)


def _lock_approach(hand: Array, approach: Array, clearance_z: float, rise: bool) -> Array:
    """While out of line with the lock: back off in -y and 0.1 towards `clearance_z` (up if
    `rise`) until past that height, then head for `approach`."""
    if rise:
        off_height, dz = hand[2] < clearance_z, 0.1
    else:
        off_height, dz = hand[2] > clearance_z, -0.1
    return jnp.where(off_height, hand + jnp.array([0.0, -0.1, dz]), approach)


@register("door-lock-v3")
def door_lock(obs: Array) -> Array:
    o = Observation(obs)
    lock = o.obj + jnp.array([-0.02, -0.02, 0.0])
    target = first_true(
        [
            (
                xy_dist(o.hand, lock) > 0.02,
                _lock_approach(o.hand, lock + jnp.array([0.0, 0.0, 0.3]), 0.25, True),
            ),
            (jnp.abs(o.hand[2] - lock[2]) > 0.02, lock),
        ],
        lock + jnp.array([-0.1, 0.0, -0.1]),  # turn the lock down
    )
    return action(move(o.hand, target, p=25.0), -1.0)


@register("door-unlock-v3")
def door_unlock(obs: Array) -> Array:
    o = Observation(obs)
    lock = o.obj + jnp.array([-0.04, -0.02, -0.03])
    target = jnp.where(
        xy_dist(o.hand, lock) > 0.02,
        _lock_approach(o.hand, lock, 0.15, False),
        lock + jnp.array([0.1, 0.0, 0.01]),  # turn the lock up
    )
    return action(move(o.hand, target, p=25.0), 1.0)


def _press_from_above(obs: Array, offset: tuple[float, float, float], grab: float) -> Array:
    """Hover 0.1 above the button (shifted by `offset`) until within 0.04 in xy, then press down."""
    o = Observation(obs)
    button = o.obj + jnp.array(offset)
    target = jnp.where(xy_dist(o.hand, button) > 0.04, button + jnp.array([0.0, 0.0, 0.1]), button)
    return action(move(o.hand, target, p=25.0), grab)


@register("button-press-topdown-v3")
def button_press_topdown(obs: Array) -> Array:
    return _press_from_above(obs, (0.0, 0.0, 0.0), 1.0)


@register("button-press-topdown-wall-v3")
def button_press_topdown_wall(obs: Array) -> Array:
    return _press_from_above(obs, (0.0, -0.06, 0.0), -1.0)


@register("button-press-v3")
def button_press(obs: Array) -> Array:
    o = Observation(obs)
    button = o.obj + jnp.array([0.0, 0.0, -0.07])
    xz = jnp.array([0, 2])
    # np.isclose(hand, button, atol=0.02) on x and z, with its default rtol=1e-5 relative to the button.
    aligned = jnp.all(jnp.abs(o.hand[xz] - button[xz]) <= 0.02 + 1e-5 * jnp.abs(button[xz]))
    # Line up in x and z while backing off in y, then push the button in.
    target_y = jnp.where(aligned, button[1] + 0.02, o.hand[1] - 0.1)
    target = button.at[1].set(target_y)
    return action(move(o.hand, target, p=25.0), 0.0)


@register("button-press-wall-v3")
def button_press_wall(obs: Array) -> Array:
    o = Observation(obs)
    button = o.obj + jnp.array([0.0, 0.0, 0.04])
    off_x = jnp.abs(o.hand[0] - button[0]) > 0.02
    far_y = button[1] - o.hand[1] > 0.09
    off_z = jnp.abs(o.hand[2] - button[2]) > 0.02
    target = first_true(
        [
            (off_x, jnp.stack([button[0], o.hand[1], 0.3])),  # line up in x, high above the wall
            (far_y, jnp.stack([button[0], button[1], 0.3])),
            (off_z, button + jnp.array([0.0, -0.05, 0.0])),
        ],
        button + jnp.array([0.0, -0.02, 0.0]),
    )
    # The gripper stays closed on the way and opens only for the final press.
    grab = jnp.where(off_x | far_y | off_z, 1.0, -1.0)
    return action(move(o.hand, target, p=15.0), grab)


def _slide_window(obs: Array, side: float, hover: float) -> Array:
    """Hover over the handle on its `-side` x edge, drop to it, then slide it 0.1 towards `side`."""
    o = Observation(obs)
    handle = o.obj + jnp.array([-0.03 * side, -0.03, -0.08])
    target = first_true(
        [
            (xy_dist(o.hand, handle) > 0.04, handle + jnp.array([0.0, 0.0, hover])),
            (jnp.abs(o.hand[2] - handle[2]) > 0.02, handle),
        ],
        handle + jnp.array([0.1 * side, 0.0, 0.0]),
    )
    return action(move(o.hand, target, p=25.0), 1.0)


@register("window-open-v3")
def window_open(obs: Array) -> Array:
    return _slide_window(obs, side=1.0, hover=0.3)


@register("window-close-v3")
def window_close(obs: Array) -> Array:
    return _slide_window(obs, side=-1.0, hover=0.25)
