"""Progress reporting: the status line over Warp's kernel builds and long phases (a fake clock
drives it), the hook on a real Warp module compile, and the explained CUDA warning."""

from __future__ import annotations

import uuid

import numpy as np
import warp as wp

import mwjax.physics  # noqa: F401  (installs the hook, as every env build does)
from mwjax import progress


class Clock:
    def __init__(self) -> None:
        self.now = 0.0

    def __call__(self) -> float:
        return self.now


def test_status_line_counts_builds_and_closes_the_burst(capsys):
    clock = Clock()
    status = progress._Status(clock=clock, background=False)
    first = status.compile_started()
    clock.now = 0.5
    status.tick()  # a compile shows up only once it has run for a second
    clock.now = 5.0
    status.tick()
    clock.now = 12.0
    status.compile_finished(first, built=True)
    second = status.compile_started()
    clock.now = 16.0
    status.tick()
    clock.now = 20.0
    status.compile_finished(second, built=True)  # logs (not a terminal) get a line every 10 s at most
    status.compile_finished(status.compile_started(), built=False)  # found in Warp's cache
    clock.now = 30.0
    status.tick()  # nothing built for a while: the burst is over
    lines = capsys.readouterr().err.splitlines()
    assert lines == [
        "building physics kernels: 0 done (5 s)",
        "building physics kernels: 1 done (16 s)",
        "built 2 physics kernel modules in 20 s (Warp caches them: later runs load them)",
    ]
    assert status.totals == progress.KernelBuilds(built=2, cached=1, seconds=20.0)


def test_phase_reports_its_time_and_the_builds_within_it(capsys):
    clock = Clock()
    status = progress._Status(clock=clock, background=False)
    with status.phase_block("compiling the step (XLA)"):
        clock.now = 1.0
        token = status.compile_started()
        clock.now = 4.0
        status.compile_finished(token, built=True)
        clock.now = 10.0
    lines = capsys.readouterr().err.splitlines()
    assert lines[0] == "compiling the step (XLA) ..."
    assert (
        lines[-1] == "compiling the step (XLA): 10.0 s (of which Warp building 1 physics kernel module: 3 s)"
    )


def test_warp_module_compiles_are_counted(tmp_path, monkeypatch, capsys):
    """A kernel Warp has never seen (new module, empty cache) is compiled through the hook."""
    monkeypatch.setattr(wp.config, "kernel_cache_dir", str(tmp_path))
    scale = float(uuid.uuid4().int % 1000)

    @wp.kernel(module="unique")
    def scaled(values: wp.array(dtype=float)):
        i = wp.tid()
        values[i] = values[i] * scale

    values = wp.array(np.ones(3, np.float32), device="cpu")
    before = progress.kernel_builds()
    with progress.phase("a fresh kernel"):
        wp.launch(scaled, dim=3, inputs=[values], device="cpu")
    after = progress.kernel_builds()
    assert after.built == before.built + 1
    assert after.seconds > before.seconds
    np.testing.assert_allclose(values.numpy(), scale)
    assert "a fresh kernel: " in capsys.readouterr().err
    assert wp.config.log_level == wp.LOG_WARNING  # Warp's per-module info lines are off


def test_cuda_warning_is_explained_and_other_lines_kept(capsys):
    progress._explain_cuda_warning(
        "Warp CUDA warning: Could not find or load the NVIDIA CUDA driver. GPU execution will not be"
        " available.\nsomething else\n"
    )
    err = capsys.readouterr().err
    assert "Could not find" not in err
    assert err.splitlines() == [
        "mwjax: no NVIDIA CUDA driver found, so Warp runs the physics on the CPU "
        "(slow: the CPU path is for tests and debugging)",
        "something else",
    ]


def test_progress_can_be_turned_off(monkeypatch, capsys):
    monkeypatch.setenv("MWJAX_PROGRESS", "0")
    status = progress._Status(clock=Clock(), background=False)
    with status.phase_block("quiet"):
        pass
    assert capsys.readouterr().err == ""
