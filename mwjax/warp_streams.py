"""Reference-counts Warp's registration of external CUDA streams (a workaround for Warp 1.18).

Each time an MJX-Warp call captures a CUDA graph, Warp's JAX FFI callback wraps XLA's stream in a
new `warp.Stream(cuda_stream=...)`, which registers the stream in Warp's native table, and the
wrapper's `__del__` unregisters it. The table is not reference counted: deleting any wrapper of
a stream removes the entry that every other live wrapper of it relies on. Warp's codegen catches
its own exceptions while it builds a kernel, and their tracebacks keep the callback's frame, and
with it that call's wrapper, in a reference cycle. Python's cyclic collector then deletes the
wrapper at an arbitrary later moment; when that moment falls inside a later callback, between
its registration and its `capture_begin`, the capture fails with "Warp error: unknown stream".
Unpatched, the MT50 step with per-scene constraint rows failed so at its first call every time
it ran (docs/performance.md).

`install()` counts the live wrappers of each external stream and unregisters a stream only
when its last wrapper goes. Streams that Warp creates and owns are left as they are.
"""

from __future__ import annotations

import collections
import threading
from typing import Any

import warp

_live: collections.Counter[int] = collections.Counter()
_lock = threading.Lock()
_installed = False


def install() -> None:
    """Patch `warp.Stream` once per process (idempotent)."""
    global _installed
    with _lock:
        if _installed:
            return
        _installed = True
    stream_init = warp.Stream.__init__
    stream_del = warp.Stream.__del__
    # Bound here rather than read as module globals, which may be gone when the interpreter
    # deletes the last wrappers at exit.
    live, lock = _live, _lock

    def counted_init(self: warp.Stream, *args: Any, **kwargs: Any) -> None:
        stream_init(self, *args, **kwargs)
        if "cuda_stream" in kwargs and self.cuda_stream:
            with lock:
                live[int(self.cuda_stream)] += 1

    def counted_del(self: warp.Stream) -> None:
        if self.cuda_stream and not self.owner:
            handle = int(self.cuda_stream)
            with lock:
                if live[handle] > 1:
                    # Another wrapper of this stream is alive: keep its registration.
                    live[handle] -= 1
                    return
                live.pop(handle, None)
        stream_del(self)

    warp.Stream.__init__ = counted_init
    warp.Stream.__del__ = counted_del


def live_wrappers(cuda_stream: int) -> int:
    """How many live `warp.Stream` objects wrap the external stream `cuda_stream`."""
    with _lock:
        return _live[cuda_stream]
