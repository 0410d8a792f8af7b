"""`mwjax.kernels`: the Warp modules built ahead, in parallel, are the ones the env's step asks for."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

import mwjax
from mwjax import kernels
from mwjax.benchmarks import task_names
from mwjax.tasks import get_task

ROOT = Path(__file__).parents[1]


def test_scenes_are_the_physics_groups_that_make_builds():
    env = mwjax.make("MT10", envs_per_task=1)
    assert kernels.scenes("MT10") == [(g.scene, g.mocap_bodies) for g in env.physics.groups]


def test_a_meta_learning_set_covers_both_splits():
    names = {scene for scene, _ in kernels.scenes("ML10")}
    tasks = task_names("ML10", "train") + task_names("ML10", "test")
    expected = {get_task(name).scene for name in tasks}
    assert names == expected


@pytest.mark.slow
def test_after_a_build_the_first_step_compiles_no_scene_module(tmp_path):
    # A fresh Warp cache: the build compiles every module of the two scenes; a new process that
    # makes and steps the env then compiles at most MJX's own FFI module (not scene-specific).
    env = {**os.environ, "WARP_CACHE_PATH": str(tmp_path)}
    build = [sys.executable, "-m", "mwjax.kernels", "push-v3,pick-place-v3", "--workers", "2"]
    built = subprocess.run(build, cwd=ROOT, env=env, capture_output=True, text=True, check=True)
    assert int(built.stdout.split()[0]) > 10, built.stdout
    step = (
        "import jax, mwjax\n"
        "from mwjax import progress\n"
        "env = mwjax.make(['push-v3', 'pick-place-v3'], envs_per_task=2)\n"
        "state = env.reset(jax.random.key(0))\n"
        "jax.block_until_ready(jax.jit(env.step)(state, jax.numpy.zeros((4, 4))))\n"
        "print(progress.kernel_builds().built)\n"
    )
    run = subprocess.run(
        [sys.executable, "-c", step], cwd=ROOT, env=env, capture_output=True, text=True, check=True
    )
    assert int(run.stdout.split()[-1]) <= 1, run.stdout
