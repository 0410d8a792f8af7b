"""`mwjax.kernels`: the Warp modules built ahead, in parallel, are the ones the env's step asks for."""

from __future__ import annotations

import concurrent.futures
import os
import subprocess
import sys
import threading
import time
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
import warp

import mwjax
from mwjax import kernels
from mwjax.benchmarks import task_names
from mwjax.tasks import get_task

ROOT = Path(__file__).parents[1]


def test_scenes_are_the_physics_groups_that_make_builds():
    env = mwjax.make("MT10", envs_per_task=1)
    assert kernels.scenes("MT10") == [(g.scene, g.mocap_bodies) for g in env.physics.groups]


def _fake_pool(monkeypatch, compile_module=None):
    """The build with threads for processes and 7 modules that compile at once (or as
    `compile_module` says); returns the list of the dry runs' (scenes, config)."""
    dry_runs = []

    def distinct_modules(todo, config):
        dry_runs.append((list(todo), config))
        return {f"wp_module_{i}": todo[0] for i in range(7)}

    def compiled(scene, bodies, config, identifier):
        return 1, time.time(), 0.0, 0.0

    monkeypatch.setattr(kernels, "_distinct_modules", distinct_modules)
    monkeypatch.setattr(kernels, "_compile_module", compile_module or compiled)
    monkeypatch.setattr(kernels, "_pool", concurrent.futures.ThreadPoolExecutor)
    return dry_runs


def test_a_completed_build_is_recorded_and_not_repeated(tmp_path, monkeypatch):
    """A build of the same scenes and settings into the same Warp cache returns at once; other
    scenes, other settings or `force` build again."""
    monkeypatch.setattr(warp.config, "kernel_cache_dir", str(tmp_path))
    calls = _fake_pool(monkeypatch)
    assert kernels.build(["push-v3"]).built == 7
    assert kernels.build(["push-v3"]).built == 0
    assert len(calls) == 1
    assert kernels.build(["push-v3"], force=True).built == 7
    assert kernels.build(["push-v3"], mwjax.PhysicsConfig(contacts_per_env=32)).built == 7
    assert kernels.build(["drawer-open-v3"]).built == 7
    assert kernels.build(["drawer-close-v3"]).built == 0  # drawer-open's scene, recorded
    assert len(calls) == 4
    records = sorted(path.name for path in tmp_path.iterdir())
    assert len(records) == 3 and all(name.startswith("mwjax-built-") for name in records)


def test_a_failed_build_leaves_no_record(tmp_path, monkeypatch):
    monkeypatch.setattr(warp.config, "kernel_cache_dir", str(tmp_path))

    def compile_module(scene, bodies, config, identifier):
        raise RuntimeError("a worker failed")

    _fake_pool(monkeypatch, compile_module)
    with pytest.raises(RuntimeError):
        kernels.build(["push-v3"])
    assert not list(tmp_path.iterdir())


def test_a_started_build_compiles_while_the_caller_goes_on(tmp_path, monkeypatch):
    """`start_build` returns with the modules still compiling; `result()` waits for them all and
    only then records the build."""
    monkeypatch.setattr(warp.config, "kernel_cache_dir", str(tmp_path))
    release = threading.Event()

    def compile_module(scene, bodies, config, identifier):
        assert release.wait(timeout=30)
        return 1, time.time(), 0.0, 0.0

    _fake_pool(monkeypatch, compile_module)
    pending = kernels.start_build(["push-v3"], workers=2)
    assert not pending.done and pending.modules == 7 and pending.workers == 2
    assert not list(tmp_path.iterdir())
    release.set()
    result = pending.result()
    assert result.built == 7 and len(result.modules) == 7 and pending.done
    assert [path.name.startswith("mwjax-built-") for path in tmp_path.iterdir()] == [True]
    assert kernels.start_build(["push-v3"]).done  # recorded: nothing to wait for


def _gpu_children(monkeypatch, tmp_path, returncode=0, delay_s=0.0):
    """`prebuild` as on a GPU, into the Warp cache `tmp_path`, its child process run here (the
    CLI with the fake pool) and recorded; returns the list of the children's commands."""
    monkeypatch.setattr(warp.config, "kernel_cache_dir", str(tmp_path))
    monkeypatch.setattr(kernels, "local_device", lambda: SimpleNamespace(platform="gpu"))
    monkeypatch.delenv(kernels.PREBUILD_VARIABLE, raising=False)
    _fake_pool(monkeypatch)
    commands = []

    def run(command, env, stdout, text):
        commands.append(command)
        assert env["PYTHONPATH"].split(os.pathsep)[0] == str(ROOT)
        time.sleep(delay_s)
        if returncode == 0:
            kernels.main(command[3:])
        return subprocess.CompletedProcess(command, returncode, stdout="7 kernel modules built\n")

    monkeypatch.setattr(kernels.subprocess, "run", run)
    return commands


def test_an_env_on_a_gpu_builds_its_scenes_in_a_child_process_first(tmp_path, monkeypatch, capsys):
    """Its own scenes and settings, through `python -m mwjax.kernels` of the same mwjax; once:
    a later env of those scenes, or of some of them, finds them recorded."""
    commands = _gpu_children(monkeypatch, tmp_path)
    config = mwjax.PhysicsConfig(contacts_per_env=48)
    env = mwjax.make(["push-v3", "door-open-v3"], envs_per_task=1, physics=config)
    assert "7 kernel modules built" in capsys.readouterr().err  # the child's summary, as a status line
    [command] = commands
    assert command[:4] == [sys.executable, "-m", "mwjax.kernels", "--scenes"]
    todo = [(g.scene, g.mocap_bodies) for g in env.physics.groups]
    assert len(todo) == 2 and all(path.exists() for path in kernels.scene_records(todo, config))
    mwjax.make(["door-close-v3"], envs_per_task=1, physics=config)  # door-open's scene
    assert len(commands) == 1
    mwjax.make(["door-close-v3"], envs_per_task=1)  # other settings: other modules
    assert len(commands) == 2


def test_the_prebuild_leaves_alone_cpus_opt_outs_and_builds_under_way(tmp_path, monkeypatch):
    commands = _gpu_children(monkeypatch, tmp_path)
    todo, config = kernels.scenes(["push-v3"]), mwjax.PhysicsConfig()
    monkeypatch.setenv(kernels.PREBUILD_VARIABLE, "0")
    kernels.prebuild(todo, config)
    monkeypatch.delenv(kernels.PREBUILD_VARIABLE)
    with monkeypatch.context() as cpu:
        cpu.setattr(kernels, "local_device", lambda: SimpleNamespace(platform="cpu"))
        kernels.prebuild(todo, config)
    assert commands == []
    release = threading.Event()

    def compile_module(scene, bodies, config, identifier):
        assert release.wait(timeout=30)
        return 1, time.time(), 0.0, 0.0

    monkeypatch.setattr(kernels, "_compile_module", compile_module)
    pending = kernels.start_build(["push-v3"], workers=2)
    kernels.prebuild(todo, config)  # this process's own build has them
    assert commands == []
    release.set()
    assert pending.result().built == 7


def test_processes_that_make_envs_at_once_build_once(tmp_path, monkeypatch):
    commands = _gpu_children(monkeypatch, tmp_path, delay_s=0.5)
    arguments = (kernels.scenes(["push-v3"]), mwjax.PhysicsConfig())
    threads = [threading.Thread(target=kernels.prebuild, args=arguments) for _ in range(3)]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()
    assert len(commands) == 1


def test_a_failed_child_warns_and_leaves_the_modules_to_the_first_step(tmp_path, monkeypatch):
    commands = _gpu_children(monkeypatch, tmp_path, returncode=1)
    todo, config = kernels.scenes(["push-v3"]), mwjax.PhysicsConfig()
    with pytest.warns(RuntimeWarning, match="exit 1"):
        kernels.prebuild(todo, config)
    assert len(commands) == 1 and not any(path.exists() for path in kernels.scene_records(todo, config))


def test_a_cache_folder_that_cannot_be_written_warns_instead_of_failing_the_env(tmp_path, monkeypatch):
    commands = _gpu_children(monkeypatch, tmp_path)
    (tmp_path / "file").write_text("")
    monkeypatch.setattr(warp.config, "kernel_cache_dir", str(tmp_path / "file" / "cache"))
    with pytest.warns(RuntimeWarning, match="the first step compiles them"):
        kernels.prebuild(kernels.scenes(["push-v3"]), mwjax.PhysicsConfig())
    assert commands == []


def test_the_command_line_refuses_an_unknown_set_without_a_traceback(usage_error):
    assert "unknown benchmark 'MT11'" in usage_error(kernels.main, ["MT11"])


def test_the_child_builds_in_this_process_s_deterministic_mode(monkeypatch):
    # Switched on by `determinism.enable()` here, not by the variable the child would read.
    monkeypatch.delenv("MWJAX_DETERMINISTIC", raising=False)
    assert "MWJAX_DETERMINISTIC" not in kernels._child_environment()
    monkeypatch.setattr(kernels.determinism, "enabled", lambda: True)
    assert kernels._child_environment()["MWJAX_DETERMINISTIC"] == "1"


def test_the_summary_names_the_slowest_module_and_the_last_to_finish():
    modules = (
        kernels.ModuleTime("wp_a_1", "s", 1, started_s=1.0, setup_s=2.0, compile_s=30.0),
        kernels.ModuleTime("wp_b_2", "s", 1, started_s=20.0, setup_s=0.0, compile_s=15.0),
        kernels.ModuleTime("wp_c_3", "s", 0, started_s=2.0, setup_s=1.0, compile_s=0.1),
    )
    build = kernels.Build(built=2, seconds=36.0, dry_run_s=0.8, workers=2, modules=modules)
    summary = build.summary()
    assert summary.startswith("2 kernel modules built in 36 s: dry run 0.8 s, then 3 modules in 2 processes")
    assert "slowest compile 30.0 s (wp_a_1)" in summary
    assert "last to finish wp_b_2, started at 20.0 s" in summary
    assert [line.split()[-2] for line in build.report().splitlines()[1:]] == ["wp_b_2", "wp_a_1", "wp_c_3"]
    assert kernels.Build(built=0, seconds=0.1).summary() == "0 kernel modules built in 0 s"


def test_the_slow_module_families_go_first_and_name_real_modules():
    """The pool's order puts the convex collider's modules (the longest GPU compiles) first, and
    every family `_slow_first` ranks names a module that a scene's step launches."""
    modules = list(kernels.launched_modules(*kernels.scenes(["reach-v3"])[0], mwjax.PhysicsConfig()))
    for family in kernels._SLOW_FAMILIES:
        assert any(family in identifier for identifier in modules), family
    collider = [identifier for identifier in modules if "ccd_kernel" in identifier]
    assert collider and sorted(modules, key=kernels._slow_first)[: len(collider)] == collider


def test_a_meta_learning_set_covers_both_splits():
    names = {scene for scene, _ in kernels.scenes("ML10")}
    tasks = task_names("ML10", "train") + task_names("ML10", "test")
    expected = {get_task(name).scene for name in tasks}
    assert names == expected


def test_the_dry_run_lists_the_modules_a_real_step_loads(monkeypatch):
    """`launched_modules` (no kernel runs) names exactly the modules, with their block sizes, that
    a real `step_once` (model and data set-up, step, kinematics) of each of MT10's scenes loads."""
    from warp._src.context import Module

    loaded = set()
    load = Module.load

    def recording_load(module, device, block_dim=None, *args, **kwargs):
        loaded.add(module.get_module_identifier(block_dim=block_dim))
        return load(module, device, block_dim, *args, **kwargs)

    config = mwjax.PhysicsConfig()
    for scene, bodies in kernels.scenes("MT10"):
        listed = kernels.launched_modules(scene, bodies, config)
        loaded.clear()
        with monkeypatch.context() as patch:
            patch.setattr(Module, "load", recording_load)
            kernels.step_once(scene, bodies, config)
        assert set(listed) == loaded, scene


def test_the_dry_run_loads_no_module_and_answers_occupancy_queries_itself(monkeypatch):
    """The dry run compiles nothing in the calling process: every path that loads a module is
    recorded instead, Warp's occupancy query included (on a GPU it loads the kernel's module;
    MJWarp asks it for its broadphase, its convex collider and its solver)."""
    from warp._src.context import Module

    def refuse(*args, **kwargs):
        raise AssertionError("the dry run loaded a module")

    monkeypatch.setattr(Module, "load", refuse)
    monkeypatch.setattr(warp, "get_suggested_block_size", refuse)
    scene, bodies = kernels.scenes(["push-v3"])[0]
    listed = kernels.launched_modules(scene, bodies, mwjax.PhysicsConfig())
    assert any("nxn_broadphase" in name for name in listed)  # the module whose grid it queries
    assert warp.get_suggested_block_size is refuse  # restored after the dry run


@warp.kernel
def _add_one(values: warp.array(dtype=float)):
    values[warp.tid()] += 1.0


def test_a_launch_from_another_thread_runs_during_a_dry_run():
    values = warp.zeros(4, dtype=float, device="cpu")
    launches = []
    with kernels._recording_launches(launches):
        warp.launch(_add_one, dim=4, inputs=[values], device="cpu")  # recorded, not run
        other = threading.Thread(target=lambda: warp.launch(_add_one, dim=4, inputs=[values], device="cpu"))
        other.start()
        other.join()
    assert [module for module, _, _ in launches] == [_add_one.module]
    np.testing.assert_array_equal(values.numpy(), np.ones(4))


@pytest.mark.slow
def test_after_a_build_the_first_step_compiles_no_scene_module(tmp_path):
    # A fresh Warp cache: the build compiles every module of the two scenes; a new process that
    # makes and steps the env then compiles at most MJX's own FFI module (not scene-specific).
    env = {**os.environ, "WARP_CACHE_PATH": str(tmp_path)}
    build = [sys.executable, "-m", "mwjax.kernels", "push-v3,pick-place-v3", "--workers", "2"]
    report = [*build, "--report"]
    built = subprocess.run(report, cwd=ROOT, env=env, capture_output=True, text=True, check=True)
    count = int(built.stdout.split()[0])
    assert count > 10, built.stdout
    rows = built.stdout.splitlines()[2:]  # the summary, the report's header, a row per module
    assert len(rows) >= count and all(row.split()[3].startswith("wp_") for row in rows), built.stdout
    again = subprocess.run(build, cwd=ROOT, env=env, capture_output=True, text=True, check=True)
    assert int(again.stdout.split()[0]) == 0, again.stdout  # recorded: no processes, nothing built
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


@pytest.mark.slow
def test_the_child_process_of_a_prebuild_builds_and_records_the_scenes(tmp_path):
    # The command `prebuild` runs, for real, into a fresh Warp cache: it builds the env's scenes
    # with its settings, and records each.
    config = mwjax.PhysicsConfig(contacts_per_env=48)
    todo = kernels.scenes(["push-v3", "door-open-v3"])
    env = {**os.environ, "WARP_CACHE_PATH": str(tmp_path)}
    command = kernels.child_command(todo, config)
    built = subprocess.run(command, cwd=tmp_path, env=env, capture_output=True, text=True, check=True)
    assert int(built.stdout.split()[0]) > 10, built.stdout
    records = sorted(path.name for path in Path(tmp_path).rglob("mwjax-built-*"))
    assert len(records) == 2, records


def test_records_name_what_selects_the_modules():
    todo = kernels.scenes(["reach-v3"])
    default = kernels.scene_records(todo, mwjax.PhysicsConfig())
    assert default is not None
    assert kernels.scene_records(todo, mwjax.PhysicsConfig(concurrent_scenes=True)) == default
    assert kernels.scene_records(todo, mwjax.PhysicsConfig(scenes_per_call=2)) == default
    assert kernels.scene_records(todo, mwjax.PhysicsConfig(graph_mode="warp_staged_ex")) == default
    assert kernels.scene_records(todo, mwjax.PhysicsConfig(substeps=4)) != default
