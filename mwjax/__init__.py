"""mwjax: Meta-World+ as a batched, jittable simulator on MJX-Warp."""

from mwjax.env import Env, State, make
from mwjax.physics import PhysicsConfig
from mwjax.wrappers.gymnasium import register_envs

register_envs()

__all__ = ["Env", "PhysicsConfig", "State", "make"]
__version__ = "0.1.0"
