"""Shared fixtures: one compiled all-task env for every test that needs the whole registry (XLA
compiles the 36-scene step once; on a 2-core CPU that alone takes minutes)."""

from __future__ import annotations

import dataclasses
import os

import jax
import pytest
from reference import recorded_tasks, shape

import mwjax
from mwjax.tasks import TASKS


def _on_gpu() -> bool:
    return jax.default_backend() == "gpu"


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    slow_ok = os.environ.get("MWJAX_SLOW") == "1" or _on_gpu()
    for item in items:
        if "gpu" in item.keywords and not _on_gpu():
            item.add_marker(pytest.mark.skip(reason="needs a CUDA GPU"))
        if "slow" in item.keywords and not slow_ok:
            item.add_marker(pytest.mark.skip(reason="long check: set MWJAX_SLOW=1 or run on a GPU"))


@dataclasses.dataclass(frozen=True)
class AllTasks:
    """Every registered task with a reference recording, one env per recorded reset."""

    env: mwjax.Env
    reset_to: object
    step: object


@pytest.fixture(scope="session")
def all_tasks() -> AllTasks:
    ported = [task for task in recorded_tasks() if task in TASKS]
    env = mwjax.make(ported, envs_per_task=shape(ported[0])[0])
    return AllTasks(env=env, reset_to=jax.jit(env.reset_to), step=jax.jit(env.step))
