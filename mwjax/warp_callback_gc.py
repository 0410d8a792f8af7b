"""Holds Python's cyclic garbage collector off while a Warp FFI callback runs.

A Warp call from XLA runs in a Python callback that, on a GPU, captures the call's kernels into
a CUDA graph. While a stream captures, CUDA forbids freeing device resources such as textures,
and Python's cyclic collector runs whenever the callback's own allocations cross its threshold,
deleting whatever unreachable objects exist at that moment. An MJX render context that was
dropped earlier (a closed env's renderer, say) is such an object: collected inside a capture,
its textures' destruction fails ("operation not permitted when stream is capturing") and breaks
the capture. With the collector held for the callback's duration, such objects go at the next
collection outside any callback instead; the callbacks allocate little, so the hold costs
nothing measurable. Held process-wide (`gc.disable`), since a capture forbids these calls from
any thread; an explicit `gc.collect()` on another thread still collects.

`install()` wraps Warp's FFI callback; `held()` wraps mwjax's own (`mwjax.scene_streams`).
"""

from __future__ import annotations

import contextlib
import functools
import gc
import threading
from collections.abc import Iterator
from typing import Any

from warp._src.jax import ffi

_lock = threading.Lock()
_depth = 0  # callbacks running now, across threads
_was_enabled = False  # the collector's state before the outermost of them


@contextlib.contextmanager
def held() -> Iterator[None]:
    """No automatic cyclic collection until the last of the overlapping `held()` blocks ends;
    then the collector is as it was before the first began."""
    global _depth, _was_enabled
    with _lock:
        if _depth == 0:
            _was_enabled = gc.isenabled()
            gc.disable()
        _depth += 1
    try:
        yield
    finally:
        with _lock:
            _depth -= 1
            if _depth == 0 and _was_enabled:
                gc.enable()


@functools.cache  # once per process
def install() -> None:
    """Wrap Warp's FFI callback (idempotent)."""
    original = ffi.FfiCallable.ffi_callback

    def ffi_callback(self: ffi.FfiCallable, call_frame: Any, platform: str) -> Any:
        with held():
            return original(self, call_frame, platform)

    ffi.FfiCallable.ffi_callback = ffi_callback
