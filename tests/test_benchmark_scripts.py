"""The benchmark scripts' `--set`/`--sets`: an unknown set is a usage error, read before any work."""

from __future__ import annotations

import argparse
import importlib.util
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
        ["profile_adapter.py", "--set", "MT11"],
    ],
)
def test_the_scripts_refuse_an_unknown_set_with_a_usage_error(argv, monkeypatch, usage_error):
    """Each script's `main` as its command line runs it, in this process (a child process per
    script spent most of half a minute importing JAX beside the rest of the suite)."""
    assert "unknown benchmark 'MT11'" in usage_error(_script_main(argv, monkeypatch))


def test_profile_adapter_refuses_a_scan_that_does_not_divide_the_steps(monkeypatch, usage_error):
    main = _script_main(["profile_adapter.py", "--steps", "100", "--scan-steps", "3"], monkeypatch)
    assert "--scan-steps must be 0 or divide --steps" in usage_error(main)


def test_profile_adapter_refuses_an_unknown_graph_mode(monkeypatch, usage_error):
    main = _script_main(["profile_adapter.py", "--graph-mode", "warp_stagd"], monkeypatch)
    assert "unknown graph_mode 'warp_stagd'" in usage_error(main)


def test_profile_adapter_in_warps_own_graph_mode_needs_the_scan_level(monkeypatch, usage_error):
    main = _script_main(["profile_adapter.py", "--graph-mode", "warp", "--scan-steps", "0"], monkeypatch)
    assert "--graph-mode warp times only the scan level" in usage_error(main)


def _script_main(argv: list[str], monkeypatch):
    """The `main` of the script `argv[0]` of benchmarks/, loaded in this process, with `argv` as
    its command line."""
    monkeypatch.syspath_prepend(str(BENCHMARKS))
    monkeypatch.setattr(sys, "argv", argv)
    spec = importlib.util.spec_from_file_location(f"script_{Path(argv[0]).stem}", BENCHMARKS / argv[0])
    script = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(script)
    return script.main
