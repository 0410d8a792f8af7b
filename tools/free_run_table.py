"""The whole-episode fidelity table: mwjax's free runs beside the engine-only baseline, per task.

For a recording made by `tools/record_episodes.py` (reference episodes) and its engine-only
baseline (`tools/reference_baseline.py`: the reference's code on MuJoCo C 3.17 from the recorded
reset states), mwjax resets to every recorded goal itself and replays the recorded actions open
loop. Per task: per-step success agreement with the reference and the median relative V2 return
error (|G - G_ref| / max(1, |G_ref|)), for mwjax and for the baseline. Runs in mwjax's venv:

    python tools/free_run_table.py --episodes tests/fixtures/episodes \
        --baseline tests/fixtures/episodes_baseline --out benchmarks/results/fidelity
"""

from __future__ import annotations

import argparse
import datetime
import json
import subprocess
import time
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np

import mwjax


def load(directory: Path, task: str) -> dict:
    with np.load(directory / f"{task}.npz") as archive:
        return {key: archive[key] for key in archive.files}


def agreement(ours: np.ndarray, ref: np.ndarray) -> float:
    return float(np.mean(ours == ref))


def return_error(ours: np.ndarray, ref: np.ndarray) -> float:
    """Median over episodes of |G - G_ref| / max(1, |G_ref|) (G: the V2 return), as the test."""
    ours, ref = ours.sum(axis=-1), ref.sum(axis=-1)
    return float(np.median(np.abs(ours - ref) / np.maximum(1.0, np.abs(ref))))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--episodes", type=Path, required=True)
    parser.add_argument("--baseline", type=Path, required=True)
    parser.add_argument("--out", type=Path, required=True)
    parser.add_argument("--tasks", nargs="*", default=None, help="default: every recorded task")
    args = parser.parse_args()
    tasks = args.tasks or sorted(p.stem for p in args.episodes.glob("*-v3.npz"))
    ref = {task: load(args.episodes, task) for task in tasks}
    base = {task: load(args.baseline, task) for task in tasks}
    seed = json.loads(str(ref[tasks[0]]["meta"]))["seed"]
    resets, steps = ref[tasks[0]]["action"].shape[:2]

    start = time.time()
    env = mwjax.make(tasks, envs_per_task=resets, goal_variants={t: ref[t]["rand_vec"] for t in tasks})
    step = jax.jit(env.step)
    state = jax.jit(env.reset_with_variants)(jnp.tile(jnp.arange(resets), len(env.task_list)))
    actions = np.concatenate([ref[task]["action"] for task in env.task_list])
    reward, success = [], []
    for t in range(steps):
        state = step(state, jnp.asarray(actions[:, t]))
        reward.append(np.asarray(state.reward))
        success.append(np.asarray(state.info["success"]))
        if t % 50 == 0:
            print(f"step {t}/{steps} ({time.time() - start:.0f} s)", flush=True)
    reward, success = np.stack(reward, axis=1), np.stack(success, axis=1)

    rows = []
    for task in env.task_list:
        r = env.task_rows(task)
        rows.append(
            {
                "task": task,
                "success_agreement": agreement(success[r], ref[task]["success_v2"]),
                "baseline_success_agreement": agreement(base[task]["success_v2"], ref[task]["success_v2"]),
                "return_error": return_error(reward[r], ref[task]["reward_v2"]),
                "baseline_return_error": return_error(base[task]["reward_v2"], ref[task]["reward_v2"]),
            }
        )
    commit = subprocess.run(
        ["git", "rev-parse", "--short", "HEAD"], capture_output=True, text=True
    ).stdout.strip()
    device = jax.devices()[0]
    device_name = getattr(device, "device_kind", str(device)).replace(" ", "_")
    date = datetime.date.today().isoformat()
    command = (
        "python tools/free_run_table.py "
        f"--episodes {args.episodes} --baseline {args.baseline} --out {args.out}"
    )
    mean = {key: float(np.mean([row[key] for row in rows])) for key in rows[0] if key != "task"}
    lines = [
        f"# Whole-episode fidelity, seed {seed}: mwjax free runs vs the engine-only baseline",
        "",
        f"`{command}`, commit {commit}, {device_name}, {date}. {resets} episodes x {steps} steps per task "
        "(episodes 0-1 random actions, the rest the reference's experts + N(0, 0.1) noise). mwjax: its own "
        "reset to each recorded goal, then the recorded actions, open loop. Baseline: the reference's "
        "code on MuJoCo C 3.17 (3.3.0's engine defaults) from the recorded reset state. Return error: "
        "median over episodes of |G - G_ref| / max(1, |G_ref|), G the V2 return.",
        "",
        "| task | success agreement, mwjax | baseline | return error, mwjax | baseline |",
        "| --- | ---: | ---: | ---: | ---: |",
    ]
    for row in rows:
        lines.append(
            f"| {row['task']} | {row['success_agreement']:.3f} | {row['baseline_success_agreement']:.3f} | "
            f"{row['return_error']:.4f} | {row['baseline_return_error']:.4f} |"
        )
    lines.append(
        f"| **mean** | {mean['success_agreement']:.3f} | {mean['baseline_success_agreement']:.3f} | "
        f"{mean['return_error']:.4f} | {mean['baseline_return_error']:.4f} |"
    )
    args.out.mkdir(parents=True, exist_ok=True)
    name = f"free-run-seed{seed}-{commit}-{device_name}-{date}"
    (args.out / f"{name}.md").write_text("\n".join(lines) + "\n")
    out = {"seed": seed, "commit": commit, "device": device_name, "date": date, "command": command}
    (args.out / f"{name}.json").write_text(json.dumps({**out, "mean": mean, "rows": rows}, indent=1))
    print("\n".join(lines))
    print(f"-> {args.out / name}.md")


if __name__ == "__main__":
    main()
