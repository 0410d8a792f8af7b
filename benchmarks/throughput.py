"""Env steps per second of mwjax (physics, observations, V2 rewards and autoreset included).

The protocol: for each set and batch size, compile a jitted `lax.scan` rollout with random
actions drawn on device, run it once from reset to warm up, then time full 500-step episodes:
every env autoresets once per timed rollout, default physics, and a row where any env dropped a
contact, constraint row or collider pair (`info["physics_overflow"]`) is refused (no figure).

    python benchmarks/throughput.py --sets MT1:pick-place-v3 MT10 --batch 16384 131072

Anything else is labelled in the row's `protocol` and printed beside its figure: other rollout
lengths (`--steps`), buffers or graph modes, no warm-up, and `--stagger W`. `--stagger W` starts
every env at a different point of its episode (counters spread over 0..499) and times a window of
W steps after a W-step warm-up: resets then fall in every step, as in a long run with staggered
episodes, so a window shorter than an episode still sees its share of them. That lets a batch
whose 500-step rollout would not fit a 10-minute device call (MT50 at 400k envs) be measured.

`--vs-reference PYTHON` also runs the reference (metaworld 3.1.1 under its own interpreter, one
process per env through Gymnasium's AsyncVectorEnv, see `reference_throughput.py`) in the same
invocation and prints mwjax's best protocol rate over it per set. `--adapter` also times the
Gymnasium adapter (`mwjax.make_vector`, one jitted call and a NumPy transfer per step) at the same
batch sizes, with the run's `--concurrent-scenes` / `--scenes-per-call` (absent: the adapter's
default, on one GPU its scenes side by side, staged), in staggered episodes: it times a window of
`--adapter-steps` steps after a warm-up of as many, and records its share of the jitted rate.
`--adapter-only` times the adapter alone, for a batch whose jitted and adapter rows together would
not fit a 10-minute device call (MT50 at 409,600 envs: each compiles its own programs).
`--plot` saves the scaling curve (protocol rows only) as a PNG beside the JSON.

On a GPU set XLA_PYTHON_CLIENT_MEM_FRACTION (~0.45) so JAX leaves Warp room.
"""

from __future__ import annotations

import argparse
import concurrent.futures
import dataclasses
import importlib.util
import json
import multiprocessing
import os
import shlex
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
from common import (
    add_concurrent_scenes_argument,
    build_kernels,
    provenance,
    result_path,
    rows_arg,
    scene_settings,
    set_arg,
    staggered_vector_env,
    tasks_arg,
)

import mwjax
from mwjax.benchmarks import task_names
from mwjax.env import staggered
from mwjax.physics import DROPPED, runs_scenes_together, scenes_together_by_default
from mwjax.wrappers.gymnasium import make_vector

EPISODE = 500  # the reference's max_episode_steps, mwjax's default


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


def warp_kernel_modules() -> int:
    """How many compiled modules Warp's kernel cache holds (one folder each). The cache is shared:
    a process building into it meanwhile (a training run on another GPU) counts too, so a refusal
    on this count can be a false alarm, never a missed compile."""
    import warp

    folder = warp.config.kernel_cache_dir
    if not folder or not os.path.isdir(folder):
        return 0
    # Files beside the folders are mwjax's records of finished scene builds, not modules.
    return sum(entry.is_dir() for entry in os.scandir(folder))


def deviations(
    steps: int, warmup: bool, stagger: int | None, physics: mwjax.PhysicsConfig, platform: str
) -> list[str]:
    """How a measurement departs from the protocol (empty: it is the protocol). Scenes side by
    side count by what `platform` runs: asking for what the default does there is no deviation,
    and `MWJAX_CONCURRENT_SCENES=0` turning the default off is one."""
    out = []
    if stagger is not None:
        out.append(f"staggered episodes, {stagger}-step window")
    elif steps != EPISODE:
        out.append(f"{steps}-step rollouts")
    if not warmup:
        out.append("no warm-up")
    defaults = mwjax.PhysicsConfig()
    for field in dataclasses.fields(defaults):
        if field.name == "concurrent_scenes":
            together = runs_scenes_together(physics, platform)
            if together != scenes_together_by_default(defaults, platform):
                out.append(f"concurrent_scenes={together}")
        elif getattr(physics, field.name) != getattr(defaults, field.name):
            out.append(f"{field.name}={getattr(physics, field.name)}")
    return out


def measure(
    benchmark: str,
    total: int,
    steps: int,
    repeats: int,
    physics: mwjax.PhysicsConfig,
    warmup: bool = True,
    stagger: int | None = None,
) -> dict:
    """One row: build the set at `total` envs, compile, warm up, time `repeats` rollouts."""
    n_tasks = len(task_names(tasks_arg(benchmark)))
    if total % n_tasks:
        raise ValueError(f"batch {total} is not divisible by the {n_tasks} tasks of {benchmark}")
    if stagger is not None:
        steps = stagger
    kernel_build_s = build_kernels(tasks_arg(benchmark), physics)
    t0 = time.perf_counter()
    env = mwjax.make(tasks_arg(benchmark), envs_per_task=total // n_tasks, seed=0, physics=physics)
    build_s = time.perf_counter() - t0

    def rollout(state: mwjax.State, key: jax.Array) -> tuple[mwjax.State, jax.Array, jax.Array]:
        """`steps` env steps; per env, the dropping overflow flags raised at any of them."""

        def body(carry: tuple[mwjax.State, jax.Array, jax.Array], key: jax.Array) -> tuple:
            state, dropped, successes = carry
            action = jax.random.uniform(key, (env.num_envs, 4), minval=-1.0, maxval=1.0)
            state = env.step(state, action)
            dropped = dropped | (state.info["physics_overflow"] & int(DROPPED))
            return (state, dropped, successes + state.info["success"].sum()), None

        init = (state, jnp.zeros(env.num_envs, jnp.int32), jnp.zeros((), jnp.int32))
        (state, dropped, successes), _ = jax.lax.scan(body, init, jax.random.split(key, steps))
        return state, dropped, successes

    run = jax.jit(rollout, donate_argnums=0)
    t0 = time.perf_counter()
    state = jax.block_until_ready(jax.jit(env.reset)(jax.random.key(0)))
    reset_compile_s = time.perf_counter() - t0
    if stagger is not None:  # each env at a different point of its episode
        state = staggered(state, env.max_episode_steps, jax.random.key(1))
    t0 = time.perf_counter()
    compiled = run.lower(state, jax.random.key(1)).compile()
    compile_s = time.perf_counter() - t0
    dropped_envs = np.zeros(env.num_envs, bool)
    first_rollout_s = None
    if warmup:  # Warp loads (or on a fresh machine compiles) its kernels at the first call
        t0 = time.perf_counter()
        state, dropped, _ = jax.block_until_ready(compiled(state, jax.random.key(1)))
        first_rollout_s = time.perf_counter() - t0
        dropped_envs |= np.asarray(dropped) != 0
    modules_before = warp_kernel_modules()
    times = []
    for i in range(repeats):
        t0 = time.perf_counter()
        state, dropped, successes = jax.block_until_ready(compiled(state, jax.random.key(2 + i)))
        times.append(time.perf_counter() - t0)
        dropped_envs |= np.asarray(dropped) != 0
    # A module compiled inside the timed rollouts means the figure timed the compiler.
    compiled_in_timing = warp_kernel_modules() - modules_before
    overflow_envs = int(dropped_envs.sum())
    labels = deviations(steps, warmup, stagger, physics, jax.devices()[0].platform)
    refused = []
    if overflow_envs:
        refused.append(f"{overflow_envs} envs dropped contacts, constraint rows or collider pairs")
    if compiled_in_timing:
        refused.append(
            f"Warp's kernel cache gained {compiled_in_timing} modules during the timed rollouts (built by "
            "this process or by another one sharing the cache)"
        )
    stats = jax.devices()[0].memory_stats() or {}
    return {
        "benchmark": benchmark,
        "num_envs": env.num_envs,
        "steps_per_rollout": steps,
        "protocol": "full episodes" if not labels else "labelled: " + "; ".join(labels),
        "env_steps_per_s": None if refused else env.num_envs * steps / min(times),
        "refused": "; ".join(refused) or None,
        "overflow_envs": overflow_envs,
        "scenes_together": env.physics.concurrent_scenes,
        "rollout_s": times,
        "kernel_build_s": kernel_build_s,  # Warp's modules, in parallel processes (GPU only)
        "build_s": build_s,
        "reset_compile_s": reset_compile_s,
        "step_compile_s": compile_s,  # tracing and lowering included
        "first_rollout_s": first_rollout_s,
        "state_bytes_per_env": sum(x.nbytes for x in jax.tree.leaves(state)) / env.num_envs,
        "jax_peak_bytes_in_use": stats.get("peak_bytes_in_use"),
        "gpu_memory_used_mib": gpu_memory_used_mib(),
        "success_steps_last_rollout": int(successes),
    }


def in_fresh_process(function: Callable[..., dict], *args: object) -> dict:
    """`function(*args)` in a fresh interpreter, with the device's whole memory: Warp keeps each
    captured CUDA graph, and the scratch it allocated, for the life of the process, so a row
    measured after another would have less of the card than a user's program of that one set.
    The row carries the child's provenance (the parent never starts JAX on the device)."""
    spawn = multiprocessing.get_context("spawn")
    with concurrent.futures.ProcessPoolExecutor(max_workers=1, mp_context=spawn) as pool:
        return pool.submit(_with_provenance, function, *args).result()


def _with_provenance(function: Callable[..., dict], *args: object) -> dict:
    return {**function(*args), "provenance": provenance()}


def measure_adapter(
    benchmark: str, total: int, steps: int, array_type: str, graph_mode: str | None, scenes: dict
) -> dict:
    """The Gymnasium adapter stepped from Python with `array_type` actions in and results out:
    "numpy" is what a Gymnasium user gets, "jax" (device arrays) isolates the host transfer.
    `graph_mode` is the adapter env's `PhysicsConfig.graph_mode` (None: the adapter's default),
    `scenes` its `concurrent_scenes` / `scenes_per_call` settings (`scene_settings`).

    The episodes are staggered as `--stagger` staggers the jitted rollout's, and a `steps`-step
    window is timed after a `steps`-step warm-up: steps taken from reset, with the arm near its
    start pose and no reset among them, cost the physics less than a long run's do."""
    n_tasks = len(task_names(tasks_arg(benchmark)))
    envs = make_vector(
        tasks_arg(benchmark),
        envs_per_task=total // n_tasks,
        seed=0,
        array_type=array_type,
        physics=mwjax.PhysicsConfig(graph_mode=graph_mode, **scenes),
    )
    staggered_vector_env(envs)
    rng = np.random.default_rng(0)
    actions = rng.uniform(-1, 1, size=(steps, envs.num_envs, 4)).astype(np.float32)
    if array_type == "jax":
        actions = jnp.asarray(actions)
    for action in actions:  # the first step compiles
        out = envs.step(action)
    jax.block_until_ready(out)
    t0 = time.perf_counter()
    for action in actions:
        out = envs.step(action)
    jax.block_until_ready(out)
    return {
        f"adapter_{array_type}_env_steps_per_s": envs.num_envs * steps / (time.perf_counter() - t0),
        "scenes_together": envs.unwrapped.env.physics.concurrent_scenes,
    }


def adapter_row(benchmark: str, total: int, steps: int, graph_mode: str | None, scenes: dict) -> dict:
    """The adapter's timing, each array type in a process of its own (Warp keeps an env's CUDA
    graphs for the life of its process), or the error that stopped it (out of device memory,
    say): recorded in the row, so the throughput rows measured before it are still written."""
    row: dict = {
        "benchmark": benchmark,
        "num_envs": total,
        "adapter_steps": steps,
        "protocol": f"staggered episodes, {steps}-step window after a {steps}-step warm-up",
        "graph_mode": graph_mode,
    }
    for array_type in ("jax", "numpy"):
        try:
            row |= in_fresh_process(measure_adapter, benchmark, total, steps, array_type, graph_mode, scenes)
        except Exception as e:  # the child's exception, or a child that died (BrokenProcessPool)
            return row | {"error": f"{array_type} arrays: {type(e).__name__}: {e}"}
    jax_rate, numpy_rate = row["adapter_jax_env_steps_per_s"], row["adapter_numpy_env_steps_per_s"]
    return row | {"numpy_transfer_ms_per_step": 1e3 * total * (1 / numpy_rate - 1 / jax_rate)}


def jitted_row(benchmark: str, total: int, args: argparse.Namespace, physics: mwjax.PhysicsConfig) -> dict:
    """The jitted rollout's row, measured in a fresh process, and its line on the console."""
    row = in_fresh_process(
        measure, benchmark, total, args.steps, args.repeats, physics, not args.no_warmup, args.stagger
    )
    rate = f"{row['env_steps_per_s']:>12,.0f}" if row["env_steps_per_s"] else "     REFUSED"
    print(
        f"{benchmark:>20} {row['num_envs']:>7} envs {rate} env steps/s  ({row['protocol']})  "
        f"compile {row['step_compile_s']:.0f}s  rollouts {[round(t, 1) for t in row['rollout_s']]}s  "
        f"overflow envs {row['overflow_envs']}" + (f"  refused: {row['refused']}" if row["refused"] else ""),
        flush=True,
    )
    return row


def measure_reference(python: str, benchmark: str, steps: int) -> dict:
    script = Path(__file__).with_name("reference_throughput.py")
    command = [*shlex.split(python), str(script), "--set", benchmark, "--steps", str(steps)]
    out = subprocess.run([*command, "--envs", str(os.cpu_count())], capture_output=True, text=True)
    if out.returncode:  # recorded, not fatal: the mwjax rows measured before it are kept
        return {"benchmark": benchmark, "error": f"reference run failed: {out.stderr[-3000:]}"}
    return json.loads(out.stdout.strip().splitlines()[-1])


def plot(result: dict, path: Path) -> None:
    """The scaling curve of the protocol rows, with the reference and the adapter beside it."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7, 4.5))
    rows = [r for r in result["results"] if r["protocol"] == "full episodes" and r["env_steps_per_s"]]
    for i, name in enumerate(dict.fromkeys(r["benchmark"] for r in result["results"])):
        color = f"C{i}"
        mine = sorted((r for r in rows if r["benchmark"] == name), key=lambda r: r["num_envs"])
        if mine:
            ax.plot([r["num_envs"] for r in mine], [r["env_steps_per_s"] for r in mine], "o-", color=color)
            ax.lines[-1].set_label(f"mwjax {name}")
        adapter = [r for r in result.get("adapter", []) if r["benchmark"] == name and "error" not in r]
        for j, mode in enumerate(dict.fromkeys(r.get("graph_mode") for r in adapter)):
            same = [r for r in adapter if r.get("graph_mode") == mode]
            ax.plot(
                [r["num_envs"] for r in same],
                [r["adapter_numpy_env_steps_per_s"] for r in same],
                ("x", "+", "^")[j % 3] + ":",
                color=color,
                label=f"mwjax {name}, Gymnasium adapter (NumPy, {mode or 'default'} graphs)",
            )
        for ref in result.get("reference", []):
            if ref["benchmark"] == name and "error" not in ref:
                ax.axhline(
                    ref["env_steps_per_s"],
                    color=color,
                    ls="--",
                    lw=1,
                    label=f"metaworld 3.1.1 {name} ({ref['cpu_cores']} CPU cores)",
                )
    ax.set_xscale("log", base=2)
    ax.set_yscale("log")
    ax.set_xlabel("envs in the batch")
    ax.set_ylabel("env steps / s (full 500-step episodes, random actions)")
    ax.grid(alpha=0.3, which="both")
    ax.legend(fontsize=7)
    ax.set_title(f"{result['device']}, commit {result['commit'][:10]}, {result['date'][:10]}", fontsize=9)
    fig.tight_layout()
    fig.savefig(path, dpi=120)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--sets",
        type=set_arg,
        nargs="+",
        default=["MT1:pick-place-v3", "MT10"],
        help="task sets",
    )
    parser.add_argument("--batch", nargs="+", type=int, default=[1000, 4000], help="total envs per set")
    parser.add_argument("--steps", type=int, default=EPISODE, help="steps per rollout (500: the protocol)")
    parser.add_argument("--repeats", type=int, default=1, help="timed rollouts per row (the best counts)")
    parser.add_argument(
        "--stagger", type=int, metavar="W", default=None, help="staggered episodes, W-step window"
    )
    parser.add_argument("--no-warmup", action="store_true", help="time the first rollout too (labelled)")
    parser.add_argument("--contacts", type=int, default=None, help="PhysicsConfig.contacts_per_env")
    parser.add_argument("--constraints", type=rows_arg, default=None, help="constraints_per_env")
    parser.add_argument("--ccd-pairs", type=rows_arg, default=None, help="ccd_pairs_per_env")
    parser.add_argument("--graph-mode", default=None, help="PhysicsConfig.graph_mode")
    add_concurrent_scenes_argument(parser)
    parser.add_argument("--vs-reference", metavar="PYTHON", default=None, help="also time metaworld 3.1.1")
    parser.add_argument("--reference-steps", type=int, default=EPISODE)
    parser.add_argument("--adapter", action="store_true", help="also time the Gymnasium adapter")
    parser.add_argument(
        "--adapter-only",
        action="store_true",
        help="time the Gymnasium adapter alone, no jitted rows (a large set's adapter row in a device "
        "call of its own)",
    )
    parser.add_argument(
        "--adapter-steps",
        type=int,
        default=None,
        help="the adapter's window (default: W of --stagger, else 100)",
    )
    parser.add_argument(
        "--adapter-graph-modes",
        nargs="+",
        default=["default"],
        help="the adapter's PhysicsConfig.graph_mode, a row each ('default': the adapter's own, Warp's "
        "staged mode on one GPU; 'warp': MJX's default capture)",
    )
    parser.add_argument("--plot", action="store_true", help="save the scaling curve as a PNG")
    parser.add_argument("--out", default=None, help="JSON path (default: benchmarks/results/throughput/...)")
    args = parser.parse_args()
    if args.stagger is not None and not 1 <= args.stagger <= EPISODE:
        parser.error(f"--stagger must be in [1, {EPISODE}]")
    if args.adapter_steps is not None and args.adapter_steps < 1:
        parser.error("--adapter-steps must be a positive number of steps")
    adapter_window = args.adapter_steps or args.stagger or 100
    args.adapter |= args.adapter_only
    if args.plot and args.adapter_only:
        parser.error("--plot draws the jitted rows' curve, and --adapter-only measures none")
    if args.plot and importlib.util.find_spec("matplotlib") is None:
        parser.error("--plot needs matplotlib: pip install 'mwjax[plots]'")
    settings = {
        "contacts_per_env": args.contacts,
        "constraints_per_env": args.constraints,
        "ccd_pairs_per_env": args.ccd_pairs,
        "graph_mode": args.graph_mode,
    }
    scenes = scene_settings(args)
    physics = mwjax.PhysicsConfig(**{k: v for k, v in settings.items() if v is not None}, **scenes)

    rows, adapter, reference = [], [], []
    for benchmark in args.sets:
        n_tasks = len(task_names(tasks_arg(benchmark)))
        for total in args.batch:
            row = None if args.adapter_only else jitted_row(benchmark, total - total % n_tasks, args, physics)
            if row:
                rows.append(row)
            for graph_mode in args.adapter_graph_modes if args.adapter else ():
                mode = None if graph_mode == "default" else graph_mode
                timing = adapter_row(benchmark, total - total % n_tasks, adapter_window, mode, scenes)
                if "error" in timing:
                    text = f"FAILED: {timing['error']}"
                else:
                    text = (
                        f"{timing['adapter_numpy_env_steps_per_s']:>12,.0f} env steps/s with NumPy, "
                        f"{timing['adapter_jax_env_steps_per_s']:,.0f} with jax arrays"
                    )
                    if row and row["env_steps_per_s"]:  # the adapter's share of the jitted rollout's rate
                        timing["numpy_share_of_jitted"] = (
                            timing["adapter_numpy_env_steps_per_s"] / row["env_steps_per_s"]
                        )
                        text += f" ({timing['numpy_share_of_jitted']:.0%} of the jitted rollout's with NumPy)"
                adapter.append(timing)
                together = ", scenes side by side" if timing.get("scenes_together") else ""
                print(f"{'':>20} {'':>7}       adapter ({graph_mode} graphs{together}): {text}", flush=True)
    if args.vs_reference:
        for benchmark in args.sets:
            ref = measure_reference(args.vs_reference, benchmark, args.reference_steps)
            if "error" in ref:
                reference.append(ref)
                print(f"{benchmark:>20} reference: {ref['error']}", flush=True)
                continue
            ours = [
                r["env_steps_per_s"] for r in rows if r["benchmark"] == benchmark and r["env_steps_per_s"]
            ]
            ref["mwjax_best_env_steps_per_s"] = max(ours, default=None)
            ref["ratio"] = max(ours) / ref["env_steps_per_s"] if ours else None
            reference.append(ref)
            ratio = f"mwjax {max(ours):,.0f} = {ref['ratio']:.0f}x" if ours else "no mwjax figure"
            print(
                f"{benchmark:>20} reference (metaworld 3.1.1, {ref['num_envs']} envs, AsyncVectorEnv, "
                f"{ref['cpu_cores']} cores): {ref['env_steps_per_s']:,.0f} env steps/s; {ratio}",
                flush=True,
            )
    # The first child's provenance (an adapter that failed in its first process has none).
    provenances = [row.pop("provenance") for row in rows + adapter if "provenance" in row]
    if not provenances:
        sys.exit(f"nothing was measured: {[row.get('error') for row in adapter]}")
    first = provenances[0]
    result = {
        **first,
        "command": shlex.join(["python", *sys.argv]),
        "physics": dataclasses.asdict(physics),
        "results": rows,
        "adapter": adapter,
        "reference": reference,
    }
    out = Path(args.out) if args.out else result_path("throughput", "throughput", ".json", first["device"])
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(result, indent=2))
    print(f"device {result['device']}, commit {result['commit'][:10]}, {result['date']} -> {out}")
    if args.plot:
        plot(result, out.with_suffix(".png"))
        print(f"plot -> {out.with_suffix('.png')}")
    if any(row["refused"] for row in rows):
        sys.exit("some rows were refused (no figure): see 'refused' in the JSON")


if __name__ == "__main__":
    main()
