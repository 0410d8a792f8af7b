"""What the benchmark scripts share: a run's provenance (device, commit, date, command), task-set
and buffer arguments as the command line spells them, and where results go."""

from __future__ import annotations

import argparse
import datetime
import os
import platform
import shlex
import subprocess
import sys
from pathlib import Path

RESULTS = Path(__file__).parent / "results"


def commit() -> str:
    """The commit measured: `MWJAX_COMMIT` where the checkout has no `.git` (a copied tree).
    Imports nothing heavy, so a parent process that must not start JAX can call it."""
    if os.environ.get("MWJAX_COMMIT"):
        return os.environ["MWJAX_COMMIT"]
    try:
        return subprocess.run(
            ["git", "rev-parse", "HEAD"], capture_output=True, text=True, check=True, cwd=RESULTS.parent
        ).stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        return "unknown"


def device_name() -> str:
    import jax

    device = jax.devices()[0]
    return getattr(device, "device_kind", str(device))


def provenance() -> dict:
    """Where, when and how a result was measured: every result file starts with this."""
    import jax

    device = jax.devices()[0]
    return {
        "device": device_name(),
        "platform": device.platform,
        "host": platform.node(),
        "commit": commit(),
        "date": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds"),
        "command": shlex.join(["python", *sys.argv]),
        "jax": jax.__version__,
        "xla_mem_fraction": os.environ.get("XLA_PYTHON_CLIENT_MEM_FRACTION"),
    }


def result_path(kind: str, name: str, suffix: str, device: str | None = None) -> Path:
    """`benchmarks/results/<kind>/<name>-<commit>-<device>-<date><suffix>` (`device`: the
    measuring device's name, where a parent process must not start JAX to ask)."""
    date = datetime.date.today().isoformat()
    stem = f"{name}-{commit()[:7]}-{(device or device_name()).replace(' ', '_')}-{date}"
    path = RESULTS / kind / f"{stem}{suffix}"
    path.parent.mkdir(parents=True, exist_ok=True)
    return path


def set_arg(text: str) -> str:
    """`--set` checked where the command line is read: the text back, or a usage error that names
    the known sets (imports mwjax: not for a parent process that must not start Warp)."""
    from mwjax.benchmarks import benchmark, parse_tasks

    try:
        benchmark(parse_tasks(text))
    except ValueError as error:
        raise argparse.ArgumentTypeError(str(error)) from None
    return text


def add_set_argument(parser: argparse.ArgumentParser, default: str) -> None:
    """The `--set` option of the scripts that take one set (checked by `set_arg`)."""
    parser.add_argument(
        "--set", type=set_arg, default=default, help="a set name, MT1:<task>, or tasks separated by commas"
    )


_DEFAULT = object()  # not a string: argparse would pass it through `type`


def add_concurrent_scenes_argument(parser: argparse.ArgumentParser) -> None:
    """`--concurrent-scenes on|off` and `--scenes-per-call N|all`, read as
    `PhysicsConfig.concurrent_scenes` (absent: None, the default, side by side on one GPU) and
    `PhysicsConfig.scenes_per_call` (`scene_settings` gives both as keyword arguments)."""
    parser.add_argument(
        "--concurrent-scenes",
        type=_on_off,
        metavar="{on,off}",
        default=None,
        help="PhysicsConfig.concurrent_scenes (default: on for one GPU, else off)",
    )
    add_scenes_per_call_argument(parser)


def add_scenes_per_call_argument(parser: argparse.ArgumentParser) -> None:
    """`--scenes-per-call N|all` (`PhysicsConfig.scenes_per_call`; all: None)."""
    parser.add_argument(
        "--scenes-per-call",
        type=_per_call,
        metavar="{N,all}",
        default=_DEFAULT,
        help="PhysicsConfig.scenes_per_call: at most N scenes per combined call, or all in one "
        "(default: PhysicsConfig's)",
    )


def scene_settings(args: argparse.Namespace) -> dict[str, object]:
    """The `PhysicsConfig` keyword arguments that the options of `add_concurrent_scenes_argument`
    or `add_scenes_per_call_argument` set (none for an option left out: the config's default)."""
    settings: dict[str, object] = {}
    if getattr(args, "concurrent_scenes", None) is not None:
        settings["concurrent_scenes"] = args.concurrent_scenes
    if args.scenes_per_call is not _DEFAULT:
        settings["scenes_per_call"] = args.scenes_per_call
    return settings


def _per_call(text: str) -> int | None:
    if text == "all":
        return None
    if not text.isdigit() or int(text) < 1:
        raise argparse.ArgumentTypeError(f"expected a positive integer or all, not {text!r}")
    return int(text)


def _on_off(text: str) -> bool:
    if text not in ("on", "off"):
        raise argparse.ArgumentTypeError(f"expected on or off, not {text!r}")
    return text == "on"


def tasks_arg(text: str) -> str | list[str]:
    """A set as `mwjax.make` takes it (`mwjax.benchmarks.parse_tasks`)."""
    from mwjax.benchmarks import parse_tasks

    return parse_tasks(text)


def rows_arg(text: str) -> int | str:
    """A buffer size on the command line: a count per env, or "per_scene"."""
    return text if text == "per_scene" else int(text)


def build_kernels(tasks: str | list[str], physics: object = None) -> float | None:
    """On a GPU, Warp's modules for `tasks` built side by side first (`mwjax.kernels`), rather than
    one by one inside the first step; returns the seconds it took (None on the CPU)."""
    import jax

    if jax.default_backend() != "gpu":
        return None
    from mwjax import kernels

    return kernels.build(tasks, physics).seconds


def staggered_vector_env(envs: object) -> object:
    """`envs` (a `mwjax.make_vector` env) reset with its episodes staggered as `--stagger`
    staggers the jitted rollout's, so that its steps cost what a long run's do; returns the
    adapter under its wrappers (its `state`, `step`, `env`)."""
    import jax

    from mwjax.env import staggered

    envs.reset(seed=0)
    adapter = envs.unwrapped
    adapter.state = staggered(adapter.state, adapter.env.max_episode_steps, jax.random.key(1))
    return adapter
