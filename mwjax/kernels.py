"""Warp's physics kernels for a task set, built before the first step, in parallel processes.

Warp compiles a kernel module the first time a model of a new structure launches it, and MJWarp
specializes its modules per scene (degrees of freedom, geom-type pairs, collider settings), so a
fresh machine's first MT50 step compiles tens of modules one after another, tens of seconds some
of them. `build(tasks)` compiles them side by side instead: a dry run of each scene's MJWarp step
(one world, no JAX, no kernel launched) lists the modules it would load, and a pool of processes
compiles each distinct module once into Warp's kernel cache (`~/.cache/warp`, or
`WARP_CACHE_PATH`), where the env's first step then finds them. The scenes are prepared exactly as
`mwjax.make` prepares them (same mocap bodies, same physics settings, mwjax's Warp patches
installed), which is what makes the cached modules the ones the env asks for.

    python -m mwjax.kernels MT50 --report     # --report: each module's start and compile time

`start_build(tasks)` returns once the processes compile, so that the caller can compile its XLA
programs meanwhile (which launch no physics kernel) and wait (`PendingBuild.wait()`) before the
first step. A completed build is recorded in Warp's cache, per scene, and a later build of the same
scenes and settings returns at once (`--force` builds anyway). On a GPU, an env whose scenes are
not recorded there builds them so before its physics is made (`prebuild`), in a child process.
"""

from __future__ import annotations

import argparse
import concurrent.futures
import contextlib
import dataclasses
import fcntl
import functools
import hashlib
import inspect
import json
import multiprocessing
import os
import subprocess
import sys
import threading
import time
import warnings
from collections.abc import Callable, Iterator, Sequence
from pathlib import Path
from typing import Any

import mujoco
import mujoco.mjx.third_party.mujoco_warp as mjwarp
import warp

from mwjax import benchmarks, caches, determinism, placement, progress
from mwjax.models import constraint_rows
from mwjax.physics import PhysicsConfig, local_device, warp_model
from mwjax.tasks import get_task

Scene = tuple[str, tuple[str, ...]]


def scenes(tasks: str | Sequence[str] | benchmarks.Benchmark) -> list[Scene]:
    """The (scene, mocap bodies) pairs that `mwjax.make` builds physics for, over every split of
    the set (a meta-learning set's train and test envs group their tasks separately)."""
    bench = benchmarks.benchmark(tasks)
    out: dict[Scene, None] = {}
    for split in ("train", "test") if bench.test else ("train",):
        groups = placement.scene_groups([get_task(name) for name in bench.tasks(split)])
        out.update({(members[0].scene, placement.mocap_bodies(members)): None for members in groups})
    return list(out)


@dataclasses.dataclass(frozen=True)
class ModuleTime:
    """Where one module's share of a build went, in a worker process. `started_s`: from the
    pool's start to the task's (waiting for a free worker, the worker's start and imports);
    `setup_s`: the worker's dry run of the scene (its first task of that scene only);
    `compile_s`: Warp's load of the module (compiling it unless another worker just cached it)."""

    identifier: str
    scene: str
    built: int
    started_s: float
    setup_s: float
    compile_s: float

    @property
    def finished_s(self) -> float:
        """From the pool's start to the module's compile's end."""
        return self.started_s + self.setup_s + self.compile_s


@dataclasses.dataclass(frozen=True)
class Build:
    """What `build` did: `built` modules compiled in `seconds`, of which `dry_run_s` listing them;
    `modules` the per-module times (empty when Warp's cache recorded the build as done)."""

    built: int
    seconds: float
    dry_run_s: float = 0.0
    workers: int = 0
    modules: tuple[ModuleTime, ...] = ()

    def summary(self) -> str:
        """One line: what was built and where the time went."""
        line = f"{self.built} kernel modules built in {self.seconds:.0f} s"
        if not self.modules:
            return line
        slowest = max(self.modules, key=lambda m: m.compile_s)
        last = max(self.modules, key=lambda m: m.finished_s)
        return (
            f"{line}: dry run {self.dry_run_s:.1f} s, then {len(self.modules)} modules in "
            f"{self.workers} processes; slowest compile {slowest.compile_s:.1f} s "
            f"({_short(slowest.identifier)}); "
            f"last to finish {_short(last.identifier)}, started at {last.started_s:.1f} s"
        )

    def report(self) -> str:
        """A line per module, the last to finish first."""
        rows = sorted(self.modules, key=lambda m: -m.finished_s)
        lines = ["started_s  setup_s  compile_s  module (scene)"]
        lines += [
            f"{m.started_s:9.1f}  {m.setup_s:7.1f}  {m.compile_s:9.1f}  {_short(m.identifier)} ({m.scene})"
            for m in rows
        ]
        return "\n".join(lines)


def _short(identifier: str) -> str:
    """A module identifier without MJWarp's package path."""
    return identifier.replace("mujoco.mjx.third_party.mujoco_warp._src.", "")


def build(
    tasks: str | Sequence[str] | benchmarks.Benchmark,
    config: PhysicsConfig | None = None,
    workers: int | None = None,
    force: bool = False,
) -> Build:
    """Compile the Warp kernel modules of every scene of `tasks` into Warp's cache, `workers`
    processes at a time (default: one per CPU core, at most `MAX_DEFAULT_WORKERS`).

    A build that completed leaves a record per scene in Warp's cache (`scene_records`); while they
    are there, a later build of the same scenes and settings returns at once instead of starting
    processes that would only load the cached modules (~10 s for MT10's eight scenes). `force`
    builds anyway."""
    return start_build(tasks, config, workers, force).wait()


def start_build(
    tasks: str | Sequence[str] | benchmarks.Benchmark,
    config: PhysicsConfig | None = None,
    workers: int | None = None,
    force: bool = False,
) -> PendingBuild:
    """`build`, returning once its processes compile: the dry run here, then each module a task
    of the pool, whose workers run on while this process does other work that launches no
    physics kernel (e.g. XLA compiling programs that step the scenes). `result()` waits."""
    return start_scene_build(scenes(tasks), config, workers, force)


def start_scene_build(
    todo: Sequence[Scene],
    config: PhysicsConfig | None = None,
    workers: int | None = None,
    force: bool = False,
) -> PendingBuild:
    """`start_build` for the (scene, mocap bodies) pairs `todo`."""
    config = config or PhysicsConfig()
    start = time.perf_counter()
    records = scene_records(todo, config)
    if records is not None and all(record.exists() for record in records) and not force:
        with progress.phase(f"physics kernels for {len(todo)} scenes: already in Warp's cache"):
            return PendingBuild(start)
    workers = max(1, workers or min(os.cpu_count() or 1, MAX_DEFAULT_WORKERS))
    pool = _pool(workers)
    try:
        pool_start = time.time()  # wall clock: comparable with the workers' clocks on this host
        for _ in range(workers):  # the workers start (seconds of imports each) during the dry run
            pool.submit(_start_worker)
        with progress.phase(f"listing the physics kernel modules of {len(todo)} scenes"):
            tasks_by_module = _distinct_modules(todo, config)
        order = sorted(tasks_by_module.items(), key=lambda task: _slow_first(task[0]))
        futures = {
            pool.submit(_compile_module, scene, bodies, config, identifier): (identifier, scene)
            for identifier, (scene, bodies) in order
        }
    except BaseException:
        pool.shutdown(cancel_futures=True)
        raise
    _under_way.update(records or ())
    return PendingBuild(start, pool, futures, workers, pool_start, time.time() - pool_start, records or ())


@dataclasses.dataclass
class PendingBuild:
    """A build under way in worker processes (`start_build`): `futures` maps each module's task
    to (module, scene). `result()` waits for them, records the build in Warp's cache and shuts the
    pool down; without a pool the build was already recorded as done."""

    start: float
    pool: concurrent.futures.Executor | None = None
    futures: dict[concurrent.futures.Future, tuple[str, str]] = dataclasses.field(default_factory=dict)
    workers: int = 0
    pool_start: float = 0.0
    dry_run_s: float = 0.0
    records: Sequence[Path] = ()
    _result: Build | None = None

    def __post_init__(self) -> None:
        if self.pool is None:
            self._result = Build(0, time.perf_counter() - self.start)

    @property
    def modules(self) -> int:
        """The distinct modules the build compiles."""
        return len(self.futures)

    @property
    def done(self) -> bool:
        return self._result is not None

    def wait(self, label: str | None = None) -> Build:
        """`result()`, with a status line (`label`, or what is building) while the modules compile."""
        if self.done:
            return self.result()
        label = label or f"building {self.modules} physics kernel modules ({self.workers} processes)"
        with progress.phase(label):
            return self.result()

    def result(self) -> Build:
        if self._result is not None:
            return self._result
        assert self.pool is not None
        modules = []
        try:
            for future in concurrent.futures.as_completed(self.futures):
                built, started, setup_s, compile_s = future.result()
                started_s = started - self.pool_start
                modules.append(ModuleTime(*self.futures[future], built, started_s, setup_s, compile_s))
        except BaseException:
            _under_way.difference_update(self.records)
            raise
        finally:
            self.pool.shutdown(cancel_futures=True)
        for record in self.records:
            record.parent.mkdir(parents=True, exist_ok=True)
            record.touch()
        built = sum(m.built for m in modules)
        self._result = Build(
            built, time.perf_counter() - self.start, self.dry_run_s, self.workers, tuple(modules)
        )
        return self._result


# More processes do not shorten a build: its end is set by the longest module's compile (a convex
# collider's, ~25 s on a GPU), and a set's modules add up to less than 16 times that (MT50's 74:
# ~325 s of compile, `--report` shows each). Each process costs seconds of imports and a device
# context.
MAX_DEFAULT_WORKERS = 16


def scene_records(todo: Sequence[Scene], config: PhysicsConfig) -> list[Path] | None:
    """The files in Warp's kernel cache that record a completed build of each scene of `todo`
    (None without a cache folder). A name hashes all that selects the scene's modules: the scene
    and its mocap bodies, the physics settings, mwjax's sources and scene files (its Warp patches
    and assets), Warp's and MuJoCo's versions and options, and the device. Per scene, so that a
    set's build also covers an env of one of its splits or tasks. Emptying Warp's cache removes
    them with the modules."""
    folder = warp.config.kernel_cache_dir
    if not folder:
        return None
    device = warp.get_preferred_device()
    common = (
        # How the scenes' calls are issued (side by side, how many per call, graph mode) selects no module.
        dataclasses.astuple(config.physics_only()),
        caches.sources_digest(),
        warp.__version__,
        mujoco.__version__,
        str(warp.config.mode),
        str(warp.config.deterministic),
        device.name,
        getattr(device, "arch", None),
    )
    return [
        Path(folder) / f"mwjax-built-{hashlib.sha256(repr((scene, common)).encode()).hexdigest()[:20]}"
        for scene in todo
    ]


# Records of the builds this process has started (`start_scene_build`), until one fails: an env
# made meanwhile (`prebuild`) leaves its scenes to them.
_under_way: set[Path] = set()

PREBUILD_VARIABLE = "MWJAX_PREBUILD"


def prebuild(todo: Sequence[Scene], config: PhysicsConfig) -> None:
    """Before an env's physics first runs on a GPU, build its scenes' modules in parallel, unless
    Warp's cache records them as built or this process is building them (`start_build`).
    Otherwise the first step compiles them one after another (MT50 on a fresh machine: ~8 minutes
    against ~1). A child process (`python -m mwjax.kernels`) runs the build: a pool started here
    would re-import the caller's script in every worker (multiprocessing's spawn). Processes that
    make envs at once (one per GPU) take turns on a lock in Warp's cache, so one of them builds.
    `MWJAX_PREBUILD=0` skips it; a failed child leaves a warning and the modules to the first step."""
    if os.environ.get(PREBUILD_VARIABLE, "1") == "0" or local_device().platform != "gpu":
        return
    records = scene_records(todo, config)
    if not records:
        return
    try:
        with _cache_lock(records[0].parent):
            if all(record.exists() or record in _under_way for record in records):
                return
            progress.note(
                f"Warp's cache ({records[0].parent}) lacks the physics kernels of {len(todo)} scenes: "
                f"building them first, in parallel (`python -m mwjax.kernels`; {PREBUILD_VARIABLE}=0 skips)"
            )
            # Its summary on stdout comes back as a status line; its progress shows as it goes.
            child = subprocess.run(
                child_command(todo, config), env=_child_environment(), stdout=subprocess.PIPE, text=True
            )
            if child.stdout.strip():
                progress.note(child.stdout.strip())
            failure = f"exit {child.returncode}" if child.returncode else None
    except OSError as error:  # e.g. a cache folder this process cannot write
        failure = str(error)
    if failure is not None:
        warnings.warn(
            f"building the physics kernels in a child process failed ({failure}); the first step "
            "compiles them one after another instead",
            RuntimeWarning,
            stacklevel=2,
        )


def child_command(todo: Sequence[Scene], config: PhysicsConfig) -> list[str]:
    """`python -m mwjax.kernels` for exactly these scenes and settings."""
    spec = {"scenes": [list(scene) for scene in todo], "config": dataclasses.asdict(config)}
    return [sys.executable, "-m", "mwjax.kernels", "--scenes", json.dumps(spec)]


def _child_environment() -> dict[str, str]:
    """This environment, with this mwjax first on the child's import path and this process's
    deterministic mode (its modules differ) however it was switched on."""
    root = str(Path(__file__).parents[1])
    path = os.environ.get("PYTHONPATH")
    environment = {**os.environ, "PYTHONPATH": root if not path else os.pathsep.join([root, path])}
    if determinism.enabled():
        environment["MWJAX_DETERMINISTIC"] = "1"
    return environment


@contextlib.contextmanager
def _cache_lock(folder: Path) -> Iterator[None]:
    """Held by one process (or thread) at a time, across the processes that share `folder`."""
    folder.mkdir(parents=True, exist_ok=True)
    with open(folder / "mwjax-build.lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        try:
            yield
        finally:
            fcntl.flock(lock, fcntl.LOCK_UN)


def _pool(workers: int) -> concurrent.futures.Executor:
    return concurrent.futures.ProcessPoolExecutor(workers, mp_context=multiprocessing.get_context("spawn"))


def _distinct_modules(todo: Sequence[Scene], config: PhysicsConfig) -> dict[str, Scene]:
    """Each module that the scenes' steps launch, once, with a scene that launches it.

    Scenes share most of their modules, so stepping each scene in a process of its own would
    compile the shared ones in every process at once. A dry run of every scene in this process
    (`launched_modules`: no kernel runs, nothing compiles) lists the distinct modules instead,
    and each becomes one task for the pool."""
    tasks: dict[str, Scene] = {}
    for scene, bodies in todo:
        for identifier in launched_modules(scene, bodies, config):
            tasks.setdefault(identifier, (scene, bodies))
    return tasks


# Module families by their compile time on a GPU, longest first (`--report` shows each module's):
# the convex collider's (18-24 s each on an H200), then the primitive colliders, the solver's
# Cholesky kernels and MJWarp's large module-level ones (up to ~10 s); the rest take about a second.
_SLOW_FAMILIES = (
    "ccd_kernel",
    "primitive_narrowphase",
    "cholesky",
    "_src.passive_",
    "_src.smooth_",
    "_src.forward_",
)


def _slow_first(identifier: str) -> int:
    """A sort key that puts the modules of the slow families first, the slowest family first."""
    ranks = (rank for rank, family in enumerate(_SLOW_FAMILIES) if family in identifier)
    return next(ranks, len(_SLOW_FAMILIES))


def _start_worker() -> None:
    """Nothing: a task that makes the pool start a worker, which imports this module (Warp,
    MuJoCo, mwjax) to run it."""


Launch = tuple[warp.Module, warp.Device, int]


def launched_modules(scene: str, mocap_bodies: tuple[str, ...], config: PhysicsConfig) -> dict[str, Launch]:
    """Every Warp module that one step and one kinematics call of the scene launch (in this
    process, on Warp's preferred device), by Warp's module identifier (its name, hash and block
    size: its folder in Warp's cache), with the device and block size it launches with.

    `step_once` runs with Warp's launches recorded instead of run (`_recording_launches`), so
    MJWarp's kernel builders make the modules a real step would load, and nothing compiles.
    `tests/test_kernels.py` checks the list against the modules a real `step_once` loads."""
    launches: list[Launch] = []
    with _recording_launches(launches):
        step_once(scene, mocap_bodies, config)
    return {
        module.get_module_identifier(block_dim=block_dim): (module, device, block_dim)
        for module, device, block_dim in launches
    }


def step_once(scene: str, mocap_bodies: tuple[str, ...], config: PhysicsConfig) -> None:
    """One world of the scene, its model and data made as `mwjax.make` makes them, through one
    MJWarp step and one kinematics call."""
    model = warp_model(scene, mocap_bodies, config)
    device_model = mjwarp.put_model(model)
    device_model.opt.warn_overflow = 0  # as `mwjax.physics` runs it: the variant without printf
    data = mjwarp.make_data(model, nworld=1, naconmax=config.contacts_per_env, njmax=constraint_rows(scene))
    mjwarp.step(device_model, data)
    mjwarp.kinematics(device_model, data)


_RECORDING = threading.Lock()


@contextlib.contextmanager
def _recording_launches(launches: list[Launch]) -> Iterator[None]:
    """Within the block, `warp.launch` and `warp.launch_tiled` append (module, device, block size)
    to `launches` instead of launching, as Warp's launch resolves them (a launch of no threads
    loads nothing), as does `warp.get_suggested_block_size` (which loads the module on a GPU), and
    Warp's conditional graph nodes run their bodies once."""
    from warp._src import context

    signature = inspect.signature(context.launch)

    def launch(*args: Any, **kwargs: Any) -> None:
        call = signature.bind(*args, **kwargs)
        call.apply_defaults()
        arguments = call.arguments
        stream = arguments["stream"]
        device = stream.device if stream is not None else context.runtime.get_device(arguments["device"])
        if context._normalize_launch_dim(arguments["dim"])[1] == 0:
            return
        block_dim = context._resolve_launch_block_dim(device, arguments["block_dim"])
        launches.append((arguments["kernel"].module, device, block_dim))

    def launch_tiled(*args: Any, dim: int | Sequence[int], block_dim: int, **kwargs: Any) -> None:
        extents = [dim] if isinstance(dim, int) else list(dim)
        launch(*args, dim=[*extents, block_dim], block_dim=block_dim, **kwargs)

    def suggested_block_size(kernel: Any, device: Any = None) -> tuple[int, int]:
        # On a GPU, Warp's occupancy query loads the kernel's module at the module's own block
        # size; the answer only sizes launch grids, so any plausible one lists the same modules.
        device = context.runtime.get_device(device)
        if device.is_cpu:
            return (1, 1)
        launches.append((kernel.module, device, kernel.module.options["block_dim"]))
        return (256, device.sm_count)

    def capture_while(condition: Any, while_body: Callable[..., None], **kwargs: Any) -> None:
        while_body(**kwargs)

    def capture_if(
        condition: Any, on_true: Callable | None = None, on_false: Callable | None = None, **kwargs: Any
    ) -> None:
        for body in (on_true, on_false):
            if body is not None:
                body(**kwargs)

    replacements = {
        "launch": launch,
        "launch_tiled": launch_tiled,
        "get_suggested_block_size": suggested_block_size,
        "capture_while": capture_while,
        "capture_if": capture_if,
    }
    saved = {name: getattr(warp, name) for name in replacements}
    owner = threading.get_ident()

    def in_this_thread(recording: Callable, original: Callable) -> Callable:
        # Only the dry run's own thread records: a step running meanwhile in another thread of
        # the process (an env's Warp calls on XLA's threads) still launches its kernels.
        @functools.wraps(original)
        def dispatch(*args: Any, **kwargs: Any) -> Any:
            function = recording if threading.get_ident() == owner else original
            return function(*args, **kwargs)

        return dispatch

    with _RECORDING:
        for name, function in replacements.items():
            setattr(warp, name, in_this_thread(function, saved[name]))
        try:
            yield
        finally:
            for name, function in saved.items():
                setattr(warp, name, function)


@functools.cache
def _worker_modules(scene: str, mocap_bodies: tuple[str, ...], config: PhysicsConfig) -> dict[str, Launch]:
    return launched_modules(scene, mocap_bodies, config)


def _compile_module(
    scene: str, mocap_bodies: tuple[str, ...], config: PhysicsConfig, identifier: str
) -> tuple[int, float, float, float]:
    """In a worker: load one module of the scene as its launch would (compiling it unless Warp's
    cache has it); returns how many modules that compiled (0 or 1), when the task started (wall
    clock), and the seconds of the scene's dry run (0 when this worker had made it) and of the load."""
    started = time.time()
    os.environ["MWJAX_PROGRESS"] = "0"  # the parent reports; workers stay quiet
    module, device, block_dim = _worker_modules(scene, mocap_bodies, config)[identifier]
    loading = time.time()
    before = progress.kernel_builds().built
    module.load(device, block_dim)
    return progress.kernel_builds().built - before, started, loading - started, time.time() - loading


def main(argv: Sequence[str] | None = None) -> None:
    parser = argparse.ArgumentParser(prog="python -m mwjax.kernels", description=__doc__.splitlines()[0])
    parser.add_argument(
        "set", nargs="?", help="a set name (MT10, ML45, ...) or task names separated by commas"
    )
    # An env's own scenes and physics settings, as JSON (`prebuild` starts this module so).
    parser.add_argument("--scenes", help=argparse.SUPPRESS)
    parser.add_argument("--workers", type=int, default=None, help="processes (default: CPU cores, ≤ 16)")
    parser.add_argument("--force", action="store_true", help="build even where a completed build is recorded")
    parser.add_argument("--report", action="store_true", help="print each module's times")
    args = parser.parse_args(argv)
    if (args.set is None) == (args.scenes is None):
        parser.error("give a set or task names")
    if args.scenes is not None:
        spec = json.loads(args.scenes)
        todo = [(scene, tuple(bodies)) for scene, bodies in spec["scenes"]]
        pending = start_scene_build(todo, PhysicsConfig(**spec["config"]), args.workers, args.force)
        result = pending.wait()
    else:
        try:
            tasks = benchmarks.parse_tasks(args.set)
            benchmarks.benchmark(tasks)
        except ValueError as error:
            parser.error(str(error))
        result = build(tasks, workers=args.workers, force=args.force)
    print(f"{result.summary()}; Warp's cache: {warp.config.kernel_cache_dir}")
    if args.report and result.modules:
        print(result.report())


if __name__ == "__main__":
    main()
