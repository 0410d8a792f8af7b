"""tools/compare_runs.py on committed training results."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from tool_scripts import load_tool

from mwjax import stats

ROOT = Path(__file__).resolve().parents[1]
compare_runs = load_tool("compare_runs")

TRAIN = ROOT / "benchmarks" / "results" / "train"
V1 = TRAIN / "train-MT10-ppo-v1-5-seeds-vmapped-7461e14-NVIDIA_H200-2026-11-26.json"
V2 = TRAIN / "train-MT10-ppo-v2-5-seeds-vmapped-7461e14-NVIDIA_H200-2026-11-26.json"


def test_compares_two_recipes_by_the_setting_they_differ_in():
    table = compare_runs.compare(V1, V2, reps=50)
    assert "A: reward_version=v1 (5 seeds)" in table and "B: reward_version=v2 (5 seeds)" in table
    tasks, v1, _ = compare_runs.scores(V1)
    _, v2, _ = compare_runs.scores(V2)
    runs = json.loads(V1.read_text())["runs"]
    assert np.allclose(v1.mean(axis=1), [run["eval_success"] for run in runs])
    row = next(line for line in table.splitlines() if line.startswith(f"| {tasks[3]} |"))
    assert row == f"| {tasks[3]} | {v1[:, 3].mean():.2f} | {v2[:, 3].mean():.2f} |"
    assert f"P(B > A) = {stats.probability_of_improvement(v2, v1, reps=50).value:.3f}" in table


def test_refuses_results_over_different_tasks(tmp_path):
    data = json.loads(V1.read_text())
    for run in data["runs"]:
        run["eval_success_per_task"].pop("reach-v3")
    other = tmp_path / "other.json"
    other.write_text(json.dumps(data))
    with pytest.raises(ValueError, match="different tasks"):
        compare_runs.compare(V1, other, reps=10)
