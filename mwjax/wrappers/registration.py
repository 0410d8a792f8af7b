"""The `mwjax/...` Gymnasium ids: the reference's `Meta-World/...` ids and the seed paper's
spellings of them. Importing this needs only Gymnasium; the adapters (and with them JAX and
the simulator) load when an env is made, so `import mwjax` and `python -m mwjax --help` stay fast.
"""

from __future__ import annotations

import importlib
from collections.abc import Callable
from typing import Any

import gymnasium as gym

# metaworld 3.1.1's task-set ids (`metaworld.register_mw_envs`), each with the set it builds.
MT_SETS = ("MT10", "MT25", "MT50")
ML_SETS = ("ML10", "ML25", "ML45")


def _adapter(name: str, *bound: Any) -> Callable[..., Any]:
    """`mwjax.wrappers.gymnasium.<name>(*bound, **kwargs)`, imported at the first call. The
    registration binds the set (and an ML id's split) positionally, so a caller's `split=` on
    e.g. `ML10-train` is refused as a duplicate argument, as the reference refuses it."""

    def create(**kwargs: Any) -> Any:
        adapters = importlib.import_module("mwjax.wrappers.gymnasium")
        return getattr(adapters, name)(*bound, **kwargs)

    create.__name__ = create.__qualname__ = f"{name}{bound!r}"
    return create


def _register_set(env_id: str, *bound: Any) -> None:
    """A task set: `gym.make_vec` gives the vector env; `gym.make` (as the paper writes it) gives
    the same vector env, typed as a `gymnasium.Env` and without Gymnasium's single-env checker."""
    gym.register(
        f"mwjax/{env_id}",
        entry_point=_adapter("vector_as_env", *bound),
        vector_entry_point=_adapter("registered_vector", *bound),
        order_enforce=False,
        disable_env_checker=True,
    )


def register_envs() -> None:
    """Registers every `mwjax/...` id (idempotent)."""
    if "mwjax/MT10" in gym.registry:
        return
    gym.register(
        "mwjax/MT1",
        entry_point=_adapter("MwjaxEnv"),
        vector_entry_point=_adapter("registered_vector", "MT1"),
    )
    for hidden, name in ((True, "goal_hidden"), (False, "goal_observable")):
        gym.register(f"mwjax/{name}", entry_point=_adapter("GoalEnv", hidden))
    for name in MT_SETS:
        _register_set(name, name)
    for name in ("ML1", *ML_SETS):
        for split in ("train", "test"):
            _register_set(f"{name}-{split}", name, split)
    _register_set("custom-mt-envs", "custom-mt")
    _register_set("custom-ml-envs", "custom-ml")
    # The Meta-World+ paper's spellings of the same sets.
    _register_set("MT-custom", "custom-mt")
    _register_set("ML-1-train", "ML1", "train")
    _register_set("ML-1-test", "ML1", "test")
    _register_set("ML-custom", "custom-ml")
