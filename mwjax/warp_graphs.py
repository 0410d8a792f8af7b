"""Optionally bounds the CUDA graphs Warp keeps per MJX-Warp call site (Warp 1.18: 32 per callable).

In MJX's default graph mode ("warp"), Warp's FFI callback captures each call into a CUDA graph,
keyed by the call site (`call_id`) and the addresses of all its buffers, replays it when the same
site comes with the same addresses, and keeps up to 32 graphs per Warp callable (least recently
used first out). Each graph keeps the scratch memory its call allocated while it was captured:
the convex collider's GJK/EPA buffers are hundreds of MB per scene at 100k+ envs. When XLA hands
a site other buffers (another execution of the program, a donated state that moved, a program
compiled anew), Warp captures again and keeps the old graph as well, so a large batch's memory
can grow by a whole set of graphs at a time, up to 32 per callable.

`install()` can bound it per site: with `MWJAX_WARP_GRAPHS_PER_SITE=K` (K >= 1) a site keeps
the graphs of its last K sets of buffer addresses, an older set's graph, with its scratch, is
released before the new one is captured, and Warp's per-callable limit is lifted (it would evict
graphs of sites in use when a callable has more than 32 sites). `bounded(K)` bounds only the sites
traced inside it (Warp's per-callable limit stays; a site is a call id, which programs with the
same calls share, `mwjax.warp_call_ids`): the Gymnasium adapter traces its jitted calls
so, with K=1, because a program called from Python step by step gets new temporary buffers at
every call and so never replays a graph (measured: `docs/performance.md`, the adapter), while
keeping up to 32 ran out of memory at 131k envs. The process-wide bound is off by default (0:
Warp's own policy), because one site may legitimately see several sets in one execution: measured on an
H200 (MT10, 32,760 envs, 500-step rollouts, substeps as a device loop), Warp's policy kept 32
graphs for 12 sites, the same after every rollout, and K=1 made most calls capture anew, 306,646
instead of 494,003 env steps/s
(`benchmarks/results/profile/warp-memory-probe-MT10-32760-500steps-per-site-*-0bcc205-*`). The
CPU is not concerned: Warp captures nothing there (`mwjax.warp_cpu_graphs` records its own).
"""

from __future__ import annotations

import collections
import contextlib
import ctypes
import functools
import os
import threading
from collections.abc import Callable, Iterator
from typing import Any, TypeVar

from warp._src.jax import ffi

from mwjax import warp_call_ids

T = TypeVar("T")
_lock = threading.Lock()
_installed = False
# Per-site bounds set by `bounded`: (id of the Warp callable, call id) -> graphs kept.
_site_limits: dict[tuple[int, int], int] = {}


def per_site() -> int:
    """Graphs each call site keeps (`MWJAX_WARP_GRAPHS_PER_SITE`; 0: Warp's own policy)."""
    value = os.environ.get("MWJAX_WARP_GRAPHS_PER_SITE", "0")
    if not value.isdigit():
        raise ValueError(f"MWJAX_WARP_GRAPHS_PER_SITE must be a non-negative integer, not {value!r}")
    return int(value)


def admit(kept: collections.deque[int], key: int, limit: int) -> list[int]:
    """Record that a site's call uses the buffer set `key`, most recent last in `kept`, and
    return the keys it no longer keeps (their graphs are to be released): at most `limit`."""
    if key in kept:
        kept.remove(key)
        kept.append(key)
        return []
    kept.append(key)
    return [kept.popleft() for _ in range(len(kept) - limit)]


@contextlib.contextmanager
def bounded(limit: int) -> Iterator[None]:
    """Warp call sites traced inside the block keep at most `limit` graphs each (on top of Warp's
    per-callable limit). Wrap the call of a jitted function, whose first call traces it."""
    if limit < 1:
        raise ValueError(f"limit must be at least 1, got {limit}")
    install(force=True)
    with warp_call_ids.issued(f"bounded to {limit}") as sites:
        try:
            yield
        finally:
            with _lock:
                for c, call_id in sites:
                    _site_limits[id(c), call_id] = limit


def stepped_from_python(function: Callable[..., T]) -> Callable[..., T]:
    """`function` (jitted) with the Warp call sites it traces bounded to one graph each: for a
    program called step by step from Python, whose calls never replay a graph (module doc)."""

    @functools.wraps(function)
    def call(*args: Any, **kwargs: Any) -> T:
        with bounded(1):
            return function(*args, **kwargs)

    return call


def bounded_sites() -> set[tuple[int, int]]:
    """The call sites `bounded` has bounded in this process: (id of the Warp callable, call id)."""
    return set(_site_limits)


def install(force: bool = False) -> None:
    """Patch Warp's FFI callback once per process (idempotent; a no-op with a limit of 0 unless
    `force`, which `bounded` uses)."""
    global _installed
    with _lock:
        if _installed or (per_site() == 0 and not force):
            return
        _installed = True
    original = ffi.FfiCallable.ffi_callback
    everywhere = per_site()

    def ffi_callback(self: ffi.FfiCallable, call_frame: Any, platform: str) -> Any:
        frame = call_frame.contents
        if (
            platform != ffi._FFI_PLATFORM_CUDA
            or self.graph_mode != ffi.JaxCallableGraphMode.WARP
            or frame.extension_start
        ):
            return original(self, call_frame, platform)
        # The key Warp's callback computes for this call (same fields, same order).
        attr = ctypes.cast(frame.attrs.attrs[0], ctypes.POINTER(ffi.XLA_FFI_Scalar)).contents
        call_id = ctypes.cast(attr.value, ctypes.POINTER(ctypes.c_int64)).contents.value
        limit = _site_limits.get((id(self), call_id), everywhere)
        if limit == 0:
            return original(self, call_frame, platform)
        inputs = ctypes.cast(frame.args.args, ctypes.POINTER(ctypes.POINTER(ffi.XLA_FFI_Buffer)))
        outputs = ctypes.cast(frame.rets.rets, ctypes.POINTER(ctypes.POINTER(ffi.XLA_FFI_Buffer)))
        key = hash(
            (
                ffi.get_device_ordinal_from_callframe(frame),
                call_id,
                *(inputs[i].contents.data for i in self.array_input_indices),
                *(outputs[i].contents.data for i in self.array_output_indices),
            )
        )
        with ffi._FFI_CALLBACK_LOCK:
            desc = self.call_descriptors[call_id]
            kept = desc.__dict__.get("mwjax_graph_keys")
            if kept is None:  # the site's first call; a process-wide bound replaces Warp's
                kept = desc.mwjax_graph_keys = collections.deque()
                if everywhere:
                    self.graph_cache_max = None
            for old in admit(kept, key, limit):
                self.captures.pop(old, None)
        return original(self, call_frame, platform)

    ffi.FfiCallable.ffi_callback = ffi_callback


def kept_graphs() -> tuple[int, int]:
    """(CUDA graphs Warp's callables keep, callables that keep any): what `install()` bounds."""
    kept = [len(c.captures) for c in ffi._FFI_CALLABLE_REGISTRY.values() if c.captures]
    return sum(kept), len(kept)
