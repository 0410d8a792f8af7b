"""Env steps per second of mwjax (physics, observations, V2 rewards and autoreset included).

Each measurement builds a task set at a total batch size, compiles a jitted `lax.scan` rollout
with random actions drawn on device, runs it once to warm up, then times `--repeats` rollouts of
`--steps` env steps (500 by default, so every env autoresets once per rollout). Results are
printed as a table and written to `benchmarks/results/` with device, commit and date.

    python benchmarks/throughput.py --sets MT1:pick-place-v3 MT10 --batch 4096 16384 65536

On a GPU set XLA_PYTHON_CLIENT_MEM_FRACTION (~0.45) so JAX leaves Warp room.
"""

from __future__ import annotations

import argparse
import dataclasses
import datetime
import json
import os
import platform
import subprocess
import time
from pathlib import Path

import jax
import jax.numpy as jnp

import mwjax
from mwjax.benchmarks import task_names

RESULTS = Path(__file__).parent / "results"


def gpu_memory_used_mib() -> float | None:
    try:
        out = subprocess.run(
            ["nvidia-smi", "--query-gpu=memory.used", "--format=csv,noheader,nounits"],
            capture_output=True,
            text=True,
            check=True,
        ).stdout
        return float(out.split()[0])
    except (OSError, subprocess.CalledProcessError, ValueError, IndexError):
        return None


def commit() -> str:
    if os.environ.get("MWJAX_COMMIT"):
        return os.environ["MWJAX_COMMIT"]
    try:
        return subprocess.run(
            ["git", "rev-parse", "HEAD"], capture_output=True, text=True, check=True
        ).stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        return "unknown"


def measure(
    benchmark: str,
    total: int,
    steps: int,
    repeats: int,
    physics: mwjax.PhysicsConfig,
    physics_only_mode: bool = False,
    warmup: bool = True,
) -> dict:
    n_tasks = len(task_names(benchmark))
    if total % n_tasks:
        raise ValueError(f"batch {total} is not divisible by the {n_tasks} tasks of {benchmark}")
    t0 = time.perf_counter()
    env = mwjax.make(benchmark, envs_per_task=total // n_tasks, seed=0, physics=physics)
    build_s = time.perf_counter() - t0

    def rollout(state: mwjax.State, key: jax.Array) -> tuple[mwjax.State, jax.Array]:
        def body(carry: tuple[mwjax.State, jax.Array], key: jax.Array) -> tuple:
            state, successes = carry
            action = jax.random.uniform(key, (env.num_envs, 4), minval=-1.0, maxval=1.0)
            state = env.step(state, action)
            return (state, successes + state.info["success"].sum()), None

        (state, successes), _ = jax.lax.scan(
            body, (state, jnp.zeros((), jnp.int32)), jax.random.split(key, steps)
        )
        return state, successes

    def physics_only(state: mwjax.State, key: jax.Array) -> tuple[mwjax.State, jax.Array]:
        """The same number of physics calls with no action, obs, reward or reset work."""

        def body(datas: tuple, _: None) -> tuple:
            return env.physics.step(datas), None

        datas, _ = jax.lax.scan(body, state.physics, None, length=steps)
        return dataclasses.replace(state, physics=datas), jnp.zeros((), jnp.int32)

    reset = jax.jit(env.reset)
    run = jax.jit(physics_only if physics_only_mode else rollout, donate_argnums=0)
    t0 = time.perf_counter()
    state = jax.block_until_ready(reset(jax.random.key(0)))
    reset_compile_s = time.perf_counter() - t0
    t0 = time.perf_counter()
    compiled = run.lower(state, jax.random.key(1)).compile()
    compile_s = time.perf_counter() - t0
    first_rollout_s = None
    if warmup:  # Warp compiles or loads its kernels on the first call
        t0 = time.perf_counter()
        state, _ = jax.block_until_ready(compiled(state, jax.random.key(1)))
        first_rollout_s = time.perf_counter() - t0
    times = []
    for i in range(repeats):
        t0 = time.perf_counter()
        state, successes = jax.block_until_ready(compiled(state, jax.random.key(2 + i)))
        times.append(time.perf_counter() - t0)
    best = min(times)
    memory_after = gpu_memory_used_mib()
    state_bytes = sum(x.nbytes for x in jax.tree.leaves(state))
    stats = jax.devices()[0].memory_stats() or {}
    return {
        "benchmark": benchmark,
        "mode": "physics only" if physics_only_mode else "env step",
        "num_envs": env.num_envs,
        "steps_per_rollout": steps,
        "env_steps_per_s": env.num_envs * steps / best,
        "rollout_s": times,
        "build_s": build_s,
        "reset_compile_s": reset_compile_s,
        "step_compile_s": compile_s,
        "first_rollout_s": first_rollout_s,
        "state_bytes_per_env": state_bytes / env.num_envs,
        "jax_peak_bytes_in_use": stats.get("peak_bytes_in_use"),
        "gpu_memory_used_mib": memory_after,
        "success_steps_last_rollout": int(successes),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sets", nargs="+", default=["MT1:pick-place-v3", "MT10"])
    parser.add_argument("--batch", nargs="+", type=int, default=[1000, 4000])
    parser.add_argument("--steps", type=int, default=500)
    parser.add_argument("--repeats", type=int, default=2)
    parser.add_argument("--physics", choices=["default", "fast"], default="default")
    parser.add_argument("--physics-only", action="store_true", help="time the physics calls alone")
    parser.add_argument(
        "--no-warmup",
        action="store_true",
        help="time the first rollout too (with a warm Warp kernel cache it costs the same; saves a rollout)",
    )
    parser.add_argument("--out", default=None, help="JSON path (default: benchmarks/results/...)")
    args = parser.parse_args()
    physics = mwjax.PhysicsConfig() if args.physics == "default" else mwjax.PhysicsConfig.fast()

    device = jax.devices()[0]
    rows = []
    for benchmark in args.sets:
        for total in args.batch:
            n_tasks = len(task_names(benchmark))
            total = total - total % n_tasks
            row = measure(
                benchmark, total, args.steps, args.repeats, physics, args.physics_only, not args.no_warmup
            )
            rows.append(row)
            print(
                f"{benchmark:>20} {row['num_envs']:>7} envs  {row['env_steps_per_s']:>12,.0f} env steps/s  "
                f"compile {row['step_compile_s']:.0f}s  rollouts {[round(t) for t in row['rollout_s']]}s  "
                f"state {row['state_bytes_per_env'] / 1024:.0f} KiB/env",
                flush=True,
            )
    result = {
        "device": getattr(device, "device_kind", str(device)),
        "platform": device.platform,
        "host": platform.node(),
        "commit": commit(),
        "date": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds"),
        "physics": args.physics,
        "warmup_rollout": not args.no_warmup,
        "jax": jax.__version__,
        "xla_mem_fraction": os.environ.get("XLA_PYTHON_CLIENT_MEM_FRACTION"),
        "results": rows,
    }
    out = (
        Path(args.out)
        if args.out
        else RESULTS / (f"throughput-{result['device'].replace(' ', '_')}-{result['date'][:10]}.json")
    )
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(result, indent=2))
    print()
    print(f"{'set':>20} {'envs':>7} {'env steps/s':>14} {'compile s':>10}")
    for row in rows:
        rate, compile_s = row["env_steps_per_s"], row["step_compile_s"]
        print(f"{row['benchmark']:>20} {row['num_envs']:>7} {rate:>14,.0f} {compile_s:>10.1f}")
    print(f"device {result['device']}, commit {result['commit'][:10]}, {result['date']} -> {out}")


if __name__ == "__main__":
    main()
