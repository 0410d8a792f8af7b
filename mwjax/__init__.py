"""mwjax: Meta-World+ as a batched, jittable simulator on MJX-Warp."""

import os

from mwjax import determinism

# Before any MJWarp kernel module exists: the mode is a module option fixed when it is built.
if os.environ.get("MWJAX_DETERMINISTIC") == "1":
    determinism.enable()

from mwjax.env import Env, State, make  # noqa: E402
from mwjax.physics import PhysicsConfig  # noqa: E402
from mwjax.wrappers.gymnasium import register_envs  # noqa: E402

register_envs()

__all__ = ["Env", "PhysicsConfig", "State", "make"]
__version__ = "0.1.0"
