#!/usr/bin/env python
"""The reference's Gymnasium registry: every `Meta-World/...` id, which entry points it has, and
the keyword arguments it accepts, with their defaults; and the goal that its goal_observable /
goal_hidden envs draw for a few seeds, with their first observation.

Runs in the reference venv (see tools/README_reference.md); never imports mwjax. An id's kwargs
are its registered lambda's own parameters plus those its `**kwargs` reach down the reference's
call chain (`_mt_bench_vector_entry_point` -> `make_mt_envs` -> `_init_each_env`, ...), less the
ones a step of the chain binds itself. The chains are read off `metaworld/__init__.py` (3.1.1)
and written out below; the signatures come from the installed code.

    .venv-ref/bin/python tools/record_registry.py   # -> tests/fixtures/reference/registry.json
"""

from __future__ import annotations

import argparse
import enum
import functools
import inspect
import json
import warnings
from collections.abc import Callable
from importlib import metadata
from typing import Any

import gymnasium as gym
import metaworld
import numpy as np

MT_SETS = ("MT10", "MT25", "MT50")
ML_SETS = ("ML1", "ML10", "ML25", "ML45")
GOAL_ENVS = (("reach-v3", 3), ("pick-place-v3", 42), ("door-open-v3", 0), ("peg-insert-side-v3", 7))

# What an id's `**kwargs` reach, as (callable, names that the caller binds there). `name` and
# `benchmark` are bound positionally everywhere.
_INIT = metaworld._init_each_env
_MT1_CHAIN = [(metaworld.make_mt_envs, {"name", "seed", "use_one_hot", "vector_strategy", "autoreset_mode"})]
_MT1_CHAIN.append((_INIT, {"env_cls", "tasks", "seed", "num_tasks"}))
_MT_SET_CHAIN = [_MT1_CHAIN[0], (_INIT, {"env_cls", "tasks", "seed", "env_id", "num_tasks"})]
_ML_BOUND = {
    "name",
    "seed",
    "meta_batch_size",
    "total_tasks_per_cls",
    "split",
    "vector_strategy",
    "autoreset_mode",
}


def _ml_chain(make: functools.partial) -> list[tuple[Callable[..., Any], set[str]]]:
    return [
        (make, _ML_BOUND),
        (metaworld._make_ml_envs_inner, _ML_BOUND | {"benchmark"}),
        (_INIT, {"env_cls", "tasks", "seed"}),
    ]


_CUSTOM_MT_CHAIN = [
    (
        metaworld.make_mt_envs,
        {"name", "seed", "num_tasks", "env_id", "use_one_hot", "vector_strategy", "autoreset_mode"},
    ),
    (_INIT, {"env_cls", "tasks", "seed", "num_tasks", "env_id", "use_one_hot"}),
]
_CUSTOM_ML_CHAIN = [
    (metaworld._make_ml_envs_inner, _ML_BOUND - {"split"} | {"benchmark"}),
    (_INIT, {"env_cls", "tasks", "seed"}),
]


def chain_of(env_id: str) -> list[tuple[Callable[..., Any], set[str]]]:
    name = env_id.removeprefix("Meta-World/")
    if name in ("goal_hidden", "goal_observable"):
        return []
    if name == "MT1":
        return _MT1_CHAIN
    if name in MT_SETS:
        return _MT_SET_CHAIN
    if name.split("-")[0] in ML_SETS:
        train = name.endswith("-train")
        return _ml_chain(metaworld.make_ml_envs_train if train else metaworld.make_ml_envs_test)
    return {"custom-mt-envs": _CUSTOM_MT_CHAIN, "custom-ml-envs": _CUSTOM_ML_CHAIN}[name]


def jsonable(value: Any) -> Any:
    return value.value if isinstance(value, enum.Enum) else value


def parameters(function: Callable[..., Any], bound: set[str]) -> dict[str, dict[str, Any]]:
    """Keyword parameters of `function` not in `bound`: {name: {"required", "default"}}."""
    keywords = function.keywords if isinstance(function, functools.partial) else {}
    out = {}
    for param in inspect.signature(function).parameters.values():
        if param.kind in (param.VAR_KEYWORD, param.VAR_POSITIONAL) or param.name in bound:
            continue
        if param.name.startswith("_"):  # a lambda's default-bound set or split
            continue
        default = keywords.get(param.name, param.default)
        required = default is inspect.Parameter.empty
        out[param.name] = {"required": required, "default": None if required else jsonable(default)}
    # A partial's keywords that its function only takes through `**kwargs` (ML's task_select).
    for name, value in keywords.items():
        if name not in bound:
            out[name] = {"required": False, "default": jsonable(value)}
    return out


def kwargs_of(spec: gym.envs.registration.EnvSpec) -> dict[str, dict[str, Any]]:
    entry = spec.entry_point or spec.vector_entry_point
    accepted = parameters(entry, set())
    for function, bound in chain_of(spec.id):
        for name, info in parameters(function, bound).items():
            accepted.setdefault(name, info)
    if spec.id.removeprefix("Meta-World/") in ("MT1", *MT_SETS):
        # `_mt_bench_vector_entry_point` pops it out of its kwargs (the goals per task).
        accepted.setdefault("num_goals", {"required": False, "default": metaworld._N_GOALS})
    return dict(sorted(accepted.items()))


def goal_envs() -> list[dict[str, Any]]:
    out = []
    for task, seed in GOAL_ENVS:
        row: dict[str, Any] = {"env_name": task, "seed": seed}
        for kind in ("goal_observable", "goal_hidden"):
            env = gym.make(f"Meta-World/{kind}", env_name=task, seed=seed)
            obs, _ = env.reset()
            row[kind] = {"rand_vec": env.unwrapped._last_rand_vec.tolist(), "reset_obs": obs.tolist()}
            env.close()
        out.append(row)
    return out


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--out", default="tests/fixtures/reference/registry.json")
    args = parser.parse_args()
    warnings.filterwarnings("ignore")
    ids = {}
    for env_id, spec in gym.registry.items():
        if not env_id.startswith("Meta-World/"):
            continue
        ids[env_id.removeprefix("Meta-World/")] = {
            "entry_point": spec.entry_point is not None,
            "vector_entry_point": spec.vector_entry_point is not None,
            "kwargs": kwargs_of(spec),
        }
    record = {
        "what": "metaworld's registered Gymnasium ids: entry points and accepted kwargs; goal env resets",
        "versions": {name: metadata.version(name) for name in ("metaworld", "gymnasium", "mujoco", "numpy")},
        "ids": ids,
        "goal_envs": goal_envs(),
    }
    with open(args.out, "w") as file:
        json.dump(record, file, indent=1, default=lambda x: np.asarray(x).tolist())
        file.write("\n")
    print(f"{len(ids)} ids -> {args.out}")


if __name__ == "__main__":
    main()
