"""The benchmark scripts' `--set`/`--sets`: an unknown set is a usage error, read before any work."""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
from pathlib import Path

import pytest

BENCHMARKS = Path(__file__).parents[1] / "benchmarks"


def test_a_known_set_comes_back_as_written_and_an_unknown_one_names_the_sets(monkeypatch):
    monkeypatch.syspath_prepend(str(BENCHMARKS))
    import common

    for text in ("MT10", "MT1:reach-v3", "reach-v3,push-v3", "ML45"):
        assert common.set_arg(text) == text
    for text, message in [("MT11", "known: MT1, MT10"), ("reach-v3,reach-v9", "unknown task 'reach-v9'")]:
        with pytest.raises(argparse.ArgumentTypeError, match=message):
            common.set_arg(text)


@pytest.mark.parametrize(
    "argv",
    [
        ["throughput.py", "--sets", "MT10", "MT11"],
        ["experts.py", "--set", "MT11"],
        ["stress_buffers.py", "--set", "MT11"],
        ["render_throughput.py", "--sets", "MT11"],
    ],
)
def test_the_scripts_refuse_an_unknown_set_with_a_usage_error(argv):
    env = {**os.environ, "JAX_PLATFORMS": "cpu"}
    run = subprocess.run([sys.executable, *argv], cwd=BENCHMARKS, env=env, capture_output=True, text=True)
    assert run.returncode == 2, run.stderr
    assert "unknown benchmark 'MT11'" in run.stderr and "Traceback" not in run.stderr
