"""Two training recipes compared over their seeds, e.g. V1 against V2 rewards: per-task mean
success, IQM and mean with 95% stratified-bootstrap CIs, and the probability of improvement
P(B > A) with its CI (`mwjax.stats`, the statistics Meta-World+ reports), as a Markdown table.

    python tools/compare_runs.py A.json B.json

A and B are JSONs the training examples wrote (`--out`, or a `--combine` summary): their runs'
per-task scores (`eval_success_per_task`, or the RL² example's `meta_test_success_per_task`)
over the same tasks. The recipes are named by the settings in which they differ.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

from mwjax import stats

SCORE_KEYS = ("eval_success_per_task", "meta_test_success_per_task")


def scores(path: Path) -> tuple[list[str], np.ndarray, list[dict]]:
    """(tasks, scores `(runs, tasks)`, the runs' configs) of one results JSON."""
    runs = json.loads(path.read_text())["runs"]
    key = next((k for k in SCORE_KEYS if k in runs[0]), None)
    if key is None:
        raise ValueError(f"{path}: its runs have none of {', '.join(SCORE_KEYS)}")
    tasks = list(runs[0][key])
    if any(list(run[key]) != tasks for run in runs):
        raise ValueError(f"{path}: its runs score different tasks")
    return tasks, np.array([[run[key][t] for t in tasks] for run in runs]), [run["config"] for run in runs]


def names(config_a: dict, config_b: dict) -> tuple[str, str]:
    """Each recipe as the settings in which it differs from the other (seed aside)."""
    differ = sorted(
        k for k in config_a.keys() | config_b.keys() if k != "seed" and config_a.get(k) != config_b.get(k)
    )
    if not differ:
        return "A", "B"
    return tuple(", ".join(f"{k}={c.get(k)}" for k in differ) for c in (config_a, config_b))


def compare(path_a: Path, path_b: Path, reps: int = 2000) -> str:
    tasks_a, a, configs_a = scores(path_a)
    tasks_b, b, configs_b = scores(path_b)
    if tasks_a != tasks_b:
        raise ValueError(f"the files score different tasks: {tasks_a} and {tasks_b}")
    name_a, name_b = names(configs_a[0], configs_b[0])
    lines = [
        f"| task | A: {name_a} ({len(a)} seeds) | B: {name_b} ({len(b)} seeds) |",
        "| --- | ---: | ---: |",
        *(
            f"| {task} | {ma:.2f} | {mb:.2f} |"
            for task, ma, mb in zip(tasks_a, a.mean(0), b.mean(0), strict=True)
        ),
    ]
    for statistic in ("mean", "iqm"):
        cells = []
        for s in (a, b):
            e = stats.stratified_bootstrap_ci(s, statistic, reps=reps)
            cells.append(f"{e.value:.3f} [{e.low:.3f}, {e.high:.3f}]")
        lines.append(
            f"| **{statistic.upper() if statistic == 'iqm' else statistic}** (95% CI) | {' | '.join(cells)} |"
        )
    p = stats.probability_of_improvement(b, a, reps=reps)
    lines += ["", f"P(B > A) = {p.value:.3f}, 95% CI [{p.low:.3f}, {p.high:.3f}] (0.5: neither is better)"]
    return "\n".join(lines)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("a", type=Path, help="the first recipe's results JSON")
    parser.add_argument("b", type=Path, help="the second recipe's results JSON")
    parser.add_argument("--reps", type=int, default=2000, help="bootstrap resamples")
    args = parser.parse_args()
    try:
        print(compare(args.a, args.b, args.reps))
    except (OSError, ValueError, KeyError) as error:
        sys.exit(f"compare_runs: {error}")


if __name__ == "__main__":
    main()
