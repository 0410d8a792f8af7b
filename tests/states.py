"""Bit-for-bit comparison of two env states, leaf by leaf (PRNG keys by their data)."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np


def assert_same_state(expected, actual, context: str = "") -> None:
    """Every leaf of `actual` equals `expected`'s, bit for bit; a failure names the leaf (after
    `context`) and the rows that differ."""
    paths = jax.tree_util.tree_leaves_with_path(expected)
    leaves = jax.tree.leaves(actual)
    assert len(paths) == len(leaves)
    for (path, a), b in zip(paths, leaves, strict=True):
        if jnp.issubdtype(a.dtype, jax.dtypes.prng_key):
            a, b = jax.random.key_data(a), jax.random.key_data(b)
        a, b = np.asarray(a), np.asarray(b)
        where = f"{context}{jax.tree_util.keystr(path)}"
        assert a.shape == b.shape, where
        differ = np.flatnonzero((a != b).reshape(len(a), -1).any(axis=1)) if a.ndim else []
        assert np.array_equal(a, b), f"{where} differs in rows {differ}"
