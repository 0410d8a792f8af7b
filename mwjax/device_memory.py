"""GPU memory shared by JAX and Warp.

JAX reserves 75% of a GPU for its own pool when its backend starts, but MJX-Warp allocates the
physics' collider and solver scratch with Warp, outside that pool: about 100 KB per env for MT50
(docs/performance.md, "MT50 at larger batches"). With JAX's default, a large batch fails inside
Warp ("Failed to allocate ... bytes"), minutes into its first step. So:

- `import mwjax` sets `XLA_PYTHON_CLIENT_MEM_FRACTION` to `DEFAULT_FRACTION` (45%, what every
  figure in the README was measured with) when no JAX memory setting was made and JAX's backend
  has not started; a variable set by the user wins.
- On a GPU whose JAX pool was fixed at more than `WARN_ABOVE` anyway (JAX started first, or a
  setting), `mwjax.make` warns once.
- A Warp allocation failure inside mwjax's own Warp calls says which knobs to turn.
"""

from __future__ import annotations

import os
import sys
import warnings
from collections.abc import MutableMapping

FRACTION_VARIABLE = "XLA_PYTHON_CLIENT_MEM_FRACTION"
# Any of these means the user chose how JAX takes memory.
USER_SETTINGS = (FRACTION_VARIABLE, "XLA_PYTHON_CLIENT_PREALLOCATE", "XLA_PYTHON_CLIENT_ALLOCATOR")
DEFAULT_FRACTION = "0.45"
WARN_ABOVE = 0.6
_HINT = (
    "Warp allocates the physics' scratch outside JAX's memory pool (~100 KB per env for MT50). "
    f"Give it room: a smaller {FRACTION_VARIABLE} (mwjax's default is {DEFAULT_FRACTION}; MT50 at "
    "716,800 envs needs 0.37 on a 141 GB H200), set before JAX starts, or fewer envs."
)


def set_default_pool(environ: MutableMapping[str, str] | None = None) -> bool:
    """Set JAX's pool to `DEFAULT_FRACTION` of the GPU unless the user chose a memory setting or
    JAX's backend already started (then the variable would be read by no one). Returns whether
    it set it."""
    environ = os.environ if environ is None else environ
    if any(name in environ for name in USER_SETTINGS) or _backend_started():
        return False
    environ[FRACTION_VARIABLE] = DEFAULT_FRACTION
    return True


def _backend_started() -> bool:
    if "jax" not in sys.modules:  # JAX not imported: its backend cannot have started
        return False
    from jax._src import xla_bridge

    return xla_bridge.backends_are_initialized()


def pool_warning(pool_bytes: int, total_bytes: int) -> str | None:
    """The warning for a JAX pool of `pool_bytes` on a GPU of `total_bytes`, if it leaves Warp
    too little room."""
    if total_bytes <= 0 or pool_bytes / total_bytes <= WARN_ABOVE:
        return None
    share = f"{pool_bytes / total_bytes:.0%}"
    return (
        f"JAX's memory pool holds {share} of this GPU, so large batches may fail inside Warp. "
        f"{_HINT} (`import mwjax` before JAX starts sets it when no JAX memory variable is set.)"
    )


class DeviceMemoryWarning(UserWarning):
    """JAX's memory pool leaves Warp too little of the GPU."""


_warned = False


def check_pool(device: object) -> None:
    """Warn once per process if JAX's pool on the GPU `device` leaves Warp too little room."""
    global _warned
    if _warned or getattr(device, "platform", None) != "gpu" or not _preallocates():
        return
    try:
        stats = device.memory_stats() or {}  # type: ignore[attr-defined]
        total = gpu_memory_bytes(device)
    except (AttributeError, RuntimeError, TypeError, ValueError):
        return  # a device that cannot report its memory gets no warning, and the env is made
    message = pool_warning(int(stats.get("bytes_limit", 0)), total)
    if message:
        _warned = True
        warnings.warn(message, DeviceMemoryWarning, stacklevel=3)


def gpu_memory_bytes(device: object) -> int:
    """The GPU memory of the JAX device `device`, as CUDA reports it (through Warp)."""
    import warp as wp

    return int(wp.get_device(f"cuda:{getattr(device, 'local_hardware_id', 0) or 0}").total_memory)


def _preallocates() -> bool:
    """Whether JAX holds its whole pool from the start (its default), rather than growing it."""
    growing = os.environ.get("XLA_PYTHON_CLIENT_PREALLOCATE", "").lower() in ("false", "0")
    return not growing and os.environ.get("XLA_PYTHON_CLIENT_ALLOCATOR") != "platform"


def explained(error: Exception) -> str:
    """`error`'s message, with what to do if it is Warp failing to allocate device memory."""
    message = str(error)
    return f"{message}. {_HINT}" if "Failed to allocate" in message else message
