"""Do Warp's preallocated buffers ever drop anything? Full episodes under stress policies, per task.

Runs every task of a set for whole 500-step episodes at many envs per task under policies chosen
to provoke contacts and constraint rows, and records per task which of Warp's overflow flags any
env raised (`info["physics_overflow"]`) and the most constraint rows any env needed at once
(`Physics.constraint_rows_needed`, counted whether or not they fit). Policies:

  random        uniform actions in [-1, 1]^4 at every step (RL exploration)
  jammed        saturated actions held for 25-100 steps: a random corner of the action cube, or
                straight at the object and down into it, the gripper mostly closed; pushes the hand
                into the table, walls and objects and squeezes whatever is between the fingers
  expert-noise  the scripted expert plus Gaussian noise (sd 0.5), clipped: near-solutions with
                objects grasped, dropped and knocked over

    python benchmarks/stress_buffers.py --set MT50 --envs-per-task 1024 --record

`--part K/N` runs the K-th of N slices of the set's tasks (a set too large to build and run in one
go runs as several processes; `--record` merges them). The tables are written after each policy,
so a run cut short keeps what it finished.

Writes a JSON and a Markdown table to `benchmarks/results/overflow/`; exits non-zero when any env
dropped something. `--record` also writes each scene's peak rows to
`mwjax/models/stress_rows.json`, from which `mwjax.models.constraint_rows` sizes the default
buffers (with a margin), so re-running this after a change of scenes or engine re-sizes them.
"""

from __future__ import annotations

import argparse
import json
import time
from collections.abc import Callable

import jax
import jax.numpy as jnp
import numpy as np
from common import add_set_argument, build_kernels, provenance, result_path, tasks_arg
from mujoco.mjx.third_party.mujoco_warp import OverflowType

import mwjax
from mwjax import policies
from mwjax.benchmarks import task_names
from mwjax.models import MODELS_DIR
from mwjax.physics import DROPPED

POLICIES = ("random", "jammed", "expert-noise")
HOLD = (25, 100)  # the jammed policy holds each action this many steps (a range)
NOISE = 0.5


def flag_names(bits: int) -> str:
    names = [flag.name for flag in OverflowType if flag.name not in ("NONE", "ALL") and bits & flag]
    return ", ".join(names) or "none"


def stress_actions(env: mwjax.Env) -> Callable:
    """`(policy, obs, t, keys) -> actions` for a batch, `policy` an index into `POLICIES`."""
    expert = policies.expert_policy(env)
    n = env.num_envs

    def random(obs: jax.Array, t: jax.Array, keys: jax.Array) -> jax.Array:
        return jax.random.uniform(jax.random.fold_in(keys[0], t), (n, 4), minval=-1.0, maxval=1.0)

    def jammed(obs: jax.Array, t: jax.Array, keys: jax.Array) -> jax.Array:
        # Each env holds an action for a segment of its own length and phase.
        hold = jax.random.randint(keys[1], (n,), *HOLD)
        phase = jax.random.randint(keys[2], (n,), 0, HOLD[1])
        segment = (t + phase) // hold
        seg_keys = jax.vmap(jax.random.fold_in)(jax.random.split(keys[3], n), segment)
        draws = jax.vmap(lambda k: jax.random.uniform(k, (6,)))(seg_keys)
        corner = jnp.where(draws[:, :3] < 0.5, -1.0, 1.0)
        to_object = jnp.sign(obs[:, 4:7] - obs[:, 0:3])
        over_it = jnp.linalg.norm(obs[:, 4:6] - obs[:, 0:2], axis=-1) < 0.03
        to_object = to_object.at[:, 2].set(jnp.where(over_it, -1.0, to_object[:, 2]))
        direction = jnp.where(draws[:, 3:4] < 0.5, corner, to_object)
        grip = jnp.where(draws[:, 4] < 0.7, 1.0, -1.0)
        return jnp.concatenate([direction, grip[:, None]], axis=-1)

    def expert_noise(obs: jax.Array, t: jax.Array, keys: jax.Array) -> jax.Array:
        noise = NOISE * jax.random.normal(jax.random.fold_in(keys[4], t), (n, 4))
        return jnp.clip(expert(None, obs, keys[0]) + noise, -1.0, 1.0)

    branches = [random, jammed, expert_noise]

    def act(policy: jax.Array, obs: jax.Array, t: jax.Array, keys: jax.Array) -> jax.Array:
        return jax.lax.switch(policy, branches, obs, t, keys)

    return act


def part_of(tasks: str | list[str], part: str) -> list[str]:
    """The K-th of N contiguous slices (`part` "K/N") of a set's tasks."""
    k, n = (int(x) for x in part.split("/"))
    if not 1 <= k <= n:
        raise SystemExit(f"--part {part}: K/N with 1 <= K <= N")
    names = list(task_names(tasks) if isinstance(tasks, str) else tasks)
    size = -(-len(names) // n)
    return names[(k - 1) * size : k * size]


def record(table: dict, scenes: dict, args: argparse.Namespace, result: dict, policy: str) -> None:
    """Merge one policy's per-scene peaks into `stress_rows.json` (the most seen by any run: runs
    at other batch sizes or on other devices add to the corpus, never shrink it)."""
    path = MODELS_DIR / "stress_rows.json"
    recorded = json.loads(path.read_text()) if path.exists() else {"scenes": {}, "sources": []}
    for name, scene in scenes.items():
        entry = recorded["scenes"].setdefault(name, {"peak_rows": 0, "by_policy": {}, "tasks": []})
        peak = max(table[task][policy]["peak_rows"] for task in scene["tasks"])
        entry["by_policy"][policy] = max(entry["by_policy"].get(policy, 0), peak)
        entry["peak_rows"] = max(entry["by_policy"].values())
        entry["tasks"] = sorted(set(entry["tasks"]) | set(scene["tasks"]))
    recorded["sources"].append(
        f"{result['command']}: {args.envs_per_task} envs per task, {args.steps} steps, policy "
        f"{policy}, {result['device']}, commit {result['commit'][:7]}, "
        f"{result['date'][:10]}"
    )
    path.write_text(json.dumps(recorded, indent=1, sort_keys=True) + "\n")
    print(f"-> {path}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    add_set_argument(parser, default="MT50")
    parser.add_argument("--envs-per-task", type=int, default=1024)
    parser.add_argument("--steps", type=int, default=500, help="steps per run (500: whole episodes)")
    parser.add_argument("--policies", nargs="+", choices=POLICIES, default=list(POLICIES))
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--part", default="1/1", help="K/N: the K-th of N slices of the set's tasks")
    parser.add_argument("--record", action="store_true", help="write mwjax/models/stress_rows.json")
    args = parser.parse_args()

    t0 = time.perf_counter()
    tasks = part_of(tasks_arg(args.set), args.part)
    build_kernels(tasks)
    env = mwjax.make(tasks, envs_per_task=args.envs_per_task, seed=args.seed)
    act = stress_actions(env)

    def run(policy: jax.Array, key: jax.Array) -> tuple[jax.Array, jax.Array, jax.Array]:
        """One batch of whole episodes; per env, the flags raised, the most rows needed and the
        steps whose physics diverged and was reset (`info["physics_reset"]`)."""
        reset_key, key = jax.random.split(key)
        keys = jax.random.split(key, 5)
        state = env.reset(reset_key)

        def body(carry: tuple, t: jax.Array) -> tuple:
            state, flags, rows, resets = carry
            state = env.step(state, act(policy, state.obs, t, keys))
            flags = flags | state.info["physics_overflow"]
            rows = jnp.maximum(rows, env.physics.constraint_rows_needed(state.physics))
            resets = resets + state.info["physics_reset"]
            return (state, flags, rows, resets), None

        zeros = jnp.zeros(env.num_envs, jnp.int32)
        (_, flags, rows, resets), _ = jax.lax.scan(body, (state, zeros, zeros, zeros), jnp.arange(args.steps))
        return flags, rows, resets

    compiled = jax.jit(run).lower(jnp.int32(0), jax.random.key(0)).compile()
    print(
        f"{args.set}: {env.num_envs} envs, built and compiled in {time.perf_counter() - t0:.0f} s", flush=True
    )
    table: dict[str, dict[str, dict]] = {}
    for i, name in enumerate(args.policies):
        t0 = time.perf_counter()
        key = jax.random.fold_in(jax.random.key(args.seed), i)
        flags, rows, resets = map(
            np.asarray, jax.block_until_ready(compiled(jnp.int32(POLICIES.index(name)), key))
        )
        for task in env.task_list:
            sl = env.task_rows(task)
            table.setdefault(task, {})[name] = {
                "flags": flag_names(int(np.bitwise_or.reduce(flags[sl]))),
                "dropped_envs": int(np.count_nonzero(flags[sl] & int(DROPPED))),
                "peak_rows": int(rows[sl].max()),
                "reset_envs": int(np.count_nonzero(resets[sl])),
                "resets": int(resets[sl].sum()),
            }
        dropped = sum(table[t][name]["dropped_envs"] for t in env.task_list)
        reset = sum(table[t][name]["reset_envs"] for t in env.task_list)
        print(
            f"  {name:<13} {time.perf_counter() - t0:6.1f} s, envs that dropped something: {dropped}, "
            f"envs whose physics diverged and was reset: {reset}",
            flush=True,
        )
        dropped_tasks = report(env, table, args, args.policies[: i + 1])

    if dropped_tasks:
        raise SystemExit(f"envs dropped contacts, rows or collider pairs in: {', '.join(dropped_tasks)}")


def report(env: mwjax.Env, table: dict, args: argparse.Namespace, run: list[str]) -> list[str]:
    """Write the JSON and Markdown tables for the policies `run` so far (`--record`: merge the
    last one's peaks); returns the tasks in which any env dropped something."""
    scenes: dict[str, dict] = {}
    for group in env.physics.groups:
        tasks = [t for t in env.task_list if env.task_rows(t).start < group.start + group.size]
        tasks = [t for t in tasks if env.task_rows(t).start >= group.start]
        peak = max(table[t][p]["peak_rows"] for t in tasks for p in run)
        scene = scenes.setdefault(group.scene, {"peak_rows": 0, "allocated_rows": 0, "tasks": []})
        scene["peak_rows"] = max(scene["peak_rows"], peak)
        scene["allocated_rows"] = env.physics.constraint_rows(group.scene)
        scene["tasks"] += tasks

    result = {
        **provenance(),
        "set": args.set,
        "part": args.part,
        "envs_per_task": args.envs_per_task,
        "steps": args.steps,
        "policies": run,
        "seed": args.seed,
        "tasks": table,
        "scenes": scenes,
    }
    part = "" if args.part == "1/1" else "-part" + args.part.replace("/", "of")
    out = result_path("overflow", f"stress-{args.set.replace(',', '+')}{part}", ".json")
    out.write_text(json.dumps(result, indent=1))
    lines = [
        f"# Warp buffers under stress policies, {args.set} (part {args.part}), "
        f"{args.envs_per_task} envs per task",
        "",
        f"`{result['command']}`, commit {result['commit'][:7]}, {result['device']}, {result['date']}. "
        f"Default physics; {args.steps}-step episodes from reset; per task and policy: the envs that "
        "dropped a contact, constraint row or collider pair, all flags raised, and the most "
        "constraint rows one env needed at once (allocated: the scene's `constraint_rows`); then the "
        "envs whose physics diverged and was reset (`info['physics_reset']`, MuJoCo C's automatic reset).",
        "",
        "| task | " + " | ".join(f"{p}: dropped / flags / peak rows / reset" for p in run) + " | allocated |",
        "| --- | " + " | ".join("---" for _ in run) + " | ---: |",
    ]
    for task in env.task_list:
        cells = [
            f"{c['dropped_envs']} / {c['flags']} / {c['peak_rows']} / {c['reset_envs']}"
            for c in (table[task][p] for p in run)
        ]
        scene = next(s for s in scenes.values() if task in s["tasks"])
        lines.append(f"| {task} | " + " | ".join(cells) + f" | {scene['allocated_rows']} |")
    dropped = [t for t in env.task_list if any(table[t][p]["dropped_envs"] for p in run)]
    diverged = [t for t in env.task_list if any(table[t][p]["reset_envs"] for p in run)]
    lines += [
        "",
        f"Tasks where any env dropped something: {', '.join(dropped) or 'none'}.",
        f"Tasks where any env's physics diverged and was reset: {', '.join(diverged) or 'none'}.",
    ]
    out.with_suffix(".md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))
    print(f"-> {out} (.md)")
    if args.record:
        record(table, scenes, args, result, run[-1])
    return dropped


if __name__ == "__main__":
    main()
