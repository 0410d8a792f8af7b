#!/usr/bin/env python
"""The most constraint rows (`data.nefc`) and contacts (`data.ncon`) MuJoCo C reaches per env
under the reference scripted experts: what `PhysicsConfig.constraints_per_env` has to hold.

Runs in the reference venv (see tools/README_reference.md); never imports mwjax. For each task:
`gym.make("Meta-World/MT1", env_name=task, seed=0)`, 3 episodes of 300 expert steps.

    .venv-ref/bin/python tools/reference_constraint_rows.py
        # -> benchmarks/results/reference-constraint-rows-cpu-<date>.md
"""

from __future__ import annotations

import argparse
import datetime
from pathlib import Path

import gymnasium as gym
import metaworld  # noqa: F401  (registers the Meta-World/ ids)
import mujoco
from metaworld.policies import ENV_POLICY_MAP

TASKS = (
    "peg-insert-side-v3", "sweep-into-v3", "soccer-v3", "hand-insert-v3",
    "basketball-v3", "pick-place-v3", "assembly-v3", "box-close-v3",
)  # fmt: skip


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--tasks", nargs="+", default=list(TASKS))
    parser.add_argument("--episodes", type=int, default=3)
    parser.add_argument("--steps", type=int, default=300)
    args = parser.parse_args()
    date = datetime.date.today().isoformat()
    lines = [
        f"# Constraint rows and contacts per env under the reference experts (MuJoCo C {mujoco.__version__})",
        "",
        f"`tools/reference_constraint_rows.py`, metaworld 3.1.1, seed 0, {args.episodes} episodes of "
        f"{args.steps} steps, CPU, {date}.",
        "",
        "| task | max constraint rows | max contacts |",
        "| --- | ---: | ---: |",
    ]
    for task in args.tasks:
        env = gym.make("Meta-World/MT1", env_name=task, seed=0)
        policy, data = ENV_POLICY_MAP[task](), env.unwrapped.data
        rows = contacts = 0
        for _ in range(args.episodes):
            obs, _ = env.reset()
            for _ in range(args.steps):
                obs, *_ = env.step(policy.get_action(obs))
                rows, contacts = max(rows, data.nefc), max(contacts, data.ncon)
        lines.append(f"| {task} | {rows} | {contacts} |")
        print(lines[-1], flush=True)
    out = Path(__file__).parents[1] / "benchmarks" / "results" / f"reference-constraint-rows-cpu-{date}.md"
    out.write_text("\n".join(lines) + "\n")
    print(f"-> {out}")


if __name__ == "__main__":
    main()
