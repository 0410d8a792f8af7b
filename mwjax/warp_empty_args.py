"""Makes MJX-Warp's empty model arrays in the trace, so that no `shard_map` gets a zero-size input.

JAX 0.11's Shardy partitioner crashes (a segfault in its export pass, while compiling) on a
zero-size input of a `shard_map` that the map's body uses. A sharded env's step had 172 such
inputs: JAX 0.11 turns every constant a `shard_map` body closes over into an input of the map,
and MJX-Warp passes the model's arrays to each Warp call as constants, the empty ones (index
arrays of features Meta-World's scenes lack: tendons, flexes, sensors, ...) included. Made in the
trace (`jnp.zeros`), an empty array is an operation of the body rather than a constant, and the
map gets no zero-size input. JAX 0.10 compiles either form.

Each trace makes one empty array per shape and dtype and hands it to every call that needs one:
made per use, an MT10 step's trace held 3,116 of them, a fifth of its operations, each one traced
and lowered.

`install()` does it for the model's static NumPy fields, which MJX-Warp hands to Warp's FFI
callable as they are (patching `FfiCallable.__call__`); `traced(model)` does it for the model's
array leaves, which Warp gets through MJX's own marshalling; the env's state carries no empty
arrays (`mwjax.physics.PhysicsState`).
"""

from __future__ import annotations

import threading
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
from jax._src import core
from warp._src.jax import ffi

from mwjax import warp_call_ids

# Per thread, for each open trace (by id), the trace and the empty arrays made in it by shape and
# dtype. Entries of traces no longer open are dropped at the next use: the arrays refer to their
# trace, so a weak mapping would keep every trace alive.
_local = threading.local()


def install() -> None:
    """Patch Warp's `FfiCallable.__call__` (idempotent: the patch marks itself)."""
    call = ffi.FfiCallable.__call__
    if getattr(call, "mwjax_empties_traced", False):
        return

    def with_empties_traced(self: ffi.FfiCallable, *args: Any, **kwargs: Any) -> Any:
        return call(self, *(_traced(x) for x in args), **kwargs)

    with_empties_traced.mwjax_empties_traced = True  # type: ignore[attr-defined]
    ffi.FfiCallable.__call__ = with_empties_traced


def traced(model: Any) -> Any:
    """`model` (any pytree) with its zero-size array leaves made in the trace."""
    return jax.tree.map(_traced, model)


def _traced(x: Any) -> Any:
    if not (isinstance(x, np.ndarray | jax.Array) and not isinstance(x, jax.core.Tracer) and x.size == 0):
        return x
    chain = warp_call_ids.trace_chain()
    if not chain:  # not tracing: nothing to share
        return jnp.zeros(x.shape, x.dtype)
    made = _made_in(chain)
    key = (x.shape, np.dtype(x.dtype))
    if key not in made:
        made[key] = jnp.zeros(x.shape, x.dtype)
    return made[key]


def _made_in(chain: list[core.Trace]) -> dict[tuple[tuple[int, ...], np.dtype], jax.Array]:
    """The empty arrays made so far in the innermost of the open traces `chain`, after dropping
    the entries of traces no longer open."""
    open_ids = {id(trace) for trace in chain}
    made = {k: v for k, v in getattr(_local, "made", {}).items() if k in open_ids}
    _local.made = made
    return made.setdefault(id(chain[0]), (chain[0], {}))[1]
