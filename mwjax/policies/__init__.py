"""Scripted experts for every task, in jax.numpy: vmappable, jittable, written from the
behaviour of `metaworld.policies` (the reference's experts), one family file per task family.

    policy = mwjax.policies.expert_policy(env)      # (params, obs, key) -> actions, whole batch
    action = mwjax.policies.expert("reach-v3")(obs) # one env: obs (39,) -> action (4,)
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np

from mwjax.observation import OBS_SIZE
from mwjax.policies import (  # noqa: F401  (each family module registers its experts)
    articulated,
    assembly,
    ball,
    box_close,
    coffee,
    handles,
    peg,
    placing,
    plate_slide,
    reach_push_pick_place,
    rotary,
    tool_use,
)
from mwjax.policies.common import EXPERTS, Expert

Array = jax.Array


def expert(task: str) -> Expert:
    """The expert of `task`: one observation (39,) -> one action (4,), unclipped like the reference's."""
    if task not in EXPERTS:
        raise ValueError(f"no expert for {task!r}; known: {sorted(EXPERTS)}")
    return EXPERTS[task]


def expert_policy(env: Any) -> Callable[[Any, Array, Array], Array]:
    """A batched policy `(params, obs, key) -> actions` for `env` (an `mwjax.Env`), each env's rows
    driven by its own task's expert; `params` and `key` are ignored (the experts are deterministic).
    Extra observation columns (e.g. a one-hot task id) are ignored."""
    parts = [(env.task_rows(task), jax.vmap(expert(task))) for task in env.task_list]
    # The concatenated parts' rows in env order (a sharded env spreads each task over its devices).
    order = np.argsort(np.concatenate([np.arange(env.num_envs)[rows] for rows, _ in parts]))
    in_order = bool(np.all(order == np.arange(env.num_envs)))

    def policy(params: Any, obs: Array, key: Array) -> Array:
        del params, key
        obs = jnp.asarray(obs)[:, :OBS_SIZE]
        actions = jnp.concatenate([fn(obs[rows]) for rows, fn in parts])
        return actions if in_order else actions[order]

    return policy


__all__ = ["EXPERTS", "expert", "expert_policy"]
