"""The throughput benchmark's protocol: a row where any env dropped something gets no figure."""

from __future__ import annotations

import importlib.util
import json
import os
import sys
from pathlib import Path

import children
import pytest

import mwjax

SCRIPT = Path(__file__).parents[1] / "benchmarks" / "throughput.py"


def _refused_row(workdir: Path) -> tuple[list[str], dict[str, str]]:
    command = [sys.executable, str(SCRIPT), "--sets", "reach-v3", "--batch", "2", "--steps", "3"]
    return [*command, "--constraints", "4", "--out", str(workdir / "row.json")], dict(os.environ)


@pytest.mark.child.with_args(_refused_row)
def test_a_row_with_overflow_is_refused_and_a_shorter_rollout_is_labelled(request):
    run, workdir = children.result(request.node)
    assert run.returncode != 0, run.stdout + run.stderr
    assert "refused" in run.stderr
    result = json.loads((workdir / "row.json").read_text())
    (row,) = result["results"]
    assert row["env_steps_per_s"] is None
    assert row["overflow_envs"] == 2
    assert row["protocol"] == "labelled: 3-step rollouts; constraints_per_env=4"
    for key in ("device", "commit", "date", "command"):
        assert result[key]


@pytest.fixture(scope="module")
def throughput():
    sys.path.insert(0, str(SCRIPT.parent))  # the script imports its sibling `common`
    try:
        spec = importlib.util.spec_from_file_location("throughput", SCRIPT)
        module = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(module)
        yield module
    finally:
        sys.path.remove(str(SCRIPT.parent))


@pytest.mark.parametrize(
    ("together", "platform", "labels"),
    [
        (None, "gpu", []),
        (True, "gpu", []),  # what the default does on one GPU
        (False, "gpu", ["concurrent_scenes=False"]),
        (None, "cpu", []),
        (True, "cpu", ["concurrent_scenes=True"]),
    ],
)
def test_scenes_side_by_side_are_labelled_by_what_the_device_runs(
    throughput, monkeypatch, together, platform, labels
):
    monkeypatch.delenv("MWJAX_CONCURRENT_SCENES", raising=False)
    physics = mwjax.PhysicsConfig(concurrent_scenes=together)
    assert throughput.deviations(500, True, None, physics, platform) == labels


def test_scenes_in_turn_by_the_environment_are_labelled(throughput, monkeypatch):
    monkeypatch.setenv("MWJAX_CONCURRENT_SCENES", "0")
    labels = throughput.deviations(500, True, None, mwjax.PhysicsConfig(), "gpu")
    assert labels == ["concurrent_scenes=False"]


def test_the_compile_guard_counts_module_folders_not_build_records(throughput, monkeypatch, tmp_path):
    import warp

    monkeypatch.setattr(warp.config, "kernel_cache_dir", str(tmp_path))
    (tmp_path / "wp_module_a").mkdir()
    (tmp_path / "mwjax-built-0123456789abcdef0123").touch()  # a finished scene build's record
    assert throughput.warp_kernel_modules() == 1
    (tmp_path / "wp_module_b").mkdir()
    assert throughput.warp_kernel_modules() == 2


def test_an_adapter_window_of_no_steps_is_a_usage_error(throughput, monkeypatch, usage_error):
    monkeypatch.setattr(sys, "argv", ["throughput.py", "--sets", "MT10", "--adapter", "--adapter-steps", "0"])
    assert "--adapter-steps must be a positive number of steps" in usage_error(throughput.main)


def test_adapter_only_measures_no_jitted_row(throughput, monkeypatch, tmp_path):
    called = []

    def in_fresh_process(function, *args):  # what each child would measure, without the device
        called.append(function.__name__)
        rate = {"jax": 2.0, "numpy": 1.0}[args[3]]
        return {
            f"adapter_{args[3]}_env_steps_per_s": rate,
            "provenance": {"device": "dev", "commit": "c", "date": "d"},
        }

    monkeypatch.setattr(throughput, "in_fresh_process", in_fresh_process)
    out = tmp_path / "row.json"
    argv = ["throughput.py", "--sets", "MT10", "--batch", "25", "--adapter-only", "--adapter-steps", "3"]
    monkeypatch.setattr(sys, "argv", [*argv, "--out", str(out)])
    throughput.main()
    assert called == ["measure_adapter", "measure_adapter"]
    result = json.loads(out.read_text())
    assert result["results"] == []
    (row,) = result["adapter"]
    assert (row["num_envs"], row["adapter_steps"], result["device"]) == (20, 3, "dev")
    assert "numpy_share_of_jitted" not in row and "provenance" not in row


def test_adapter_only_has_no_curve_to_plot(throughput, monkeypatch, usage_error):
    monkeypatch.setattr(sys, "argv", ["throughput.py", "--sets", "MT10", "--adapter-only", "--plot"])
    assert "--adapter-only measures none" in usage_error(throughput.main)
