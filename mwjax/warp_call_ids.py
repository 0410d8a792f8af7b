"""Gives MJX-Warp's call sites ids and names that do not depend on what the process did before.

Warp's FFI callable numbers its call sites with a per-process counter and writes the number into
the program as the call's `call_id` attribute, which its callback uses to find the site's static
inputs (and, in the graph modes, its captured graphs); it names each callable, the program's FFI
target, after its function and a per-process count of callables made for functions of that name
(MJX-Warp makes one per scene, batch shape and graph mode). Both are part of the compiled
program, and so of the key of JAX's persistent compilation cache: the same step traced after
other programs, in another script, another test order or after one more test, gets other
numbers, and every process compiles it afresh (measured: docs/performance.md).

`install()` names a callable by its function, what the function closes over and the callable's
options (a count is appended only if two different callables come to the same name).

It numbers a call site by what it is: the Warp callable, its static inputs, its
arrays' shapes and dtypes, and how many calls of that same kind the program traced before it.
Calls traced in one program get distinct ids, as with Warp's counter, while the same program
traced again, in this process or another, gets the same ids and the same cache key. An id is
written into the trace, so a trace JAX caches and reuses (it may reuse the trace of an MJX
function, even in another program) brings its ids along, under either scheme. One id may so
stand for several sites, always of one kind, and they share the site's record (Warp's static
inputs, a staged graph, a CPU replay's staging arrays, `warp_graphs`' per-site bound): all of
these describe the same call with the same static inputs, and a device runs the calls one after
the other (on the CPU, Warp's callbacks hold one lock).
`MWJAX_STABLE_CALL_IDS=0` keeps Warp's counters, for ids and names.
"""

from __future__ import annotations

import collections
import contextlib
import hashlib
import inspect
import os
import threading
import weakref
from collections.abc import Iterator
from typing import Any

import jax
from jax._src import core
from warp._src.jax import ffi

_lock = threading.Lock()
# Per outermost trace (one program being traced): calls of each kind traced so far.
_counts: weakref.WeakKeyDictionary[Any, collections.Counter[str]] = weakref.WeakKeyDictionary()
# Names given to Warp callables in this process, and the one the callable being made gets.
_names: set[str] = set()
_making = threading.local()
# Open `issued()` blocks: each one's tag and the (callable, call id) pairs traced inside it.
_collectors: list[tuple[str, list[tuple[ffi.FfiCallable, int]]]] = []


def enabled() -> bool:
    """Whether call ids and names are stable (`MWJAX_STABLE_CALL_IDS`, on unless "0")."""
    return os.environ.get("MWJAX_STABLE_CALL_IDS", "1") != "0"


def install() -> None:
    """Patch Warp's `FfiCallable.__init__` and `__call__` (idempotent: the patch marks itself)."""
    call = ffi.FfiCallable.__call__
    if getattr(call, "mwjax_stable_ids", False):
        return
    init = ffi.FfiCallable.__init__
    signature = inspect.signature(init)
    unique_name = ffi.generate_unique_name

    def with_stable_name(self: ffi.FfiCallable, *args: Any, **kwargs: Any) -> None:
        options = signature.bind(self, *args, **kwargs).arguments
        _making.name = _stable_name(options) if enabled() else None
        try:
            init(self, *args, **kwargs)
        finally:
            _making.name = None

    def named(func: Any) -> str:
        return getattr(_making, "name", None) or unique_name(func)

    ffi.FfiCallable.__init__ = with_stable_name
    ffi.generate_unique_name = named

    def with_stable_id(self: ffi.FfiCallable, *args: Any, **kwargs: Any) -> Any:
        if not enabled():
            before = self.call_id
            result = call(self, *args, **kwargs)
            _collect(self, range(before, self.call_id))
            return result
        with _lock:
            kind = _kind(self, args, kwargs)
            counts = _program_counts()
            site = _site_id(kind, counts[kind])
            counts[kind] += 1
            recorded = self.call_descriptors.get(site)
            self.call_id = site
            try:
                result = call(self, *args, **kwargs)
            finally:
                # Warp registered a fresh record under `site`: an earlier trace's, with its
                # graphs and staging arrays, describes the same call and is kept instead.
                if recorded is not None:
                    self.call_descriptors[site] = recorded
        _collect(self, [site])
        return result

    with_stable_id.mwjax_stable_ids = True  # type: ignore[attr-defined]
    ffi.FfiCallable.__call__ = with_stable_id


@contextlib.contextmanager
def issued(tag: str) -> Iterator[list[tuple[ffi.FfiCallable, int]]]:
    """Collects the (callable, call id) of every Warp call traced inside the block. The calls'
    ids also depend on `tag`, so that what is done to these sites (`warp_graphs.bounded`) does
    not reach the same calls traced elsewhere; with the empty tag the ids are left as they are."""
    install()
    block: tuple[str, list[tuple[ffi.FfiCallable, int]]] = (tag, [])
    with _lock:
        _collectors.append(block)
    try:
        yield block[1]
    finally:
        with _lock:
            _collectors.remove(block)


def _collect(callable_: ffi.FfiCallable, ids: Any) -> None:
    with _lock:
        for _, sites in _collectors:
            sites.extend((callable_, i) for i in ids)


def _stable_name(options: dict[str, Any]) -> str:
    """A callable's FFI target name from its function (with what the function closes over: MJX
    wraps each MJWarp function in a local one) and its options; unique in the process."""
    func = options["func"]
    cells = [_describe(cell.cell_contents) for cell in getattr(func, "__closure__", None) or ()]
    parts = [cells] + [repr(v) for k, v in options.items() if k not in ("self", "func", "graph_cache_max")]
    digest = hashlib.blake2b(repr(parts).encode(), digest_size=6).hexdigest()
    base = f"{ffi.make_full_qualified_name(func)}_{digest}"
    with _lock:
        name, count = base, 0
        while name in _names:
            count += 1
            name = f"{base}_{count}"
        _names.add(name)
    return name


def _describe(value: Any) -> str:
    """What a closure holds, in words that are the same in every process (no addresses)."""
    if hasattr(value, "__qualname__") and hasattr(value, "__module__"):
        return f"{value.__module__}.{value.__qualname__}"
    if isinstance(value, int | float | str | bool | type(None) | inspect.Signature):
        return repr(value)
    return type(value).__qualname__ + (str(value) if isinstance(value, jax.tree_util.PyTreeDef) else "")


def _kind(self: ffi.FfiCallable, args: tuple, kwargs: dict) -> str:
    """What identifies a call of `self` apart from its place in the program."""
    parts: list[Any] = [self.name, sorted(kwargs.items()), [tag for tag, _ in _collectors if tag]]
    for arg, value in zip(self.input_args, args, strict=False):
        if arg.is_array:
            parts.append((tuple(value.shape), str(value.dtype)))
        else:
            parts.append(repr(value))
    return repr(parts)


def trace_chain() -> list[core.Trace]:
    """The traces open around the current call, innermost first (empty outside any trace)."""
    chain = []
    trace = core.trace_ctx.trace
    while trace is not None and not isinstance(trace, core.EvalTrace):
        chain.append(trace)
        trace = getattr(trace, "parent_trace", None)
    return chain


def _program_counts() -> collections.Counter[str]:
    """The call counts of the program being traced: that of the outermost trace (a jit, scan or
    cond body inside it counts with it). Outside any trace a call runs at once, alone, and
    every eager call of a kind gets the same id."""
    chain = trace_chain()
    if not chain:
        return collections.Counter()
    return _counts.setdefault(chain[-1], collections.Counter())


def _site_id(kind: str, index: int) -> int:
    digest = hashlib.blake2b(f"{kind}#{index}".encode(), digest_size=8).digest()
    return int.from_bytes(digest, "little") >> 1  # a non-negative int64
