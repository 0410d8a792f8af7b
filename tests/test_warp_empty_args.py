"""`mwjax.warp_empty_args`: MJX-Warp's empty model arrays made in the trace, one per shape and
dtype in each trace."""

from __future__ import annotations

import gc
import weakref

import jax
import jax.numpy as jnp
import numpy as np
from jax._src import core

from mwjax import warp_empty_args


def _empty_outputs(jaxpr) -> list:
    return [v.aval for e in jaxpr.eqns for v in e.outvars if v.aval.size == 0]


def test_a_trace_makes_each_empty_shape_once_and_passes_the_rest_through():
    full = np.ones(3, np.float32)

    def uses(x):
        made = [
            warp_empty_args._traced(a)
            for a in (np.zeros((0, 3), np.float32), np.zeros((0, 3), np.float32), np.zeros(0, np.int32), full)
        ]
        assert made[3] is full
        assert all(isinstance(m, jax.core.Tracer) for m in made[:3])
        return x + made[3], made[:3]

    jaxpr = jax.make_jaxpr(uses)(jnp.zeros(3))
    assert sorted((a.shape, str(a.dtype)) for a in _empty_outputs(jaxpr.jaxpr)) == [
        ((0,), "int32"),
        ((0, 3), "float32"),
    ]
    assert [a.shape for a in jaxpr.out_avals] == [(3,), (0, 3), (0, 3), (0,)]


def test_another_trace_makes_its_own():
    """An array made in one trace is not reused by the next (it would leak a dead tracer)."""

    def uses(x):
        return x, warp_empty_args._traced(np.zeros((0, 2), np.float32))

    for _ in range(2):
        assert len(_empty_outputs(jax.make_jaxpr(uses)(jnp.zeros(1)).jaxpr)) == 1
    assert jax.jit(uses)(jnp.zeros(1))[1].shape == (0, 2)


def test_outside_a_trace_it_is_an_array():
    made = warp_empty_args._traced(np.zeros((0, 4), np.int32))
    assert isinstance(made, jax.Array) and made.shape == (0, 4) and made.dtype == jnp.int32


def test_a_finished_trace_is_let_go():
    """The arrays refer to their trace: kept past the trace's end they would keep it (and its
    whole program) alive."""
    traces = []

    def uses(x):
        traces.append(weakref.ref(core.trace_ctx.trace))
        return x + warp_empty_args._traced(np.zeros((0, 2), np.float32)).sum()

    for _ in range(3):
        jax.jit(lambda x: uses(x)).lower(1.0)
    gc.collect()
    assert [ref() is None for ref in traces] == [True, True, False]  # the last, until the next
