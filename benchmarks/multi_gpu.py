"""Env steps per second of one task set on 1, 2, 4, ... local GPUs (`mwjax.make(..., devices=)`).

    python benchmarks/multi_gpu.py                      # MT50, 1 2 4 GPUs, 1,024 envs per task per GPU
    python benchmarks/multi_gpu.py --set MT1:reach-v3 --envs-per-task 2 --steps 5 --cpu  # smoke run
    python benchmarks/multi_gpu.py --stagger 100 --processes  # one process per GPU

The protocol is `benchmarks/throughput.py`'s: a jitted `lax.scan` rollout of `--steps` (500)
env steps with uniform random actions drawn on device (every env autoresets once), run once to
warm up, then timed `--repeats` times; the best is the figure. Default physics. A row whose
envs overflowed a physics buffer (`info["physics_overflow"]`, Warp dropped contacts or
constraint rows) is flagged `valid: false` and its figure not quoted as throughput.
`--stagger W` is throughput.py's too: episode counters spread over 0..499, a W-step warm-up,
then a W-step timed window in which resets fall at their long-run rate (MT50's documented
protocol, which keeps 1, 2 and 4 GPUs inside one device call).

Scaling is weak by default: every device count gets `--envs-per-task` envs per task *per
device*, so each GPU steps the same batch and perfect scaling doubles the rate with the devices.
`--strong` makes `--envs-per-task` the total instead. One device runs the plain single-device
env (`devices=None`), the others `mwjax.make(..., devices=the first n GPUs)`.

Each device count runs in its own process (a clean GPU, its own Warp graphs). Counts that fit on
disjoint GPUs start together (on 8 GPUs 1 + 2 + 4; on 4, 1 + 2 and then 4), so their compiles
overlap, and take turns (a file lock) for the warm-up and timed rollouts; `--sequential` runs
one count after another, each on GPUs 0..n-1; `--together` starts every count at once, each on
GPUs 0..n-1 (so they share GPUs: JAX's memory fraction is split between them), and only the
rollouts take turns, which fits 1 and 4 GPUs on a 4-GPU machine in one compile's time.
`--processes` runs each count above one as one process per GPU (`python -m mwjax.distributed`):
the same sharded env and rows, but no process launches Warp's work for more than one GPU.
Results: a table, and a JSON file (device names, count, batch, commit, date, command) in
`benchmarks/results/`, whose last stdout line is the summary row.
Set XLA_PYTHON_CLIENT_MEM_FRACTION (~0.45, the default here) so that JAX leaves Warp room.
"""

from __future__ import annotations

import argparse
import contextlib
import datetime
import fcntl
import json
import os
import platform
import shlex
import subprocess
import sys
import tempfile
import time
from collections.abc import Iterator
from pathlib import Path

from common import RESULTS, commit

from mwjax import distributed

# ------------------------------------------------------------------------------------------------
# One device count (a child process)


def measure(args: argparse.Namespace) -> dict:
    import jax
    import jax.numpy as jnp

    import mwjax
    from mwjax.env import staggered
    from mwjax.physics import DROPPED

    n = args.child
    devices = jax.devices()[:n]  # with --processes, every process's GPU
    if len(devices) < n:
        raise SystemExit(f"{n} devices asked for, {len(jax.devices())} visible")
    per_task = args.envs_per_task if args.strong else args.envs_per_task * n
    steps = args.steps if args.stagger is None else args.stagger
    physics = mwjax.PhysicsConfig(graph_mode=args.graph_mode)
    t0 = time.perf_counter()
    env = mwjax.make(
        args.set, envs_per_task=per_task, seed=0, physics=physics, devices=devices if n > 1 else None
    )
    build_s = time.perf_counter() - t0

    def rollout(state: mwjax.State, key: jax.Array) -> tuple:
        def body(carry: tuple, key: jax.Array) -> tuple:
            state, successes, overflowed = carry
            action = jax.random.uniform(key, (env.num_envs, 4), minval=-1.0, maxval=1.0)
            state = env.step(state, action)
            dropped = (state.info["physics_overflow"] & int(DROPPED)) != 0
            return (state, successes + state.info["success"].sum(), overflowed | dropped), None

        init = (state, jnp.zeros((), jnp.int32), jnp.zeros(env.num_envs, bool))
        (state, successes, overflowed), _ = jax.lax.scan(body, init, jax.random.split(key, steps))
        return state, successes, overflowed.sum()

    t0 = time.perf_counter()
    state = jax.block_until_ready(jax.jit(env.reset)(jax.random.key(0)))
    reset_compile_s = time.perf_counter() - t0
    if args.stagger is not None:
        state = staggered(state, env.max_episode_steps, jax.random.key(1))
    t0 = time.perf_counter()
    compiled = jax.jit(rollout, donate_argnums=0).lower(state, jax.random.key(1)).compile()
    compile_s = time.perf_counter() - t0
    print(f"[{n} device(s)] {env.num_envs} envs: compiled in {compile_s:.0f}s", file=sys.stderr, flush=True)

    with rollout_turn(args.lock, n):  # the rollouts of different counts never overlap
        t0 = time.perf_counter()
        state, _, overflow = jax.block_until_ready(compiled(state, jax.random.key(1)))
        warmup_s = time.perf_counter() - t0
        print(f"[{n} device(s)] warm-up rollout: {warmup_s:.2f}s", file=sys.stderr, flush=True)
        overflow_envs = int(overflow)
        times = []
        for i in range(args.repeats):
            t0 = time.perf_counter()
            state, successes, overflow = jax.block_until_ready(compiled(state, jax.random.key(2 + i)))
            times.append(time.perf_counter() - t0)
            print(
                f"[{n} device(s)] timed rollout: {times[-1]:.2f}s, "
                f"{env.num_envs * steps / times[-1]:,.0f} env steps/s",
                file=sys.stderr,
                flush=True,
            )
            overflow_envs = max(overflow_envs, int(overflow))
    rate = env.num_envs * steps / min(times)
    return {
        "benchmark": args.set,
        "devices": n,
        "device_names": [getattr(d, "device_kind", str(d)) for d in devices],
        "platform": devices[0].platform,
        "num_envs": env.num_envs,
        "envs_per_device": env.num_envs // n,
        "steps_per_rollout": steps,
        "stagger": args.stagger,
        "env_steps_per_s": rate,
        "env_steps_per_s_per_device": rate / n,
        "rollout_s": times,
        "warmup_rollout_s": warmup_s,
        "build_s": build_s,
        "reset_compile_s": reset_compile_s,
        "step_compile_s": compile_s,
        "success_steps_last_rollout": int(successes),
        # Comparable across counts (random actions): a sanity check that every count simulates alike.
        "success_steps_per_env": int(successes) / env.num_envs,
        "overflow_envs": overflow_envs,
        "valid": overflow_envs == 0,
        "processes": jax.process_count(),
        "jax": jax.__version__,
    }


@contextlib.contextmanager
def rollout_turn(lock_path: str, n: int) -> Iterator[None]:
    """This count's turn at the GPUs: its (first) process holds the file lock; with one process
    per GPU, the others wait on the host until it does. (A device barrier would keep their GPUs
    busy spinning, beside another count's rollout on a shared GPU.)"""
    import jax

    go = Path(f"{lock_path}.{n}")
    with open(lock_path) as lock:
        if jax.process_index() == 0:
            fcntl.flock(lock, fcntl.LOCK_EX)
            go.touch()
        while not go.exists():
            time.sleep(0.05)
        try:
            yield
        finally:
            if jax.process_index() == 0:  # the others have seen `go`: the rollouts' sums join them
                go.unlink()


# ------------------------------------------------------------------------------------------------
# The parent: one child per device count


def side_by_side(counts: list[int], gpus: int) -> list[list[int]]:
    """The counts in waves whose processes run at once on disjoint GPUs: packed largest first,
    each wave taking every count left that still fits beside it; the smallest counts run first."""
    left, waves = sorted(counts, reverse=True), []
    while left:
        wave = [left.pop(0)]
        for n in list(left):
            if sum(wave) + n <= gpus:
                wave.append(n)
                left.remove(n)
        waves.append(sorted(wave))
    return waves[::-1]


def mem_fraction(sharing: int) -> str:
    """JAX's memory fraction in each child: XLA_PYTHON_CLIENT_MEM_FRACTION (default 0.45), the
    share of a GPU that JAX should take, split between the `sharing` processes on the busiest GPU
    (each child's JAX would otherwise take the whole share and leave its neighbours nothing)."""
    total = float(os.environ.get("XLA_PYTHON_CLIENT_MEM_FRACTION", "0.45"))
    return f"{total / sharing:.3f}"


def child_env(args: argparse.Namespace, gpus: list[int], n: int, sharing: int) -> dict:
    """A child's environment; `sharing` processes share its busiest GPU."""
    env = dict(os.environ)
    env["XLA_PYTHON_CLIENT_MEM_FRACTION"] = mem_fraction(sharing)
    if args.cpu:
        env["JAX_PLATFORMS"] = "cpu"
        env["XLA_FLAGS"] = f"{env.get('XLA_FLAGS', '')} --xla_force_host_platform_device_count={n}".strip()
    else:
        env["CUDA_VISIBLE_DEVICES"] = ",".join(str(g) for g in gpus)
    return env


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--set", default="MT50", help="a set name (MT50, MT1:<task>, ...)")
    parser.add_argument("--devices", type=int, nargs="+", default=[1, 2, 4], help="device counts")
    parser.add_argument(
        "--envs-per-task", type=int, default=1024, help="per task and device (with --strong: in total)"
    )
    parser.add_argument("--strong", action="store_true", help="the same total batch on every count")
    parser.add_argument("--steps", type=int, default=500)
    parser.add_argument("--repeats", type=int, default=1)
    parser.add_argument(
        "--stagger", type=int, metavar="W", default=None, help="staggered episodes, W-step window"
    )
    parser.add_argument("--graph-mode", default=None, help="PhysicsConfig.graph_mode (warp, jax, none)")
    parser.add_argument("--cpu", action="store_true", help="host devices instead of GPUs (a smoke run)")
    parser.add_argument(
        "--sequential", action="store_true", help="one count after another even if they fit side by side"
    )
    parser.add_argument(
        "--together", action="store_true", help="every count at once on shared GPUs, rollouts in turn"
    )
    parser.add_argument(
        "--processes",
        action="store_true",
        help="run each count above 1 as one process per GPU (python -m mwjax.distributed)",
    )
    parser.add_argument("--out", default=None, help="JSON path (default: benchmarks/results/...)")
    parser.add_argument("--child", type=int, default=None, help=argparse.SUPPRESS)
    parser.add_argument("--lock", default=None, help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.child is not None:
        distributed.initialize()
        row = json.dumps(measure(args))
        if distributed.is_main():
            # On stderr too, which a log keeps even if the parent dies before writing its JSON.
            print(f"[{args.child} device(s)] result: {row}", file=sys.stderr, flush=True)
            print(row, flush=True)
        return

    counts = sorted(set(args.devices))
    available = max(counts) if args.cpu else len(distributed.visible_gpus())
    if not args.cpu and available == 0:
        sys.exit("no NVIDIA GPU visible (--cpu runs on host devices)")
    skipped = [n for n in counts if n > available]
    counts = [n for n in counts if n <= available]
    if skipped:
        print(f"skipping device counts {skipped}: {available} GPU(s) visible", flush=True)
    if args.strong and any(args.envs_per_task % n for n in counts):
        sys.exit(f"--strong: --envs-per-task {args.envs_per_task} must split evenly over {counts} devices")
    if args.stagger is not None and not 1 <= args.stagger <= 500:
        parser.error("--stagger must be in [1, 500]")
    if args.together and (args.cpu or args.sequential):
        sys.exit("--together shares GPUs: not with --cpu or --sequential")
    sharing = len(counts) if args.together else 1
    if args.together:
        waves = [counts]
    elif args.cpu or args.sequential:
        waves = [[n] for n in counts]
    else:
        waves = side_by_side(counts, available)

    script = Path(__file__).resolve()
    forwarded = ["--set", args.set, "--envs-per-task", str(args.envs_per_task), "--steps", str(args.steps)]
    forwarded += ["--repeats", str(args.repeats)] + (["--strong"] if args.strong else [])
    forwarded += ["--graph-mode", args.graph_mode] if args.graph_mode else []
    forwarded += ["--stagger", str(args.stagger)] if args.stagger is not None else []
    start = time.perf_counter()
    rows = []
    with tempfile.NamedTemporaryFile(prefix="mwjax-multi-gpu-", suffix=".lock") as lock:
        outputs = {}
        for wave in waves:
            procs, first = {}, 0
            for n in wave:
                command = [str(script), *forwarded, "--child", str(n), "--lock", lock.name]
                if args.processes and n > 1:
                    launcher = ["-m", "mwjax.distributed", "--processes", str(n)]
                    command = launcher + (["--cpu"] if args.cpu else []) + command
                command = [sys.executable, *command]
                gpus = list(range(n)) if args.together else list(range(first, first + n))
                procs[n] = subprocess.Popen(
                    command, env=child_env(args, gpus, n, sharing), stdout=subprocess.PIPE, text=True
                )
                first += n
            outputs |= {n: (p.communicate()[0], p.returncode) for n, p in procs.items()}
    for n, (stdout, code) in sorted(outputs.items()):
        if code:
            print(f"{n} device(s): the run failed (exit {code})", flush=True)
            continue
        rows.append(json.loads(stdout.strip().splitlines()[-1]))

    base = next((r for r in rows if r["devices"] == 1), None)
    for row in rows:
        row["scaling"] = row["env_steps_per_s"] / base["env_steps_per_s"] if base else None
        row["efficiency"] = row["scaling"] / row["devices"] if base else None
    names = sorted({name for r in rows for name in r["device_names"]})
    device = names[0] if len(names) == 1 else ", ".join(names) or "none"
    now = datetime.datetime.now(datetime.timezone.utc)
    summary = {
        "benchmark": args.set,
        "device": device,
        "device_counts": [r["devices"] for r in rows],
        "num_envs": [r["num_envs"] for r in rows],
        "env_steps_per_s": [r["env_steps_per_s"] for r in rows],
        "scaling": [r["scaling"] for r in rows],
        "valid": all(r["valid"] for r in rows) and len(rows) == len(counts),
        "weak_scaling": not args.strong,
        "stagger": args.stagger,
        "waves": waves,
        "together": args.together,
        "processes": args.processes,
        "commit": commit(),
        "date": now.isoformat(timespec="seconds"),
        "host": platform.node(),
        "command": shlex.join([sys.executable, *sys.argv]),
        "xla_mem_fraction": mem_fraction(sharing),
        "graph_mode": args.graph_mode,
        "wall_s": time.perf_counter() - start,
        "results": rows,
    }
    stem = f"multi-gpu-{args.set.replace(':', '-')}-{summary['commit'][:7]}-{device}-{now.date()}"
    out = Path(args.out) if args.out else RESULTS / "throughput" / f"{stem.replace(' ', '_')}.json"
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(summary, indent=2))

    header = ("devices", "envs", "env steps/s", "per device", "scaling", "compile s")
    print("\n" + " ".join(f"{h:>{w}}" for h, w in zip(header, (8, 9, 14, 12, 8, 10), strict=True)))
    for r in rows:
        scaling = f"{r['scaling']:.2f}x" if r["scaling"] else "n/a"
        flag = "" if r["valid"] else f"  OVERFLOW in {r['overflow_envs']} envs: not a throughput figure"
        print(
            f"{r['devices']:>8} {r['num_envs']:>9} {r['env_steps_per_s']:>14,.0f} "
            f"{r['env_steps_per_s_per_device']:>12,.0f} {scaling:>8} {r['step_compile_s']:>10.0f}{flag}"
        )
    print(f"{device}, commit {summary['commit'][:10]}, {summary['date']} -> {out}")
    print(json.dumps({k: v for k, v in summary.items() if k != "results"}), flush=True)


if __name__ == "__main__":
    main()
