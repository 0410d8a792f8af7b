"""Adapters over the functional core."""

from __future__ import annotations

import importlib
from types import ModuleType


def __getattr__(name: str) -> ModuleType:
    # `import mwjax` loads only `registration`; `mwjax.wrappers.gymnasium` (JAX and the physics)
    # loads at first use, as it did when `import mwjax` imported it.
    if name == "gymnasium":
        return importlib.import_module("mwjax.wrappers.gymnasium")
    raise AttributeError(f"module 'mwjax.wrappers' has no attribute {name!r}")
