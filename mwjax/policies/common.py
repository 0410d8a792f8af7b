"""The experts' shared vocabulary: `move`, ordered cases, the action (observation fields are
`mwjax.observation.Observation`'s).

The reference's experts are stateless functions of one observation: a chain of `if`s picks a
target position for the hand and a grip effort. Here each expert is a pure function of one
39-value observation, the `if` chain becomes `first_true`, and the core vmaps it.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import jax
import jax.numpy as jnp

Array = jax.Array
Expert = Callable[[Array], Array]

EXPERTS: dict[str, Expert] = {}


def register(task: str) -> Callable[[Expert], Expert]:
    """Registers `fn` as the expert of `task` (one observation (39,) -> one action (4,))."""

    def add(fn: Expert) -> Expert:
        if task in EXPERTS:
            raise ValueError(f"two experts registered for {task!r}")
        EXPERTS[task] = fn
        return fn

    return add


def move(from_xyz: Array, to_xyz: Array, p: float) -> Array:
    """The reference's proportional step; the env clips it to [-1, 1]."""
    return p * (to_xyz - from_xyz)


def first_true(cases: Sequence[tuple[Array, Array]], default: Array) -> Array:
    """The value of the first case whose condition holds, else `default` (an `if/elif/else`)."""
    out = jnp.asarray(default)
    for condition, value in reversed(cases):
        out = jnp.where(condition, value, out)
    return out


def xy_dist(a: Array, b: Array) -> Array:
    return jnp.linalg.norm(a[:2] - b[:2])


def near(a: Array, b: Array, xy_tol: float, z_tol: float) -> Array:
    """Whether `a` is within `xy_tol` of `b` in the xy plane and within `z_tol` in height: the
    reference's usual grab test, `not (xy_dist > xy_tol or |dz| > z_tol)`."""
    return (xy_dist(a, b) <= xy_tol) & (jnp.abs(a[2] - b[2]) <= z_tol)


def action(delta_pos: Array, grab_effort: Array | float) -> Array:
    return jnp.concatenate([delta_pos, jnp.reshape(jnp.asarray(grab_effort, delta_pos.dtype), (1,))]).astype(
        jnp.float32
    )
