"""Replays MJX-Warp's CPU calls as recorded Warp graphs (Warp 1.18 runs them eagerly).

On the CPU, Warp's JAX FFI callback rebuilds a `warp.array` for every buffer and calls MJWarp's
Python step, which launches its few hundred kernels one by one from Python; the launches, not the
kernels, take most of a small batch's step (a pick-place substep of 4 envs: ~23 ms eager, ~12 ms
replayed). Warp records CPU graphs (`warp.ScopedCapture` on the CPU device) and replays them
natively, but its FFI callback refuses every graph mode on the CPU, and a graph is bound to the
buffers it was recorded with, while XLA hands each call fresh ones.

`install()` gives the CPU callback Warp's CUDA `WARP_STAGED_EX` scheme: each call site (one
`call_id`: fixed shapes) gets its own staging arrays; every call copies XLA's inputs into them,
replays the graph recorded on them, and copies the outputs back. The first call of a site runs
eagerly as before (it loads the site's kernel modules); the second records the graph. The replay
launches the same kernels with the same arguments in the same order, so a rollout is bit for bit
the eager one (tests/test_warp_cpu_graphs.py). `MWJAX_CPU_GRAPHS=0` turns it off.

Warp records a CPU graph through process-wide state: while one is being recorded, every Warp
operation of the process, whatever its thread, is seen by (and may be recorded into) it. XLA runs
the calls on its own threads, asynchronously to Python, and the Python thread does Warp work of
its own when it builds a model, a render context or data (`mjx.put_model`, `mjx.make_data`, which
runs while a step is traced): a recording racing with that failed in Warp's copy, on two host
devices. So `install()` also makes those entry points take the lock Warp's FFI callbacks hold,
which every replay and recording holds too.
"""

from __future__ import annotations

import contextlib
import ctypes
import functools
import os
import threading
import warnings
from collections.abc import Iterator
from typing import Any

import mujoco.mjx.warp.io as mjx_warp_io
import warp
from mujoco.mjx.warp import mujoco_warp
from warp._src.jax import ffi

_lock = threading.Lock()
_installed = False
# Calls of a site before it is recorded: the first loads its modules eagerly.
_EAGER_CALLS = 1


_replaying = os.environ.get("MWJAX_CPU_GRAPHS", "1") != "0"


def enabled() -> bool:
    """Whether CPU calls replay recorded graphs now."""
    return _installed and _replaying


@contextlib.contextmanager
def eager() -> Iterator[None]:
    """Within it, CPU calls run eagerly, as Warp runs them (what the replay is checked against)."""
    global _replaying
    before, _replaying = _replaying, False
    try:
        yield
    finally:
        _replaying = before


class _Site:
    """One call site's staging arrays, copies and recorded graph."""

    def __init__(self) -> None:
        self.calls = 0
        self.graph: Any = None
        # Recording failed (a call Warp cannot record): the site runs eagerly from then on.
        self.failed = False
        self.keep: list[Any] = []
        # (index of the FFI buffer, staging pointer, bytes)
        self.copy_in: list[tuple[int, int, int]] = []
        self.copy_out: list[tuple[int, int, int]] = []


def install() -> None:
    """Patch Warp's FFI callback once per process (idempotent)."""
    global _installed
    with _lock:
        if _installed:
            return
        _installed = True
    for name in ("put_model", "make_data", "put_data"):
        setattr(mujoco_warp, name, _holding_the_ffi_lock(getattr(mujoco_warp, name)))
    mjx_warp_io._create_context = _holding_the_ffi_lock(mjx_warp_io._create_context)
    original = ffi.FfiCallable.ffi_callback

    def ffi_callback(self: ffi.FfiCallable, call_frame: Any, platform: str) -> Any:
        if not _replaying or platform != ffi._FFI_PLATFORM_CPU or call_frame.contents.extension_start:
            return original(self, call_frame, platform)
        frame = call_frame.contents
        attr = ctypes.cast(frame.attrs.attrs[0], ctypes.POINTER(ffi.XLA_FFI_Scalar)).contents
        call_desc = self.call_descriptors[
            ctypes.cast(attr.value, ctypes.POINTER(ctypes.c_int64)).contents.value
        ]
        site = call_desc.__dict__.setdefault("mwjax_cpu_graph", _Site())
        if site.graph is None and (site.calls < _EAGER_CALLS or site.failed):
            site.calls += 1
            return original(self, call_frame, platform)
        try:
            with ffi._FFI_CALLBACK_LOCK:
                _replay(self, site, call_desc, frame)
        except Exception as e:
            if site.graph is None:
                site.failed = True
                warnings.warn(
                    f"Warp call {self.name} runs eagerly on the CPU: recording it failed ({e})", stacklevel=2
                )
                return original(self, call_frame, platform)
            # Reported to XLA as the original callback reports its errors.
            return ffi.create_ffi_error(
                frame.api, ffi.XLA_FFI_Error_Code.UNKNOWN, f"FFI callback error: {type(e).__name__}: {e}"
            )
        return None

    ffi.FfiCallable.ffi_callback = ffi_callback


_holder = threading.local()


def _holding_the_ffi_lock(func: Any) -> Any:
    """`func` run under the lock of Warp's FFI callbacks (re-entered freely by its thread)."""

    @functools.wraps(func)
    def run(*args: Any, **kwargs: Any) -> Any:
        if getattr(_holder, "holds", False):
            return func(*args, **kwargs)
        with ffi._FFI_CALLBACK_LOCK:
            _holder.holds = True
            try:
                return func(*args, **kwargs)
            finally:
                _holder.holds = False

    return run


def _replay(self: ffi.FfiCallable, site: _Site, call_desc: Any, frame: Any) -> None:
    inputs = ctypes.cast(frame.args.args, ctypes.POINTER(ctypes.POINTER(ffi.XLA_FFI_Buffer)))
    outputs = ctypes.cast(frame.rets.rets, ctypes.POINTER(ctypes.POINTER(ffi.XLA_FFI_Buffer)))
    if site.graph is None:
        _record(self, site, call_desc, inputs, outputs)
    for index, staging, size in site.copy_in:
        ctypes.memmove(staging, inputs[index].contents.data, size)
    warp.capture_launch(site.graph)
    for index, staging, size in site.copy_out:
        ctypes.memmove(outputs[index].contents.data, staging, size)


def _record(self: ffi.FfiCallable, site: _Site, call_desc: Any, inputs: Any, outputs: Any) -> None:
    """Stage every array argument of the site and record the callback on the staging arrays."""
    device = warp.get_device("cpu")
    ffi._load_ffi_module(warp.get_module(self.func.__module__), device)
    args = self._build_arg_list(inputs, outputs, call_desc, device)
    for i, arg in enumerate(args):
        if not isinstance(arg, warp.array) or arg.size == 0:
            continue
        staging = warp.empty_like(arg)
        size = arg.size * warp._src.types.type_size_in_bytes(arg.dtype)
        site.keep.append(staging)
        if self.arg_input_indices[i] is not None:
            site.copy_in.append((self.arg_input_indices[i], staging.ptr, size))
        if self.arg_output_indices[i] is not None:
            site.copy_out.append((self.arg_output_indices[i], staging.ptr, size))
        args[i] = staging
    with warp.ScopedDevice(device), warp.ScopedCapture(device=device, force_module_load=False) as capture:
        self.func(*args)
    site.graph = capture.graph
