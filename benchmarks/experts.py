"""The jax scripted experts on every task, by the evaluation protocol, against the reference.

Runs `mwjax.evaluation.evaluator` with `mwjax.policies.expert_policy` on a task set (MT50 by
default) at the reference experts' setting: every task's own `MT1(task, seed=42)` goal variants
(the reference ran each task as MT1), one episode per variant (50 per task), up to 500 steps,
success at any step. All episodes of all tasks run in one jitted
scan. Compares each task with the serial reference run recorded by
`tools/record_expert_success.py` (`benchmarks/results/reference/reference-experts-seed42.json`) and
writes a JSON and a Markdown table to `benchmarks/results/experts/`.

    XLA_PYTHON_CLIENT_MEM_FRACTION=0.45 python benchmarks/experts.py
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import jax
import numpy as np
from common import add_set_argument, build_kernels, provenance, rows_arg, tasks_arg

import mwjax
from mwjax import policies
from mwjax.benchmarks import mt1_goal_variants, task_names
from mwjax.evaluation import evaluator

RESULTS = Path(__file__).parent / "results" / "experts"
TOLERANCE = 0.04  # the bar: every task within 0.04 below the reference


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    add_set_argument(parser, default="MT50")
    parser.add_argument(
        "--contacts", type=int, default=None, help="contacts_per_env (default: PhysicsConfig's)"
    )
    parser.add_argument(
        "--constraints", type=rows_arg, default=None, help="constraints_per_env: rows or per_scene"
    )
    parser.add_argument(
        "--box-box", default=None, choices=["box_box", "convex"], help="PhysicsConfig.box_box_collider"
    )
    parser.add_argument("--seed", type=int, default=42)
    parser.add_argument(
        "--goals",
        choices=["mt1", "set"],
        default="mt1",
        help="each task's own MT1 goal variants, as the reference's expert runs use (default), "
        "or those the task set itself draws (MT50's differ for every task but the first)",
    )
    parser.add_argument("--episodes", type=int, default=50)
    parser.add_argument(
        "--once",
        action="store_true",
        help="run the program once (its time then includes Warp's first-call work)",
    )
    parser.add_argument(
        "--reference", default=str(RESULTS.parent / "reference" / "reference-experts-seed42.json")
    )
    args = parser.parse_args()
    reference = json.loads(Path(args.reference).read_text())

    buffers = {
        "contacts_per_env": args.contacts,
        "constraints_per_env": args.constraints,
        "box_box_collider": args.box_box,
    }
    physics = mwjax.PhysicsConfig(**{k: v for k, v in buffers.items() if v is not None})
    tasks = tasks_arg(args.set)
    variants = None
    if args.goals == "mt1":
        variants = mt1_goal_variants(task_names(tasks), args.seed)
    build_kernels(tasks, physics)
    env = mwjax.make(tasks, seed=args.seed, physics=physics, goal_variants=variants)
    policy = policies.expert_policy(env.replace(envs_per_task=args.episodes))
    run = jax.jit(evaluator(env, policy, args.episodes))
    t0 = time.perf_counter()
    compiled = run.lower(None, jax.random.key(0)).compile()
    compile_s = time.perf_counter() - t0
    t0 = time.perf_counter()
    first = jax.block_until_ready(compiled(None, jax.random.key(0)))
    first_s = time.perf_counter() - t0
    result, run_s = first, first_s
    if not args.once:
        t0 = time.perf_counter()
        result = jax.block_until_ready(compiled(None, jax.random.key(0)))
        run_s = time.perf_counter() - t0

    # Counted on the host in float64, so that e.g. 48/50 compares exactly against 1.00 - 0.04.
    success = np.asarray(result.success)
    dropped = np.asarray(first.dropped) | np.asarray(result.dropped)
    per_task = success.astype(np.float64).mean(axis=1)
    rates = {t: float(r) for t, r in zip(env.task_list, per_task, strict=True)}
    # The same program twice: on a GPU the runs may differ (contact order), so both are kept.
    first_success = np.asarray(first.success)
    rows = []
    for i, task in enumerate(env.task_list):
        ref = reference["success_rate"][task]
        rows.append(
            {
                "task": task,
                "mwjax": rates[task],
                "reference": ref,
                "ok": rates[task] >= ref - TOLERANCE,
                "failed_goals": np.flatnonzero(~success[i]).tolist(),
                "first_run": float(first_success[i].astype(np.float64).mean()),
                "first_run_failed_goals": np.flatnonzero(~first_success[i]).tolist(),
                "overflow_episodes": int(dropped[i].sum()),
            }
        )
    out = {
        **provenance(),
        "set": args.set,
        "physics": str(physics),
        "seed": args.seed,
        "goals": args.goals,
        "episodes_per_task": args.episodes,
        "num_envs": args.episodes * len(env.task_list),
        "mean_success_rate": float(np.mean(list(rates.values()))),
        "reference_mean_success_rate": float(np.mean([r["reference"] for r in rows])),
        "all_within_tolerance": all(r["ok"] for r in rows),
        # Episodes in which Warp dropped a contact, row or collider pair (either run).
        "overflow_episodes": int(dropped.sum()),
        "compile_s": compile_s,
        "first_run_s": first_s,
        "run_s": run_s,
        "reference_wall_s": reference["wall_seconds"],
        "reference_machine": reference["machine"],
        "rows": rows,
    }
    label = args.set if "," not in args.set else f"{len(env.task_list)}tasks"
    if args.goals == "set":
        label += "-setgoals"
    if args.contacts or args.constraints:
        label += f"-buffers{physics.contacts_per_env}x{physics.constraints_per_env}"
    if args.box_box:
        label += f"-{args.box_box}"
    name = f"experts-{label}-{out['commit'][:7]}-{out['device'].replace(' ', '_')}-{out['date'][:10]}"
    (RESULTS / f"{name}.json").write_text(json.dumps(out, indent=1))
    lines = [
        f"# Scripted experts on {args.set}: mwjax vs metaworld 3.1.1",
        "",
        f"{out['device']}, commit {out['commit'][:10]}, {out['date']}; seed {args.seed}, "
        f"{args.episodes} episodes per task (one per goal variant), 500 steps, success at any step.",
        "Goal variants: "
        + (
            "each task's own `MT1(task, seed)` variants, the reference run's."
            if args.goals == "mt1"
            else f"those `{args.set}` draws (task by task from one RNG); the reference run used MT1's."
        ),
        f"mwjax: {out['num_envs']} episodes in one jitted scan, {run_s:.1f} s (compile {compile_s:.0f} s). "
        f"Reference: serial, {reference['wall_seconds']:.0f} s on {reference['machine']}.",
        "",
        f"Mean success: mwjax {out['mean_success_rate']:.3f}, "
        f"reference {out['reference_mean_success_rate']:.3f} (same tasks). Episodes in which Warp "
        f"dropped a contact, constraint row or collider pair: {out['overflow_episodes']}.",
        "",
        "| task | mwjax | reference | within 0.04 | failed goals | first run (same program) |",
        "| --- | --- | --- | --- | --- | --- |",
        *[
            f"| {r['task']} | {r['mwjax']:.2f} | {r['reference']:.2f} | {'yes' if r['ok'] else 'NO'} "
            f"| {r['failed_goals']} | {r['first_run']:.2f} |"
            for r in rows
        ],
    ]
    (RESULTS / f"{name}.md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    main()
