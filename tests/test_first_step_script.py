"""`benchmarks/first_step.py`: from `mwjax.make` to a first step, phase by phase, and its result file."""

from __future__ import annotations

import importlib.util
import json
import logging
from pathlib import Path

import pytest

import mwjax

BENCHMARKS = Path(__file__).parents[1] / "benchmarks"


@pytest.fixture
def first_step(monkeypatch):
    monkeypatch.syspath_prepend(str(BENCHMARKS))  # the script imports its sibling `common`
    spec = importlib.util.spec_from_file_location("first_step", BENCHMARKS / "first_step.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_the_wait_for_a_first_step_is_timed_phase_by_phase(first_step, tmp_path):
    out = tmp_path / "first-step.json"
    result = first_step.main(["--set", "reach-v3", "--envs-per-task", "1", "--out", str(out)])
    assert json.loads(out.read_text()) == result
    phases = result["phases_s"]
    names = ["make", "reset_lower", "reset_compile", "reset_run", "step_lower", "step_compile", "step_run"]
    assert list(phases) == names and all(seconds >= 0 for seconds in phases.values())
    assert result["make_to_first_step_s"] >= sum(phases.values()) - 0.01 * len(phases)  # rounding
    assert result["envs"] == 1 and result["overflow_envs"] == 0
    assert result["scenes_together"] is False  # on the CPU the scenes run in turn
    assert result["scenes_per_call"] == mwjax.PhysicsConfig().scenes_per_call  # the default
    assert result["device"] and result["command"].startswith("python") and result["commit"]
    # The step's compile (seconds on the CPU, over JAX's 1 s threshold) reads or writes JAX's cache.
    step = result["jax_cache"]["step"]
    assert result["jax_cache"]["dir"] and step["hits"] + step["writes"] == 1
    assert step["read_s"] > 0 if step["hits"] else step["read_s"] == 0


def test_the_scenes_run_as_asked(first_step, tmp_path):
    """`--concurrent-scenes on` (on the CPU the one call runs the scenes in turn inside it), and
    `--scenes-per-call all` (None: every scene in one call)."""
    argv = [
        "--set",
        "reach-v3",
        "--envs-per-task",
        "1",
        "--concurrent-scenes",
        "on",
        "--scenes-per-call",
        "all",
    ]
    result = first_step.main([*argv, "--out", str(tmp_path / "first-step.json")])
    assert result["scenes_together"] is True and result["overflow_envs"] == 0
    assert result["scenes_per_call"] is None


def test_bad_arguments_end_in_a_usage_error(first_step, tmp_path, usage_error):
    cases = [
        (["--set", "MT11"], "unknown benchmark 'MT11'"),
        (["--envs-per-task", "0"], "positive"),
        (["--concurrent-scenes", "maybe"], "expected on or off"),
        (["--scenes-per-call", "0"], "expected a positive integer or all"),
    ]
    for argv, message in cases:
        assert message in usage_error(first_step.main, [*argv, "--out", str(tmp_path / "x.json")])


@pytest.fixture
def jax_loggers_restored():
    """JAX's cache loggers as they were, after a test that turned their debug lines on."""
    loggers = [logging.getLogger(name) for name in ("jax._src.cache_key", "jax._src.compiler")]
    saved = [(logger.level, list(logger.handlers)) for logger in loggers]
    yield
    for logger, (level, handlers) in zip(loggers, saved, strict=True):
        logger.setLevel(level)
        logger.handlers[:] = handlers


@pytest.mark.usefixtures("jax_loggers_restored")
def test_explain_cache_logs_the_key_parts_and_writes_the_programs(first_step, tmp_path, capfd):
    """`--explain-cache DIR`: the hash of each part of JAX's cache keys on stderr, and the lowered
    reset and step in DIR, to compare with another process's (their writing is not timed)."""
    programs = tmp_path / "programs"
    argv = ["--set", "reach-v3", "--envs-per-task", "1", "--explain-cache", str(programs)]
    result = first_step.main([*argv, "--out", str(tmp_path / "first-step.json")])
    err = capfd.readouterr().err
    assert "get_cache_key hash of serialized computation" in err and "'jit_step'" in err
    for name in ("reset", "step"):
        assert (programs / f"{name}.mlir").read_text().startswith("module @jit_")
    assert result["make_to_first_step_s"] >= sum(result["phases_s"].values()) - 0.01 * len(result["phases_s"])
