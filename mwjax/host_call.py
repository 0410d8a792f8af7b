"""Python on the host from inside a compiled program, without a host callback.

JAX does not write a program that holds a Python host callback (`jax.debug.callback`,
`io_callback`, `pure_callback`) to its persistent compilation cache: the callback's address is
baked into the program. A step that warned through one would be compiled afresh by every process
(MT50's step: minutes on a GPU instead of a cache read). So the step calls an XLA FFI target
registered by name instead, as MJX-Warp's own calls are: the compiled program names the target and
carries its attributes, and is cached like any other; a new process registers the target again
(importing `mwjax.physics` does) before it runs a cached program.

`register(name, func)` makes `func(array, attrs)` a target; `call(name, x, **attrs)` calls it
from traced code with `x` as a host NumPy array (copied from the GPU on XLA's stream) and the
string attributes. It is for rare events (under `lax.cond`): each call synchronizes the host
with the device.
"""

from __future__ import annotations

import ctypes
import functools
import threading
import warnings
from collections.abc import Callable

import jax
import numpy as np
import warp
from warp._src.jax import ffi, xla_ffi

Handler = Callable[[np.ndarray, dict[str, str]], None]

_HANDLER_TYPE = ctypes.CFUNCTYPE(ctypes.c_void_p, ctypes.POINTER(xla_ffi.XLA_FFI_CallFrame))
_PLATFORMS = ("cpu", "CUDA")
_lock = threading.Lock()
# The ctypes handlers XLA holds pointers to, kept alive for the process's life.
_registered: dict[str, list[object]] = {}


def register(name: str, func: Handler) -> None:
    """Make `func` the FFI target `name` on the CPU and on CUDA (idempotent per name)."""
    register_target(name, lambda platform: functools.partial(_handle, func, name, platform))


def register_target(name: str, handler_for: Callable[[str], Callable[[object], int | None]]) -> None:
    """Make `handler_for(platform)`, which takes XLA's call frame, the FFI target `name` on the
    CPU ("cpu") and on CUDA ("CUDA") (idempotent per name)."""
    with _lock:
        if name in _registered:
            return
        handlers = []
        for platform in _PLATFORMS:
            handler = _HANDLER_TYPE(handler_for(platform))
            capsule = jax.ffi.pycapsule(ctypes.cast(handler, ctypes.c_void_p).value)
            jax.ffi.register_ffi_target(name, capsule, platform=platform)
            handlers.append(handler)
        _registered[name] = handlers


def version_query(frame: xla_ffi.XLA_FFI_CallFrame) -> bool:
    """Whether the call is XLA's first, which asks for the API version the handler speaks (then
    answered: not command-buffer compatible)."""
    extension = frame.extension_start
    if not (extension and extension.contents.type == xla_ffi.XLA_FFI_Extension_Type.Metadata):
        return False
    metadata = ctypes.cast(extension, ctypes.POINTER(xla_ffi.XLA_FFI_Metadata_Extension))
    metadata.contents.metadata.contents.api_version.major_version = 0
    metadata.contents.metadata.contents.api_version.minor_version = 1
    return True


def call(name: str, x: jax.Array, **attrs: str) -> None:
    """Call the target `name` on `x` from traced code (under `vmap`, with the batch axes)."""
    jax.ffi.ffi_call(name, (), has_side_effect=True, vmap_method="broadcast_all")(x, **attrs)


def _handle(func: Handler, name: str, platform: str, call_frame: object) -> int | None:
    frame = call_frame.contents
    if version_query(frame):
        return None
    try:
        args = ctypes.cast(frame.args.args, ctypes.POINTER(ctypes.POINTER(xla_ffi.XLA_FFI_Buffer)))
        buffer = args[0].contents
        shape = tuple(buffer.dims[i] for i in range(buffer.rank))
        dtype = np.dtype(xla_ffi._jnp_dtype_for_xla(buffer.dtype))
        host = np.empty(shape, dtype)
        if platform == "CUDA":
            _copy_from_device(frame, host, buffer.data)
        else:
            ctypes.memmove(host.ctypes.data, buffer.data, host.nbytes)
        func(host, xla_ffi.decode_attrs(frame.attrs))
    except Exception as e:  # a failed notice must not fail the step that raised it
        warnings.warn(f"{name} failed on the host: {type(e).__name__}: {e}", RuntimeWarning, stacklevel=1)
    return None


def _copy_from_device(frame: object, host: np.ndarray, source: int) -> None:
    """Copy `host.nbytes` from the device pointer `source`, in order on XLA's stream. Under the
    lock of Warp's FFI callbacks: with several GPUs, another device's thread may be capturing a
    CUDA graph, which a synchronizing copy from elsewhere in the process would break."""
    if warp._src.context.runtime is None:
        warp.init()
    core = warp._src.context.runtime.core
    stream = xla_ffi.get_stream_from_callframe(frame)
    device = warp.get_cuda_device(xla_ffi.get_device_ordinal_from_callframe(frame))
    with ffi._FFI_CALLBACK_LOCK:
        if not core.wp_memcpy_d2h(device.context, host.ctypes.data, source, host.nbytes, stream):
            raise RuntimeError("device-to-host copy failed")
        core.wp_cuda_stream_synchronize(stream)
