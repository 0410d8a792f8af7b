"""Env steps per second of mwjax (physics, observations, V2 rewards and autoreset included).

Each measurement builds a task set at a total batch size, compiles a jitted `lax.scan` rollout
with random actions drawn on device, runs it once to warm up, then times `--repeats` rollouts of
`--steps` env steps (500 by default, so every env autoresets once per rollout). Results are
printed as a table and written to `benchmarks/results/` with device, commit and date.

    python benchmarks/throughput.py --sets MT1:pick-place-v3 MT10 --batch 4096 16384 65536

`--vs-reference PYTHON` also runs the reference (metaworld 3.1.1, its own interpreter, one
process per env with Gymnasium's AsyncVectorEnv, see `reference_throughput.py`) in the same
invocation and prints mwjax's best rate over it per set. `--adapter` also times the Gymnasium
adapter (`mwjax.make_vector`, one jitted call and a NumPy transfer per step) at the same batch
sizes. `--plot` saves the scaling curve (env steps/s against batch size) as a PNG beside the JSON.
`--jax-cache DIR` turns on JAX's persistent compilation cache: a second process with the same
sets and batch sizes then loads the compiled programs instead of compiling them (the "warm cache"
compile time; tracing and lowering still run). `--profile-compile` writes a cProfile of each
step's compile after lowering (XLA, or the cache load) beside the JSON, `--profile-lowering` one
of the lowering (slowed by the profiler), and `--hlo-stats` counts the compiled step's
instructions per opcode into the JSON.

On a GPU set XLA_PYTHON_CLIENT_MEM_FRACTION (~0.45) so JAX leaves Warp room.
"""

from __future__ import annotations

import argparse
import collections
import cProfile
import dataclasses
import datetime
import io
import json
import os
import platform
import pstats
import re
import shlex
import subprocess
import sys
import time
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np

import mwjax
from mwjax.benchmarks import task_names
from mwjax.tasks import TASKS
from mwjax.wrappers.gymnasium import make_vector

RESULTS = Path(__file__).parent / "results" / "throughput"


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


def rows_arg(text: str) -> int | str:
    """A `--constraints` or `--ccd-pairs` value: a count per env, or "per_scene"."""
    return text if text == "per_scene" else int(text)


def tasks_arg(text: str) -> str | list[str]:
    """A `--set` value as `mwjax.make` takes it: a set name, or task names separated by commas
    (one task alone runs as a one-task set)."""
    return text.split(",") if "," in text or text in TASKS else text


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
    compile_profile: Path | None = None,
    lowering_profile: Path | None = None,
    hlo_stats: bool = False,
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
    profiler = cProfile.Profile() if compile_profile else None
    lowering_profiler = cProfile.Profile() if lowering_profile else None
    t0 = time.perf_counter()
    if lowering_profiler:  # the lowering figure then includes the profiler's own cost
        lowering_profiler.enable()
    lowered = run.lower(state, jax.random.key(1))
    lower_s = time.perf_counter() - t0
    if lowering_profiler:
        lowering_profiler.disable()
        write_profile(
            lowering_profiler,
            lowering_profile,
            f"{benchmark}, {env.num_envs} envs: lowering {lower_s:.1f} s under cProfile",
        )
    if profiler:  # not the lowering: that is Python tracing, which a profiler slows down
        profiler.enable()
    compiled = lowered.compile()
    compile_s = time.perf_counter() - t0
    if profiler:
        profiler.disable()
        write_profile(
            profiler,
            compile_profile,
            f"{benchmark}, {env.num_envs} envs: lower {lower_s:.1f} s, lower + compile {compile_s:.1f} s",
        )
    step_hlo = optimized_hlo_stats(compiled.as_text()) if hlo_stats else None
    first_rollout_s = None
    if warmup:  # Warp compiles or loads its kernels on the first call
        t0 = time.perf_counter()
        state, _ = jax.block_until_ready(compiled(state, jax.random.key(1)))
        first_rollout_s = time.perf_counter() - t0
    modules_before = warp_kernel_modules()
    times = []
    for i in range(repeats):
        t0 = time.perf_counter()
        state, successes = jax.block_until_ready(compiled(state, jax.random.key(2 + i)))
        times.append(time.perf_counter() - t0)
    # Warp compiles a kernel module on its first launch on a machine with no kernel cache; a
    # timed rollout that did so measured the compiler, not the simulator.
    compiled_in_timing = warp_kernel_modules() - modules_before
    if compiled_in_timing:
        print(
            f"warning: Warp compiled {compiled_in_timing} kernel modules inside the timed rollouts of "
            f"{benchmark} at {env.num_envs} envs: that figure is not throughput (drop --no-warmup)",
            flush=True,
        )
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
        "step_compile_s": compile_s,  # tracing and lowering included
        "step_lower_s": lower_s,
        "step_lowering_profiled": lowering_profile is not None,
        "step_hlo": step_hlo,
        "first_rollout_s": first_rollout_s,
        "state_bytes_per_env": state_bytes / env.num_envs,
        "jax_peak_bytes_in_use": stats.get("peak_bytes_in_use"),
        "gpu_memory_used_mib": memory_after,
        "success_steps_last_rollout": int(successes),
        "warp_modules_compiled_in_timed_rollouts": compiled_in_timing,
    }


def optimized_hlo_stats(text: str) -> dict:
    """What a compiled program is made of: its computations (fusion bodies included), its
    instructions over all of them, and the 25 commonest opcodes (custom calls are Warp's)."""
    opcodes: collections.Counter[str] = collections.Counter()
    computations = 0
    for line in text.splitlines():
        if line.endswith("{") and not line.startswith(" "):
            computations += 1
        elif match := _HLO_INSTRUCTION.match(line):
            opcodes[match.group(1)] += 1
    return {
        "text_bytes": len(text),
        "computations": computations,
        "instructions": sum(opcodes.values()),
        "top_opcodes": dict(opcodes.most_common(25)),
    }


_HLO_INSTRUCTION = re.compile(r"\s+(?:ROOT )?%?[\w.\-]+ = .*? ([a-z][a-z0-9\-]*)\(")


def profile_path(out: Path, kind: str, benchmark: str, total: int) -> Path:
    """Where a profile of one set and batch goes: beside the result JSON `out`."""
    return out.with_name(f"{out.stem}-{kind}-{benchmark.replace(':', '-')}-{total}.txt")


def write_profile(profiler: cProfile.Profile, path: Path, title: str) -> None:
    """The profile's heaviest calls, by cumulative and by own time, as text."""
    text = io.StringIO()
    text.write(f"{title}\n")
    stats = pstats.Stats(profiler, stream=text)
    stats.sort_stats("cumulative").print_stats(50)
    stats.sort_stats("tottime").print_stats(30)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(text.getvalue())
    print(f"profile -> {path}", flush=True)


def warp_kernel_modules() -> int:
    """How many compiled modules Warp's kernel cache holds (one folder each)."""
    import warp

    folder = warp.config.kernel_cache_dir
    return len(os.listdir(folder)) if folder and os.path.isdir(folder) else 0


def measure_adapter(benchmark: str, total: int, steps: int) -> dict:
    """The Gymnasium adapter stepped from Python: NumPy actions in, NumPy results out, against the
    same adapter with device (jax) arrays, which isolates the host transfer."""
    n_tasks = len(task_names(benchmark))
    rates = {}
    for array_type in ("jax", "numpy"):
        envs = make_vector(benchmark, envs_per_task=total // n_tasks, seed=0, array_type=array_type)
        envs.reset(seed=0)
        rng = np.random.default_rng(0)
        actions = rng.uniform(-1, 1, size=(steps + 1, envs.num_envs, 4)).astype(np.float32)
        if array_type == "jax":
            actions = jnp.asarray(actions)
        jax.block_until_ready(envs.step(actions[0]))  # compile
        t0 = time.perf_counter()
        for action in actions[1:]:
            out = envs.step(action)
        jax.block_until_ready(out)
        rates[array_type] = envs.num_envs * steps / (time.perf_counter() - t0)
        envs.close()
    per_step_ms = 1e3 * total * (1 / rates["numpy"] - 1 / rates["jax"])
    return {
        "benchmark": benchmark,
        "num_envs": total,
        "adapter_steps": steps,
        "adapter_jax_env_steps_per_s": rates["jax"],
        "adapter_numpy_env_steps_per_s": rates["numpy"],
        "numpy_transfer_ms_per_step": per_step_ms,
    }


def measure_reference(python: str, benchmark: str, steps: int) -> dict:
    script = Path(__file__).with_name("reference_throughput.py")
    out = subprocess.run(
        [
            *shlex.split(python),
            str(script),
            "--set",
            benchmark,
            "--steps",
            str(steps),
            "--envs",
            str(os.cpu_count()),
        ],
        capture_output=True,
        text=True,
    )
    if out.returncode:
        sys.exit(f"reference run failed for {benchmark}:\n{out.stderr[-3000:]}")
    return json.loads(out.stdout.strip().splitlines()[-1])


def plot(result: dict, path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7, 4.5))
    for i, name in enumerate(dict.fromkeys(r["benchmark"] for r in result["results"])):
        rows = sorted((r for r in result["results"] if r["benchmark"] == name), key=lambda r: r["num_envs"])
        color = f"C{i}"
        timed_compile = [r for r in rows if r.get("warp_modules_compiled_in_timed_rollouts")]
        rows = [r for r in rows if r not in timed_compile]
        ax.plot(
            [r["num_envs"] for r in rows],
            [r["env_steps_per_s"] for r in rows],
            "o-",
            color=color,
            label=f"mwjax {name}",
        )
        if timed_compile:
            ax.plot(
                [r["num_envs"] for r in timed_compile],
                [r["env_steps_per_s"] for r in timed_compile],
                "o",
                mfc="none",
                color=color,
                label=f"mwjax {name}, Warp compiling in the timed rollout",
            )
        adapter = [r for r in result.get("adapter", []) if r["benchmark"] == name]
        if adapter:
            ax.plot(
                [r["num_envs"] for r in adapter],
                [r["adapter_numpy_env_steps_per_s"] for r in adapter],
                "x:",
                color=color,
                label=f"mwjax {name}, Gymnasium adapter (NumPy)",
            )
        for ref in result.get("reference", []):
            if ref["benchmark"] == name:
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
    ax.set_ylabel("env steps / s")
    ax.grid(alpha=0.3, which="both")
    ax.legend(fontsize=7)
    ax.set_title(
        f"{result['device']}, {result['physics']} physics, commit {result['commit'][:18]}, "
        f"{result['date'][:10]}",
        fontsize=9,
    )
    fig.tight_layout()
    fig.savefig(path, dpi=120)


def merged(paths: list[str]) -> dict:
    """Result files of one device (separate invocations, e.g. one batch size per device call) as
    one result, to plot their curves together; rows of different commits get their own curve."""
    results = [json.loads(Path(path).read_text()) for path in paths]
    for key in ("device", "physics"):
        values = {r[key] for r in results}
        if len(values) > 1:
            raise ValueError(f"--plot-from files differ in {key}: {sorted(values)}")
    commits = list(dict.fromkeys(r["commit"][:7] for r in results))

    def rows(result: dict, key: str) -> list[dict]:
        if len(commits) == 1:
            return result.get(key, [])
        label = f" ({result['commit'][:7]})"
        return [{**row, "benchmark": row["benchmark"] + label} for row in result.get(key, [])]

    return {
        **results[0],
        "commit": ", ".join(commits),
        "date": max(r["date"] for r in results),
        **{
            key: [row for r in results for row in rows(r, key)] for key in ("results", "adapter", "reference")
        },
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sets", nargs="+", default=["MT1:pick-place-v3", "MT10"])
    parser.add_argument("--batch", nargs="+", type=int, default=[1000, 4000])
    parser.add_argument("--steps", type=int, default=500)
    parser.add_argument("--repeats", type=int, default=2)
    parser.add_argument("--physics", choices=["default", "fast"], default="default")
    parser.add_argument("--physics-only", action="store_true", help="time the physics calls alone")
    parser.add_argument("--contacts", type=int, default=None, help="PhysicsConfig.contacts_per_env")
    parser.add_argument(
        "--constraints", type=rows_arg, default=None, help="constraints_per_env: rows or per_scene"
    )
    parser.add_argument(
        "--ccd-pairs", type=rows_arg, default=None, help="ccd_pairs_per_env: slots or per_scene"
    )
    parser.add_argument("--substep-loop", action="store_true", help="PhysicsConfig(unroll_substeps=False)")
    parser.add_argument("--share-traces", action="store_true", help="PhysicsConfig(share_traces=True)")
    parser.add_argument(
        "--graph-mode",
        default=None,
        help="PhysicsConfig.graph_mode: who captures the CUDA graphs (warp, jax, none, warp_staged, ...)",
    )
    parser.add_argument(
        "--no-warmup",
        action="store_true",
        help="time the first rollout too (with a warm Warp kernel cache it costs the same; saves a rollout)",
    )
    parser.add_argument(
        "--vs-reference",
        metavar="PYTHON",
        default=None,
        help="also time metaworld 3.1.1 with this interpreter (a command line)",
    )
    parser.add_argument("--reference-steps", type=int, default=500)
    parser.add_argument("--adapter", action="store_true", help="also time the Gymnasium adapter")
    parser.add_argument("--adapter-steps", type=int, default=50)
    parser.add_argument("--plot", action="store_true", help="save the scaling curve as a PNG")
    parser.add_argument("--jax-cache", metavar="DIR", default=None, help="persistent compilation cache")
    parser.add_argument("--out", default=None, help="JSON path (default: benchmarks/results/...)")
    parser.add_argument(
        "--profile-compile", action="store_true", help="cProfile each step's compile after lowering"
    )
    parser.add_argument(
        "--profile-lowering",
        action="store_true",
        help="cProfile each step's lowering (Python tracing; the lowering figure then includes the profiler)",
    )
    parser.add_argument(
        "--hlo-stats", action="store_true", help="count the compiled step program's instructions per opcode"
    )
    parser.add_argument(
        "--plot-from",
        nargs="+",
        metavar="JSON",
        default=None,
        help="measure nothing: plot these result files (one device) to --out's PNG",
    )
    args = parser.parse_args()
    if args.plot_from:
        if not args.out:
            parser.error("--plot-from needs --out")
        plot(merged(args.plot_from), Path(args.out).with_suffix(".png"))
        print(f"plot -> {Path(args.out).with_suffix('.png')}")
        return
    if args.jax_cache:
        jax.config.update("jax_compilation_cache_dir", args.jax_cache)
        # Cache every program: the defaults skip the ones that compile in under a second.
        jax.config.update("jax_persistent_cache_min_compile_time_secs", 0.0)
        jax.config.update("jax_persistent_cache_min_entry_size_bytes", -1)
    physics = mwjax.PhysicsConfig() if args.physics == "default" else mwjax.PhysicsConfig.fast()
    buffers = {
        "contacts_per_env": args.contacts,
        "constraints_per_env": args.constraints,
        "ccd_pairs_per_env": args.ccd_pairs,
    }
    physics = dataclasses.replace(
        physics,
        graph_mode=args.graph_mode,
        unroll_substeps=not args.substep_loop,
        share_traces=args.share_traces,
        **{k: v for k, v in buffers.items() if v is not None},
    )

    device = jax.devices()[0]
    device_name = getattr(device, "device_kind", str(device))
    today = datetime.datetime.now(datetime.timezone.utc).date().isoformat()
    out = Path(args.out) if args.out else RESULTS / f"throughput-{device_name.replace(' ', '_')}-{today}.json"
    rows, adapter = [], []
    for benchmark in args.sets:
        n_tasks = len(task_names(benchmark))
        for total in args.batch:
            total = total - total % n_tasks
            compile_profile = profile_path(out, "compile", benchmark, total) if args.profile_compile else None
            lowering_profile = (
                profile_path(out, "lowering", benchmark, total) if args.profile_lowering else None
            )
            row = measure(
                benchmark,
                total,
                args.steps,
                args.repeats,
                physics,
                args.physics_only,
                not args.no_warmup,
                compile_profile,
                lowering_profile,
                args.hlo_stats,
            )
            rows.append(row)
            print(
                f"{benchmark:>20} {row['num_envs']:>7} envs  {row['env_steps_per_s']:>12,.0f} env steps/s  "
                f"compile {row['step_compile_s']:.0f}s  rollouts {[round(t) for t in row['rollout_s']]}s  "
                f"state {row['state_bytes_per_env'] / 1024:.0f} KiB/env",
                flush=True,
            )
            if args.adapter:
                timing = measure_adapter(benchmark, total, args.adapter_steps)
                adapter.append(timing)
                print(
                    f"{'':>20} {'':>7}       adapter: "
                    f"{timing['adapter_numpy_env_steps_per_s']:>12,.0f} env steps/s with NumPy, "
                    f"{timing['adapter_jax_env_steps_per_s']:,.0f} with jax arrays "
                    f"({timing['numpy_transfer_ms_per_step']:.2f} ms/step transfer)",
                    flush=True,
                )
    reference = []
    if args.vs_reference:
        for benchmark in args.sets:
            ref = measure_reference(args.vs_reference, benchmark, args.reference_steps)
            best = max(r["env_steps_per_s"] for r in rows if r["benchmark"] == benchmark)
            ref["mwjax_best_env_steps_per_s"] = best
            ref["ratio"] = best / ref["env_steps_per_s"]
            reference.append(ref)
            print(
                f"{benchmark:>20} reference (metaworld 3.1.1, {ref['num_envs']} envs, AsyncVectorEnv, "
                f"{ref['cpu_cores']} cores): {ref['env_steps_per_s']:,.0f} env steps/s; "
                f"mwjax {best:,.0f} = {ref['ratio']:.0f}x",
                flush=True,
            )
    result = {
        "device": device_name,
        "platform": device.platform,
        "host": platform.node(),
        "commit": commit(),
        "date": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds"),
        "physics": args.physics,
        "graph_mode": args.graph_mode,
        "unroll_substeps": physics.unroll_substeps,
        "share_traces": physics.share_traces,
        "contacts_per_env": physics.contacts_per_env,
        "constraints_per_env": physics.constraints_per_env,
        "ccd_pairs_per_env": physics.ccd_pairs_per_env,
        "xla_flags": os.environ.get("XLA_FLAGS"),
        "warmup_rollout": not args.no_warmup,
        "jax": jax.__version__,
        "xla_mem_fraction": os.environ.get("XLA_PYTHON_CLIENT_MEM_FRACTION"),
        "jax_cache": args.jax_cache,
        "results": rows,
        "adapter": adapter,
        "reference": reference,
    }
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(result, indent=2))
    print()
    print(f"{'set':>20} {'envs':>7} {'env steps/s':>14} {'compile s':>10}")
    for row in rows:
        rate, compile_s = row["env_steps_per_s"], row["step_compile_s"]
        print(f"{row['benchmark']:>20} {row['num_envs']:>7} {rate:>14,.0f} {compile_s:>10.1f}")
    print(f"device {result['device']}, commit {result['commit'][:10]}, {result['date']} -> {out}")
    if args.plot:
        plot(result, out.with_suffix(".png"))
        print(f"plot -> {out.with_suffix('.png')}")


if __name__ == "__main__":
    main()
