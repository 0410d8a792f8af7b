"""The throughput benchmark's protocol: a row where any env dropped something gets no figure."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

SCRIPT = Path(__file__).parents[1] / "benchmarks" / "throughput.py"


def test_a_row_with_overflow_is_refused_and_a_shorter_rollout_is_labelled(tmp_path):
    out = tmp_path / "row.json"
    command = [sys.executable, str(SCRIPT), "--sets", "reach-v3", "--batch", "2", "--steps", "3"]
    run = subprocess.run([*command, "--constraints", "4", "--out", str(out)], capture_output=True, text=True)
    assert run.returncode != 0, run.stdout + run.stderr
    assert "refused" in run.stderr
    (row,) = json.loads(out.read_text())["results"]
    assert row["env_steps_per_s"] is None
    assert row["overflow_envs"] == 2
    assert row["protocol"] == "labelled: 3-step rollouts; constraints_per_env=4"
    for key in ("device", "commit", "date", "command"):
        assert json.loads(out.read_text())[key]
