"""mwjax: Meta-World+ as a batched, jittable simulator on MJX-Warp.

`import mwjax` registers the Gymnasium ids and nothing heavier: JAX, MuJoCo and Warp load at the
first use of `mwjax.make`, `mwjax.Env`, ... (PEP 562), so `python -m mwjax --help`, which runs
this file first, answers at once.
"""

from __future__ import annotations

import importlib
import importlib.util
import os
from typing import TYPE_CHECKING, Any

from mwjax import device_memory
from mwjax.wrappers.registration import register_envs

if TYPE_CHECKING:
    from mwjax.config import EnvConfig
    from mwjax.env import Env, State, make
    from mwjax.physics import PhysicsConfig

# Before any MJWarp kernel module exists: the mode is a module option fixed when it is built.
if os.environ.get("MWJAX_DETERMINISTIC") == "1":
    from mwjax import determinism

    determinism.enable()

# Before JAX starts its backend: JAX's pool would otherwise leave Warp a quarter of the GPU.
device_memory.set_default_pool()
register_envs()

__all__ = ["Env", "EnvConfig", "PhysicsConfig", "State", "make"]
__version__ = "0.1.0"

_LAZY = {
    "Env": "mwjax.env",
    "EnvConfig": "mwjax.config",
    "State": "mwjax.env",
    "make": "mwjax.env",
    "PhysicsConfig": "mwjax.physics",
}


def __getattr__(name: str) -> Any:
    if name in _LAZY:
        return getattr(importlib.import_module(_LAZY[name]), name)
    # `mwjax.benchmarks.custom_ml(...)` and the like work after a bare `import mwjax`.
    if importlib.util.find_spec(f"mwjax.{name}") is not None:
        return importlib.import_module(f"mwjax.{name}")
    raise AttributeError(f"module 'mwjax' has no attribute {name!r}")
