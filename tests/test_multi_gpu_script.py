"""`benchmarks/multi_gpu.py`'s planning (which device counts share a wave, JAX's memory share) and a
CPU run of its one-process-per-device mode."""

from __future__ import annotations

import importlib.util
import json
import os
import sys
from pathlib import Path

import children
import pytest

BENCHMARKS = Path(__file__).parents[1] / "benchmarks"


@pytest.fixture(scope="module")
def multi_gpu():
    sys.path.insert(0, str(BENCHMARKS))  # the script imports its sibling `common`
    try:
        spec = importlib.util.spec_from_file_location("multi_gpu", BENCHMARKS / "multi_gpu.py")
        module = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(module)
        yield module
    finally:
        sys.path.remove(str(BENCHMARKS))


def test_counts_that_fit_side_by_side_share_a_wave(multi_gpu):
    assert multi_gpu.side_by_side([1, 2, 4], gpus=8) == [[1, 2, 4]]
    assert multi_gpu.side_by_side([1, 2, 4], gpus=4) == [[1, 2], [4]]
    assert multi_gpu.side_by_side([1, 2], gpus=2) == [[1], [2]]


def test_processes_sharing_a_gpu_split_the_memory_share_they_were_given(multi_gpu, monkeypatch):
    monkeypatch.delenv("XLA_PYTHON_CLIENT_MEM_FRACTION", raising=False)
    assert float(multi_gpu.mem_fraction(1)) == pytest.approx(0.45)
    assert float(multi_gpu.mem_fraction(3)) == pytest.approx(0.15)
    # A fraction set for the whole run (as the GPU instructions advise) is split too: three
    # processes each taking 0.45 of one GPU ran out of memory.
    monkeypatch.setenv("XLA_PYTHON_CLIENT_MEM_FRACTION", "0.6")
    assert float(multi_gpu.mem_fraction(3)) == pytest.approx(0.2)


def _one_process_per_device(workdir: Path) -> tuple[list[str], dict[str, str]]:
    command = [sys.executable, str(BENCHMARKS / "multi_gpu.py"), "--set", "MT1:reach-v3", "--cpu"]
    command += ["--envs-per-task", "2", "--steps", "3", "--devices", "1", "2", "--processes"]
    return [*command, "--out", str(workdir / "multi-gpu.json")], dict(os.environ)


@pytest.mark.child.with_args(_one_process_per_device)
def test_one_process_per_device_reports_one_row_per_count(request):
    result, workdir = children.result(request.node)
    assert result.returncode == 0, result.stderr[-4000:]
    summary = json.loads((workdir / "multi-gpu.json").read_text())
    assert summary["processes"] and summary["valid"] and summary["device_counts"] == [1, 2]
    assert [r["processes"] for r in summary["results"]] == [1, 2]  # the 2-device count ran in 2
    assert [r["num_envs"] for r in summary["results"]] == [2, 4]
