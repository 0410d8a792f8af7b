"""Which of Warp's overflow flags a rollout raises, per task: does any env drop contacts,
constraint rows or convex-collider pairs (the `PhysicsConfig` buffers) under the experts or
under random actions? Writes a Markdown table to `benchmarks/results/overflow/`.

    python benchmarks/overflow_check.py --set MT50 --envs-per-task 1 --steps 200 --policy expert

One env per task is the hardest case for the pooled buffers (contacts, convex-collider slots):
no other env's spare room to overflow into.
"""

from __future__ import annotations

import argparse
import datetime
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
from mujoco.mjx.third_party.mujoco_warp import OverflowType
from throughput import commit, tasks_arg

import mwjax
from mwjax import policies
from mwjax.physics import DROPPED

RESULTS = Path(__file__).parent / "results" / "overflow"


def flag_names(bits: int) -> str:
    names = [flag.name for flag in OverflowType if flag.name not in ("NONE", "ALL") and bits & flag]
    return ", ".join(names) or "none"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--set", default="MT50", help="a set name, or task names separated by commas")
    parser.add_argument("--envs-per-task", type=int, default=1)
    parser.add_argument("--steps", type=int, default=200)
    parser.add_argument("--policy", choices=["expert", "random"], default="expert")
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    env = mwjax.make(tasks_arg(args.set), envs_per_task=args.envs_per_task, seed=args.seed)
    expert = policies.expert_policy(env)

    def body(state: mwjax.State, key: jax.Array) -> tuple[mwjax.State, tuple[jax.Array, jax.Array]]:
        if args.policy == "expert":
            action = jnp.clip(expert(None, state.obs, key), -1.0, 1.0)
        else:
            action = jax.random.uniform(key, (env.num_envs, 4), minval=-1.0, maxval=1.0)
        state = env.step(state, action)
        return state, (state.info["physics_overflow"], state.info["success"])

    run = jax.jit(lambda state, key: jax.lax.scan(body, state, jax.random.split(key, args.steps)))
    state = jax.jit(env.reset)(jax.random.key(args.seed))
    _, (flags, success) = jax.block_until_ready(run(state, jax.random.key(args.seed + 1)))
    flags = np.bitwise_or.reduce(np.asarray(flags), axis=0)
    success = np.asarray(success).any(axis=0)

    device = jax.devices()[0]
    device_name = getattr(device, "device_kind", str(device)).replace(" ", "_")
    date = datetime.date.today().isoformat()
    revision = commit()[:7]
    lines = [
        f"# Warp overflow flags, {args.set}, {args.policy} actions",
        "",
        f"`benchmarks/overflow_check.py --set {args.set} --envs-per-task {args.envs_per_task} "
        f"--steps {args.steps} --policy {args.policy} --seed {args.seed}`, commit {revision}, "
        f"{device_name}, {date}. Default physics (`PhysicsConfig()`); flags raised in any env of "
        "the task at any step; success: at any step, in any env of the task.",
        "",
        "| task | success | flags | a buffer dropped something |",
        "| --- | --- | --- | --- |",
    ]
    dropped_tasks = []
    for task in env.task_list:
        rows = env.task_rows(task)
        bits = int(np.bitwise_or.reduce(flags[rows]))
        dropped = bool(bits & DROPPED)
        dropped_tasks += [task] if dropped else []
        lines.append(f"| {task} | {bool(success[rows].any())} | {flag_names(bits)} | {dropped} |")
    lines += ["", f"Tasks with a dropped contact, row or CCD pair: {', '.join(dropped_tasks) or 'none'}."]
    out = RESULTS / f"overflow-{args.set.replace(',', '+')}-{args.policy}-{revision}-{device_name}-{date}.md"
    out.write_text("\n".join(lines) + "\n")
    print("\n".join(lines))
    print(f"-> {out}")


if __name__ == "__main__":
    main()
