"""Child processes that tests start (a fresh JAX with other flags or switches), run beside the rest
of the suite.

A test marked `@pytest.mark.child(command)` gets its child's result from `result(request.node)`.
`command(workdir)` returns the child's argv and environment; `workdir` is an empty directory the
child may write to. Tests marked with the same command share one child (one run, one workdir):
that is how two test modules use one process's compiled programs. On the CPU backend the
conftest starts every collected test's child as soon as collection ends, so that it runs on a
second core while the parent runs the tests before it (a child is single-threaded for most of its
time: tracing, Warp's kernel launches); the test then only waits for it. On a GPU the child
starts when its test runs, so that two processes never hold the GPU's memory at once.
A child of a child starts no children early.
"""

from __future__ import annotations

import dataclasses
import os
import subprocess
import tempfile
from collections.abc import Callable
from pathlib import Path

import pytest

ROOT = Path(__file__).parents[1]
# Set in every child, so that a child's own pytest starts no children early.
CHILD = "MWJAX_TEST_CHILD"

Command = Callable[[Path], tuple[list[str], dict[str, str]]]


@dataclasses.dataclass
class _Running:
    process: subprocess.Popen
    workdir: tempfile.TemporaryDirectory
    stdout: object
    stderr: object


_running: dict[Command, _Running] = {}


def is_child() -> bool:
    return bool(os.environ.get(CHILD))


def _command(item: pytest.Item) -> Command:
    return item.get_closest_marker("child").args[0]


def start(item: pytest.Item) -> None:
    """Start `item`'s child (its `child` mark) unless it runs already."""
    command = _command(item)
    if command in _running:
        return
    workdir = tempfile.TemporaryDirectory(prefix="mwjax-child-")
    argv, env = command(Path(workdir.name))
    # Files, not pipes: nobody reads a pipe while the child runs, and a full one would stall it.
    stdout, stderr = (open(Path(workdir.name) / name, "w+") for name in ("stdout", "stderr"))
    env = {**env, CHILD: "1"}
    process = subprocess.Popen(argv, env=env, cwd=ROOT, stdout=stdout, stderr=stderr, text=True)
    _running[command] = _Running(process, workdir, stdout, stderr)


def result(item: pytest.Item) -> tuple[subprocess.CompletedProcess, Path]:
    """Wait for `item`'s child (starting it if it has not started) and return its result and
    its work directory (kept until the session ends)."""
    start(item)
    running = _running[_command(item)]
    returncode = running.process.wait()
    out = []
    for file in (running.stdout, running.stderr):
        file.seek(0)
        out.append(file.read())
    return subprocess.CompletedProcess(running.process.args, returncode, *out), Path(running.workdir.name)


def stop_all() -> None:
    """End the children still running (their tests did not run) and remove their directories."""
    for running in _running.values():
        if running.process.poll() is None:
            running.process.kill()
            running.process.wait()
        running.stdout.close()
        running.stderr.close()
        running.workdir.cleanup()
    _running.clear()
