"""Shared fixtures: one compiled all-task env for every test that needs the whole registry (XLA
compiles the 36-scene step once; on a 2-core CPU that alone takes minutes)."""

from __future__ import annotations

import dataclasses
import os
from pathlib import Path

# Without a GPU the suite's time goes mostly to XLA's CPU compiler, for programs that then run a
# few steps: LLVM's optimization passes cost more there than they save (the parity suite's
# fixtures: 182 s instead of 212 s with JAX's cache off). Results can differ from the default
# level's in the last bits (operations contracted or ordered otherwise), so a child process whose
# results a test compares bit for bit keeps these flags. Set before JAX starts its backend.
if not any(Path("/dev").glob("nvidia[0-9]*")):
    os.environ["XLA_FLAGS"] = f"{os.environ.get('XLA_FLAGS', '')} --xla_backend_optimization_level=0".strip()

import children
import jax
import jax.numpy as jnp
import numpy as np
import pytest
from reference import EPISODES, load, load_episodes, ported_tasks, shape

import mwjax
from mwjax import kernels


@pytest.fixture
def usage_error(capsys):
    """`usage_error(main, *args)` calls a command line's `main`, checks that it ends in argparse's
    usage error (exit status 2) and returns what it wrote on stderr."""

    def run(main, *args):
        with pytest.raises(SystemExit) as exit_info:
            main(*args)
        assert exit_info.value.code == 2
        return capsys.readouterr().err

    return run


def _on_gpu() -> bool:
    return jax.default_backend() == "gpu"


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    # Tests that wait for a child go last, so the parent works on the rest while the child runs.
    items.sort(key=lambda item: any(item.get_closest_marker(mark) for mark in ("late", "child")))
    slow_ok = os.environ.get("MWJAX_SLOW") == "1" or _on_gpu()
    for item in items:
        if "gpu" in item.keywords and not _on_gpu():
            item.add_marker(pytest.mark.skip(reason="needs a CUDA GPU"))
        if "slow" in item.keywords and not slow_ok:
            item.add_marker(pytest.mark.skip(reason="long check: set MWJAX_SLOW=1 or run on a GPU"))


def pytest_collection_finish(session: pytest.Session) -> None:
    # Children run beside the suite only on the CPU: on a GPU they would hold its memory at once.
    if _on_gpu() or children.is_child() or session.config.option.collectonly:
        return
    # With Warp's cache empty, the tests' first steps would compile the scenes' kernel modules one
    # after another in this process; build them first, each once, on every core (children too
    # find them). The all-task env's scenes launch every module the task sets' scenes do. A build
    # that Warp's cache records as done returns at once.
    kernels.build(ported_tasks())
    for item in session.items:
        if item.get_closest_marker("child") and not item.get_closest_marker("skip"):
            children.start(item)


def pytest_sessionfinish(session: pytest.Session) -> None:
    children.stop_all()


@dataclasses.dataclass(frozen=True)
class AllTasks:
    """Every registered task with a reference recording, one env per recorded episode. Its goal
    variants are the recorded goals: the parity fixtures' first, then the episode fixtures'."""

    env: mwjax.Env
    reset_with_variants: object
    step: object

    def reset_to_recorded(self, first_variant: int) -> mwjax.State:
        """Every env of each task on its own recorded goal, from `first_variant` on."""
        env = self.env
        variants = first_variant + np.tile(np.arange(env.envs_per_task), len(env.task_list))
        return self.reset_with_variants(jnp.asarray(variants))


@pytest.fixture(scope="session")
def all_tasks() -> AllTasks:
    return make_all_tasks()


def make_all_tasks() -> AllTasks:
    """The `all_tasks` env, also for a child process (tests/test_episodes.py)."""
    ported = ported_tasks()
    goals = {
        task: np.concatenate([load(task)["rand_vec"], load_episodes(EPISODES, task)["rand_vec"]])
        for task in ported
    }
    env = mwjax.make(ported, envs_per_task=shape(ported[0])[0], goal_variants=goals)
    return AllTasks(env=env, reset_with_variants=jax.jit(env.reset_with_variants), step=jax.jit(env.step))
