"""`python -m mwjax`: a fast, documented command line that refuses bad values cleanly, throughput
that never counts the first run, and the reference figures it prints."""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

from mwjax import __main__ as main_job

ROOT = Path(__file__).parents[1]


def test_every_option_has_a_help_text():
    actions = [a for a in main_job.build_parser()._actions if a.option_strings != ["-h", "--help"]]
    assert actions and all(action.help for action in actions)


def test_help_loads_neither_jax_nor_the_physics():
    code = (
        "import sys\n"
        "import mwjax.__main__ as m\n"
        "try:\n"
        "    m.parse_args(['--help'])\n"
        "except SystemExit:\n"
        "    pass\n"
        "print(sorted({k.split('.')[0] for k in sys.modules} & {'jax', 'warp', 'mujoco'}))\n"
    )
    result = subprocess.run(
        [sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, check=True
    )
    assert result.stdout.splitlines()[-1] == "[]"


def test_importing_mwjax_claims_no_device():
    # JAX takes most of a GPU's memory when its backend starts; a module-level jnp constant would
    # start it at import, in processes (a benchmark's parent, a user's torch program) that never
    # simulate, and leave the one that does without room for Warp.
    code = (
        "import mwjax.env, mwjax.tasks, mwjax.policies, mwjax.benchmarks, mwjax.evaluation\n"
        "import mwjax.wrappers.gymnasium, mwjax.rendering, mwjax.sharding, mwjax.kernels\n"
        "from jax._src import xla_bridge\n"
        "print(xla_bridge.backends_are_initialized())\n"
    )
    result = subprocess.run(
        [sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, check=True
    )
    assert result.stdout.splitlines()[-1] == "False"


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["--tasks", "MT11"], "unknown benchmark 'MT11'"),
        (["--tasks", "ML10"], "meta-learning set"),
        (["--tasks", "reach-v3,reach-v2"], "unknown task"),
        (["--envs-per-task", "0"], "must be at least 1"),
        (["--steps", "many"], "not an integer"),
    ],
)
def test_bad_values_are_usage_errors(argv, message, usage_error):
    assert message in usage_error(main_job.parse_args, argv)


def test_bad_value_from_the_shell_gives_no_traceback():
    result = subprocess.run(
        [sys.executable, "-m", "mwjax", "--tasks", "MT11"], cwd=ROOT, capture_output=True, text=True
    )
    assert result.returncode == 2
    assert "unknown benchmark 'MT11'" in result.stderr and "Traceback" not in result.stderr


def test_throughput_counts_only_the_timed_run():
    """The first run of a compiled program (Warp's kernel builds land there on a fresh machine)
    is timed apart; the rate is the second run's."""
    now = [0.0]
    durations = iter([200.0, 2.0])

    def run():
        now[0] += next(durations)

    timing = main_job.timed(run, env_steps=1000, clock=lambda: now[0])
    assert timing.first_run_s == 200.0 and timing.timed_run_s == 2.0
    assert timing.steps_per_second == 500.0


def test_reference_figures_are_the_recorded_ones():
    (path,) = ROOT.glob("benchmarks/results/**/reference-experts-seed42.json")
    recorded = json.loads(path.read_text())
    assert recorded["seed"] == main_job.REFERENCE_SEED and recorded["max_steps"] == main_job.HORIZON
    assert len(recorded["success_rate"]) == 50
    for task, rate in recorded["success_rate"].items():
        assert main_job.reference_success(task) == pytest.approx(rate, abs=1e-12), task


@pytest.mark.slow
def test_the_kernels_compile_in_processes_while_xla_compiles(tmp_path):
    """The main job with the kernel build (the GPU's path) into an empty Warp cache: the build's
    processes compile the scene modules while XLA compiles, the job waits for them before its
    first run, and its own process compiles at most MJX's own FFI module."""
    code = (
        "import mwjax.__main__ as m\n"
        "m.run_job(m.parse_args(['--tasks', 'reach-v3,push-v3', '--steps', '2']), prebuild=True)\n"
    )
    env = {**os.environ, "WARP_CACHE_PATH": str(tmp_path), "MWJAX_PROGRESS": "1"}
    result = subprocess.run(
        [sys.executable, "-c", code],
        cwd=ROOT,
        env=env,
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
        check=True,
    )
    lines = result.stdout.splitlines()

    def first(text: str) -> int:
        return next(i for i, line in enumerate(lines) if text in line)

    assert first("physics kernel modules compile in") < first("compiling the experts' rollout (XLA):")
    assert first("compiling the reset and the random-action rollout (XLA):") < first("waiting for the")
    assert first("waiting for the") < first("running the experts:") < first("throughput, random actions")
    # The CPU runs the scenes in turn; the line says how they ran.
    assert "(2 tasks, scenes in turn)" in lines[first("throughput, random actions")]
    pattern = r"Warp built (\d+) physics kernel modules? \((\d+) of them in parallel processes\)"
    total = re.search(pattern, lines[-1])
    assert total is not None, lines[-1]
    built, in_processes = int(total[1]), int(total[2])
    assert in_processes > 10 and built - in_processes <= 1, lines[-1]
