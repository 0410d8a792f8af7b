"""Progress on stderr for the long work of a first run, so that it is not silence.

- Warp compiles a kernel module the first time a physics model of a new structure runs, seconds to
  tens of seconds each, and caches it (`~/.cache/warp`, or `WARP_CACHE_PATH`). `install()`, which
  `mwjax.physics` calls, hooks Warp's module compile: a status line counts the modules while they
  build ("building physics kernels: 12 done (34 s)") and a last line says how many it built.
  It also quiets Warp's per-module and start-up info lines and explains, in one line, Warp's
  "could not find the CUDA driver" warning on machines without a GPU.
- `phase(label)` shows a label and a running clock over a long block (XLA compiling, a rollout)
  and, at its end, the time it took and the kernel modules Warp built within it.

On a terminal the status line is rewritten in place; elsewhere (logs, CI) a line is printed at
most every `LOG_INTERVAL_S` seconds. `MWJAX_PROGRESS=0` turns all of it off.
"""

from __future__ import annotations

import contextlib
import dataclasses
import functools
import os
import sys
import tempfile
import threading
import time
from collections.abc import Callable, Iterator
from typing import Any

LOG_INTERVAL_S = 10.0
# A module compile running longer than this shows up before it ends.
_SHOW_AFTER_S = 1.0
# A burst of kernel builds counts as over once none has run for this long.
_BURST_IDLE_S = 2.0
_TICK_S = 0.5
_CUDA_WARNING = "Could not find or load the NVIDIA CUDA driver"


@dataclasses.dataclass
class KernelBuilds:
    """Warp kernel modules this process compiled (`built`, in `seconds` of wall time summed over
    the compiles) or found in Warp's cache (`cached`)."""

    built: int = 0
    cached: int = 0
    seconds: float = 0.0


@dataclasses.dataclass
class _Burst:
    """Consecutive module builds, reported as one status line."""

    start: float
    built: int = 0
    last_end: float = 0.0


class _Status:
    """The process's one status line and the counters behind it (all under one lock)."""

    def __init__(self, clock: Callable[[], float] = time.perf_counter, background: bool = True) -> None:
        """`background=False` leaves the refreshing to explicit `tick()` calls."""
        self.clock = clock
        self.background = background
        self.lock = threading.RLock()
        self.totals = KernelBuilds()
        self.burst: _Burst | None = None
        # Module compiles under way (Warp may run several at once), by token: since when.
        self.compiling: dict[int, float] = {}
        self.tokens = 0
        self.phase: tuple[str, float] | None = None
        self.line_open = False  # a terminal line written without its newline yet
        self.last_logged = -float("inf")
        self.ticker: threading.Thread | None = None

    @property
    def enabled(self) -> bool:
        return os.environ.get("MWJAX_PROGRESS", "1") != "0"

    # -- output --------------------------------------------------------------------------------

    def _write(self, text: str, final: bool) -> None:
        if not self.enabled:
            return
        stream = sys.stderr
        if stream.isatty():
            stream.write(f"\r{text}\x1b[K" + ("\n" if final else ""))
            self.line_open = not final
        else:
            now = self.clock()
            if not final and now - self.last_logged < LOG_INTERVAL_S:
                return
            self.last_logged = now
            stream.write(text + "\n")
        stream.flush()

    def print_line(self, text: str) -> None:
        """A line of its own (on a terminal, in place of the status line, redrawn at the next tick)."""
        with self.lock:
            stream = sys.stderr
            stream.write(("\r" + text + "\x1b[K\n") if stream.isatty() and self.line_open else text + "\n")
            stream.flush()
            self.line_open = False

    def _render(self) -> str | None:
        now = self.clock()
        parts = []
        if self.phase is not None:
            label, start = self.phase
            parts.append(f"{label} ({now - start:.0f} s)")
        if self.burst is not None:
            seconds = now - self.burst.start
            parts.append(f"building physics kernels: {self.burst.built} done ({seconds:.0f} s)")
        return " · ".join(parts) or None

    def tick(self) -> None:
        """Refresh the status line, and close a burst of builds that has gone quiet."""
        with self.lock:
            now = self.clock()
            first = min(self.compiling.values(), default=None)
            if first is not None and self.burst is None and now - first >= _SHOW_AFTER_S:
                self.burst = _Burst(start=first, last_end=first)
            if self.burst is not None and not self.compiling and now - self.burst.last_end >= _BURST_IDLE_S:
                self._end_burst()
            text = self._render()
            if text is not None:
                self._write(text, final=False)

    def _end_burst(self) -> None:
        assert self.burst is not None
        burst, self.burst = self.burst, None
        if burst.built:
            seconds = burst.last_end - burst.start
            self._write(
                f"built {modules(burst.built)} in {seconds:.0f} s (Warp caches them: later runs load them)",
                final=True,
            )

    # -- events --------------------------------------------------------------------------------

    def compile_started(self) -> int:
        with self.lock:
            self.tokens += 1
            self.compiling[self.tokens] = self.clock()
            token = self.tokens
        self._ensure_ticker()
        return token

    def compile_finished(self, token: int, built: bool) -> None:
        with self.lock:
            start = self.compiling.pop(token)
            now = self.clock()
            if not built:
                self.totals.cached += 1
                return
            self.totals.built += 1
            self.totals.seconds += now - start
            if self.burst is None:
                self.burst = _Burst(start=start, last_end=start)
            self.burst.built += 1
            self.burst.last_end = now
            text = self._render()
            assert text is not None
            self._write(text, final=False)

    @contextlib.contextmanager
    def phase_block(self, label: str) -> Iterator[None]:
        with self.lock:
            before = dataclasses.replace(self.totals)
            self.phase = (label, self.clock())
            self._write(f"{label} ...", final=not sys.stderr.isatty())
        self._ensure_ticker()
        try:
            yield
        finally:
            with self.lock:
                _, start = self.phase
                self.phase = None
                if self.burst is not None:
                    self._end_burst()
                seconds = self.clock() - start
                built = self.totals.built - before.built
                seconds_built = self.totals.seconds - before.seconds
                note = f" (of which Warp building {modules(built)}: {seconds_built:.0f} s)" if built else ""
                self._write(f"{label}: {seconds:.1f} s{note}", final=True)

    def _ensure_ticker(self) -> None:
        with self.lock:
            if not self.background or (self.ticker is not None and self.ticker.is_alive()):
                return
            # Warp may load a module from an XLA callback while the interpreter shuts down (a
            # program still running at exit), when no thread can start.
            if sys.is_finalizing():
                return
            self.ticker = threading.Thread(target=self._run_ticker, name="mwjax-progress", daemon=True)
            self.ticker.start()

    def _run_ticker(self) -> None:
        while True:
            time.sleep(_TICK_S)
            self.tick()
            with self.lock:
                if self.phase is None and self.burst is None and not self.compiling:
                    return


_STATUS = _Status()
_installed = False


def modules(count: int) -> str:
    return f"{count} physics kernel module" + ("" if count == 1 else "s")


def kernel_builds() -> KernelBuilds:
    """Warp kernel modules compiled and loaded from the cache so far in this process."""
    with _STATUS.lock:
        return dataclasses.replace(_STATUS.totals)


def phase(label: str) -> contextlib.AbstractContextManager[None]:
    """`with phase("compiling the step (XLA)"):` shows the label and a running clock while the
    block runs, then its time and the Warp kernel modules built within it."""
    return _STATUS.phase_block(label)


def note(text: str) -> None:
    """A line of its own on stderr (none with `MWJAX_PROGRESS=0`)."""
    if _STATUS.enabled:
        _STATUS.print_line(text)


def install() -> None:
    """Hook Warp's module compile for the status line, quiet Warp's info lines and initialize
    Warp with its CUDA-driver warning explained. Idempotent."""
    global _installed
    if _installed:
        return
    _installed = True
    import warp
    from warp._src import context

    # Warp prints a start-up banner and one line per module load at LOG_INFO, its default; the
    # status line replaces them. A level the user chose (anything else) is left alone.
    if warp.config.log_level == warp.LOG_INFO:
        warp.config.log_level = warp.LOG_WARNING
    compile_module = context.Module._compile

    @functools.wraps(compile_module)
    def counted(module: Any, *args: Any, **kwargs: Any) -> bool:
        # `Module._compile` runs once per module load, and says whether it compiled or found
        # the module in Warp's cache (`Module.load`, by contrast, runs at every launch).
        token = _STATUS.compile_started()
        built = False
        try:
            built = compile_module(module, *args, **kwargs)
        finally:
            _STATUS.compile_finished(token, bool(built))
        return built

    context.Module._compile = counted
    _explain_cuda_warning(_native_stderr_of(warp.init))


def _native_stderr_of(function: Callable[[], Any]) -> str:
    """What `function` writes to file descriptor 2 (Warp's native code prints there directly)."""
    sys.stderr.flush()
    saved = os.dup(2)
    with tempfile.TemporaryFile() as captured:
        os.dup2(captured.fileno(), 2)
        try:
            function()
        finally:
            os.dup2(saved, 2)
            os.close(saved)
        captured.seek(0)
        return captured.read().decode(errors="replace")


def _explain_cuda_warning(text: str) -> None:
    for line in text.splitlines():
        if _CUDA_WARNING in line:
            line = (
                "mwjax: no NVIDIA CUDA driver found, so Warp runs the physics on the CPU "
                "(slow: the CPU path is for tests and debugging)"
            )
        _STATUS.print_line(line)
