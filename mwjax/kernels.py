"""Warp's physics kernels for a task set, built before the first step, in parallel processes.

Warp compiles a kernel module the first time a model of a new structure launches it, and MJWarp
specializes its modules per scene (degrees of freedom, geom-type pairs, collider settings), so a
fresh machine's first MT50 step compiles tens of modules one after another, tens of seconds some
of them. `build(tasks)` compiles them side by side instead: one process per scene steps MJWarp
directly, one world, no JAX, into Warp's kernel cache (`~/.cache/warp`, or `WARP_CACHE_PATH`),
where the env's first step then finds them. The scenes are prepared exactly as `mwjax.make`
prepares them (same mocap bodies, same physics settings, mwjax's Warp patches installed), which is
what makes the cached modules the ones the env asks for.

    python -m mwjax.kernels MT50 --workers 16

A machine whose cache already holds the modules loads them in a second or two per scene.
"""

from __future__ import annotations

import argparse
import concurrent.futures
import multiprocessing
import os
import time
from collections.abc import Sequence

import mujoco.mjx.third_party.mujoco_warp as mjwarp
import warp

from mwjax import benchmarks, placement, progress
from mwjax.models import constraint_rows
from mwjax.physics import PhysicsConfig, warp_model
from mwjax.tasks import get_task

Scene = tuple[str, tuple[str, ...]]


def scenes(tasks: str | Sequence[str]) -> list[Scene]:
    """The (scene, mocap bodies) pairs that `mwjax.make` builds physics for, over every split of
    the set (a meta-learning set's train and test envs group their tasks separately)."""
    bench = benchmarks.benchmark(tasks)
    out: dict[Scene, None] = {}
    for split in ("train", "test") if bench.test else ("train",):
        groups = placement.scene_groups([get_task(name) for name in bench.tasks(split)])
        out.update({(members[0].scene, placement.mocap_bodies(members)): None for members in groups})
    return list(out)


def build(
    tasks: str | Sequence[str], config: PhysicsConfig | None = None, workers: int | None = None
) -> tuple[int, float]:
    """Compile the Warp kernel modules of every scene of `tasks` into Warp's cache, `workers`
    processes at a time (default: one per CPU core). Returns (modules built, seconds)."""
    todo = scenes(tasks)
    workers = max(1, min(workers or os.cpu_count() or 1, len(todo)))
    start = time.perf_counter()
    built = 0
    spawn = multiprocessing.get_context("spawn")
    with progress.phase(f"building physics kernels for {len(todo)} scenes in {workers} processes"):
        with concurrent.futures.ProcessPoolExecutor(workers, mp_context=spawn) as pool:
            config = config or PhysicsConfig()
            futures = [pool.submit(_build_scene, scene, bodies, config) for scene, bodies in todo]
            for future in concurrent.futures.as_completed(futures):
                built += future.result()
    return built, time.perf_counter() - start


def _build_scene(scene: str, mocap_bodies: tuple[str, ...], config: PhysicsConfig) -> int:
    """Step one world of the scene once through MJWarp (its step and kinematics), which compiles
    or loads every module a step of it launches; returns how many it compiled."""
    os.environ["MWJAX_PROGRESS"] = "0"  # the parent reports; workers stay quiet
    model = warp_model(scene, mocap_bodies, config)
    device_model = mjwarp.put_model(model)
    device_model.opt.warn_overflow = 0  # as `mwjax.physics` runs it: the kernel variant without printf
    data = mjwarp.make_data(model, nworld=1, naconmax=config.contacts_per_env, njmax=constraint_rows(scene))
    mjwarp.step(device_model, data)
    mjwarp.kinematics(device_model, data)
    warp.synchronize()
    return progress.kernel_builds().built


def main() -> None:
    parser = argparse.ArgumentParser(prog="python -m mwjax.kernels", description=__doc__.splitlines()[0])
    parser.add_argument("set", help="a set name (MT10, ML45, ...) or task names separated by commas")
    parser.add_argument("--workers", type=int, default=None, help="processes at a time (default: CPU cores)")
    args = parser.parse_args()
    built, seconds = build(benchmarks.parse_tasks(args.set), workers=args.workers)
    print(f"{built} kernel modules built in {seconds:.0f} s; Warp's cache: {warp.config.kernel_cache_dir}")


if __name__ == "__main__":
    main()
