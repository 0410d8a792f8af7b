"""One process per GPU: a sharded task set whose devices are driven by separate processes.

    python -m mwjax.distributed --processes 4 examples/train_mt_ppo.py --devices all
    python -m mwjax.distributed --processes 2 --cpu my_script.py    # 2 CPU processes (tests)

starts `--processes` copies of the script, process i on GPU i alone, joined into one JAX
process group (`jax.distributed`). The script calls `mwjax.distributed.initialize()` before
anything else touches JAX; then `jax.devices()` lists every process's device and
`mwjax.make(..., devices=jax.devices())` shards the batch over all of them, exactly as one
process does over its local GPUs (same rows, same results). Each process steps its own share.

Why: in one process, every device's Warp calls are launched from the host by that one Python
process, under the GIL and Warp's lock, one device after another. That costs scaling (each of
4 H200s stepped MT50 15% slower than one alone), and a data-parallel update, whose NCCL
all-reduces wait for every device's Warp calls, hangs on 4 GPUs
(`benchmarks/results/train/ppo-chunk-probe-MT10-4-gpus-...`). One process per GPU has none of
that: each process launches its own GPU's work.

In such a run, arrays that span the devices are global: read a replicated one (a metric after
`pmean`) as usual, gather a sharded one with `jax.experimental.multihost_utils.process_allgather`.
`is_main()` says which process should print and write files. Without the launcher,
`initialize()` does nothing and a script runs as one process.

`run_independent(commands, logs, parallel)` is the other use of several GPUs: separate runs
(seeds of one experiment, say), each a process of its own on a GPU of its own, not a group.
"""

from __future__ import annotations

import argparse
import atexit
import contextlib
import os
import signal
import socket
import subprocess
import sys
import threading
import time
from collections.abc import Iterator, Sequence
from pathlib import Path
from typing import Any

PROCESS_ID = "MWJAX_PROCESS_ID"
NUM_PROCESSES = "MWJAX_NUM_PROCESSES"
COORDINATOR = "MWJAX_COORDINATOR"


def initialize() -> bool:
    """Join the process group `python -m mwjax.distributed` set up for this process (from its
    environment variables); True if it did, False (nothing done) in a process started otherwise.
    Call it before anything else uses JAX."""
    if not launched():
        return False
    import jax

    if os.environ.get("JAX_PLATFORMS") == "cpu":
        jax.config.update("jax_cpu_collectives_implementation", "gloo")
    jax.distributed.initialize(
        coordinator_address=os.environ[COORDINATOR],
        num_processes=int(os.environ[NUM_PROCESSES]),
        process_id=int(os.environ[PROCESS_ID]),
    )
    # Leave together: without it, process 0 (the coordinator) may exit first, and the others then
    # log a screenful of failed gRPC calls on their way out.
    atexit.register(jax.distributed.shutdown)
    return True


def launched() -> bool:
    """True in a process that `python -m mwjax.distributed` started."""
    return PROCESS_ID in os.environ


def is_main() -> bool:
    """True in the process that should print and write results (process 0, or the only one)."""
    return int(os.environ.get(PROCESS_ID, "0")) == 0


def visible_gpus() -> list[str]:
    """The GPUs this process may use (CUDA_VISIBLE_DEVICES, else all that nvidia-smi lists),
    found without starting JAX."""
    visible = os.environ.get("CUDA_VISIBLE_DEVICES")
    if visible is not None:
        return [v.strip() for v in visible.split(",") if v.strip()]
    try:
        out = subprocess.run(["nvidia-smi", "-L"], capture_output=True, text=True, check=True).stdout
    except (OSError, subprocess.CalledProcessError):
        return []
    return [str(i) for i, line in enumerate(out.splitlines()) if line.startswith("GPU ")]


def process_env(process: int, processes: int, coordinator: str, gpus: Sequence[str] | None) -> dict:
    """Process `process`'s environment: its GPU alone (`gpus[process]`), or with `gpus=None` one
    host CPU device."""
    env = dict(os.environ)
    env.update({PROCESS_ID: str(process), NUM_PROCESSES: str(processes), COORDINATOR: coordinator})
    if gpus is None:
        env["JAX_PLATFORMS"] = "cpu"
        flags = [f for f in env.get("XLA_FLAGS", "").split() if "host_platform_device_count" not in f]
        env["XLA_FLAGS"] = " ".join(flags)
    else:
        env["CUDA_VISIBLE_DEVICES"] = gpus[process]
    if process:  # process 0 shows the progress; the others would repeat it
        env["MWJAX_PROGRESS"] = "0"
    return env


def launch(command: Sequence[str], processes: int, cpu: bool = False) -> int:
    """Run `command` (a Python script and its arguments) as `processes` processes, process i on
    GPU i (`cpu`: on one host device each). Process 0's output is the run's; the others keep
    only their errors. If one process fails, the others are stopped (they would wait forever
    in a collective). Returns the first non-zero exit code, else 0."""
    if processes < 1:
        raise ValueError(f"processes must be at least 1, got {processes}")
    gpus = None if cpu else visible_gpus()
    if gpus is not None and len(gpus) < processes:
        raise ValueError(
            f"{processes} processes need {processes} GPUs, {len(gpus)} visible"
            + ("" if gpus else " (--cpu runs on host devices)")
        )
    with socket.socket() as probe:  # a free port for the coordinator
        probe.bind(("localhost", 0))
        coordinator = f"localhost:{probe.getsockname()[1]}"
    procs = [
        subprocess.Popen(
            [sys.executable, *command],
            env=process_env(i, processes, coordinator, gpus),
            stdout=None if i == 0 else subprocess.DEVNULL,
        )
        for i in range(processes)
    ]
    code = 0
    try:
        while any(p.poll() is None for p in procs):
            failed = next((p for p in procs if p.poll()), None)
            if failed is not None:
                code = failed.returncode
                print(
                    f"mwjax.distributed: process {procs.index(failed)} exited with {code}; "
                    "stopping the others",
                    file=sys.stderr,
                    flush=True,
                )
                break
            time.sleep(0.2)
    finally:
        stop(procs)
    return code or next((p.returncode for p in procs if p.returncode), 0)


def stop(procs: Sequence[subprocess.Popen]) -> list[int]:
    """Terminate the processes still running (SIGTERM, then SIGKILL after 30 s); their exit codes."""
    for p in procs:
        if p.poll() is None:
            p.send_signal(signal.SIGTERM)
    for p in procs:
        try:
            p.wait(timeout=30)
        except subprocess.TimeoutExpired:
            p.kill()
            p.wait()
    return [p.returncode for p in procs]


def run_independent(
    commands: Sequence[Sequence[str]], logs: Sequence[Path], parallel: int, cpu: bool = False
) -> list[int]:
    """Run each command (a Python script and its arguments) as a process of its own, not a
    process group: at most `parallel` at a time, each on a GPU no other one uses (`cpu`: on the
    host), its output to its log. Every 30 s it prints each running process's last line. Returns
    the exit codes, in the commands' order. For independent runs, e.g. seeds of one experiment.

    Ctrl-C or SIGTERM (a job's time limit, `timeout`) stops it in order: the running processes
    are terminated and it returns, their codes and those of runs never started negative, so that
    the caller can still keep what the finished runs produced."""
    gpus = None if cpu else visible_gpus()
    if gpus is not None and len(gpus) < parallel:
        raise ValueError(f"{parallel} processes at a time need {parallel} GPUs, {len(gpus)} visible")
    pending = list(range(len(commands)))
    running: dict[int, tuple[int, subprocess.Popen]] = {}  # slot -> (command, process)
    codes = [0] * len(commands)
    with sigterm_as_interrupt():
        try:
            _schedule(commands, logs, parallel, gpus, pending, running, codes)
        except KeyboardInterrupt:
            stopped = list(running.values())
            for (i, _), code in zip(stopped, stop([process for _, process in stopped]), strict=True):
                codes[i] = code
            for i in pending:
                codes[i] = -int(signal.SIGTERM)
            numbers = sorted([i + 1 for i, _ in stopped] + [i + 1 for i in pending])
            print(f"interrupted: runs {numbers} stopped or never started", flush=True)
    return codes


def _schedule(
    commands: Sequence[Sequence[str]],
    logs: Sequence[Path],
    parallel: int,
    gpus: list[str] | None,
    pending: list[int],
    running: dict[int, tuple[int, subprocess.Popen]],
    codes: list[int],
) -> None:
    """`run_independent`'s loop; `pending`, `running` and `codes` are updated in place."""
    shown = time.perf_counter()
    while pending or running:
        for slot in range(parallel):
            if slot not in running and pending:
                i = pending.pop(0)
                env = dict(os.environ)
                if gpus is not None:
                    env["CUDA_VISIBLE_DEVICES"] = gpus[slot]
                with open(logs[i], "w") as log:
                    process = subprocess.Popen(
                        [sys.executable, *commands[i]], env=env, stdout=log, stderr=subprocess.STDOUT
                    )
                running[slot] = (i, process)
                where = "the host" if gpus is None else f"GPU {gpus[slot]}"
                print(f"run {i + 1}/{len(commands)} started on {where} (log: {logs[i]})", flush=True)
        for slot, (i, process) in list(running.items()):
            if process.poll() is not None:
                codes[i] = process.returncode
                del running[slot]
                state = "done" if not codes[i] else f"FAILED (exit {codes[i]})"
                print(f"run {i + 1}/{len(commands)} {state}: {_last_line(logs[i])}", flush=True)
        if running and time.perf_counter() - shown > 30:
            shown = time.perf_counter()
            for i, _ in running.values():
                print(f"  run {i + 1}: {_last_line(logs[i])}", flush=True)
        time.sleep(0.5)


@contextlib.contextmanager
def sigterm_as_interrupt() -> Iterator[None]:
    """SIGTERM raises KeyboardInterrupt inside the block (in the main thread; elsewhere no change)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def interrupt(signum: int, frame: Any) -> None:
        raise KeyboardInterrupt

    previous = signal.signal(signal.SIGTERM, interrupt)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)


def _last_line(path: Path) -> str:
    lines = [line for line in Path(path).read_text(errors="replace").splitlines() if line.strip()]
    return lines[-1].strip()[:160] if lines else "(no output yet)"


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog="python -m mwjax.distributed",
        description="Run a script as one process per GPU, joined into one JAX process group.",
    )
    parser.add_argument("--processes", type=int, required=True, help="processes (GPUs) to use")
    parser.add_argument("--cpu", action="store_true", help="one host CPU device per process")
    parser.add_argument("script", help="the Python script to run")
    parser.add_argument("args", nargs=argparse.REMAINDER, help="its arguments")
    args = parser.parse_args(argv)
    try:
        return launch([args.script, *args.args], args.processes, cpu=args.cpu)
    except ValueError as error:
        parser.error(str(error))
        return 2


if __name__ == "__main__":
    sys.exit(main())
