"""Row-batched functions under an outer `jax.vmap` (over seeds, say).

`cond_any`: `lax.cond` on "any row", kept a branch under an outer `jax.vmap` too.

The step skips its reset work with `lax.cond(jnp.any(done), ...)`. Under a `jax.vmap` of the
whole step (over seeds, say) the predicate is batched, and JAX turns such a cond into a select
that runs both branches with every operand batched, constants included. MJX-Warp's calls are
`custom_vmap` functions that reject batched constants, so that select fails while tracing (and
it would run the reset work at every step). `cond_any` gives the outer vmap one predicate for
all its instances instead ("any row of any instance"), and vmaps the chosen branch over them.

`merge_rows`: a function of a batch of rows that an outer `jax.vmap` calls once on all its
instances' rows merged into one batch. MJX-Warp sizes its contact and convex-collider buffers
for the whole batch it is given (`naconmax`, `naccdmax`), and flattens an outer vmap's instances
into its worlds without growing them: under a vmap over S seeds, every seed's envs would share one
seed's buffers and drop contacts once they hold 1/S of them. Merged, the buffers are made for
every row of every instance.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TypeVar

import jax
import jax.numpy as jnp

T = TypeVar("T")
U = TypeVar("U")
Branch = Callable[[T, jax.Array], T]


def cond_any(rows: jax.Array, if_any: Branch, otherwise: Branch, operand: T) -> T:
    """`if_any(operand, rows)` if any of the boolean `rows` is set, else `otherwise(operand, rows)`;
    under an outer `jax.vmap`, one branch for all instances: those whose rows are all unset get
    `if_any` too when another instance's are not, so `if_any` must leave unset rows as
    `otherwise` does."""

    @jax.custom_batching.custom_vmap
    def branch(operand: T, rows: jax.Array) -> T:
        return jax.lax.cond(jnp.any(rows), if_any, otherwise, operand, rows)

    @branch.def_vmap
    def _(axis_size: int, in_batched: list, operand: T, rows: jax.Array) -> tuple[T, object]:
        def batched(x: jax.Array, is_batched: bool) -> jax.Array:
            return x if is_batched else jnp.broadcast_to(x, (axis_size, *x.shape))

        operand, rows = jax.tree.map(batched, (operand, rows), tuple(in_batched))
        out = jax.lax.cond(jnp.any(rows), jax.vmap(if_any), jax.vmap(otherwise), operand, rows)
        return out, jax.tree.map(lambda _: True, out)

    return branch(operand, rows)


def merge_rows(fn: Callable[[T], U]) -> Callable[[T], U]:
    """`fn`, which maps a pytree whose leaves all lead with one rows axis to another such pytree,
    called under an outer `jax.vmap` once on the instances' rows merged (instance by instance)
    into one rows axis, and split again afterwards; nested vmaps merge level by level."""

    @jax.custom_batching.custom_vmap
    def merged(rows: T) -> U:
        return fn(rows)

    @merged.def_vmap
    def _(axis_size: int, in_batched: list, rows: T) -> tuple[U, object]:
        def batched(x: jax.Array, is_batched: bool) -> jax.Array:
            return x if is_batched else jnp.broadcast_to(x, (axis_size, *x.shape))

        rows = jax.tree.map(batched, rows, in_batched[0])
        # Sizes spelled out, not -1: a leaf may have no elements (e.g. no bodies to capture).
        out = merged(jax.tree.map(lambda x: x.reshape(x.shape[0] * x.shape[1], *x.shape[2:]), rows))
        out = jax.tree.map(lambda x: x.reshape(axis_size, x.shape[0] // axis_size, *x.shape[1:]), out)
        return out, jax.tree.map(lambda _: True, out)

    return merged
