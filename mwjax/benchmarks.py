"""Meta-World task sets and their goal variants, sampled on the host like the reference.

`metaworld==3.1.1` builds each benchmark's 50 goal variants per task from numpy's global RNG
(`np.random.seed(seed)` once, then per task and per variant one `env.reset()`, whose two
`reset_model` calls each draw `uniform(low, high)` and redraw until the task's constraint holds).
We replay that draw sequence with a seeded `RandomState`, so a seed gives the reference's vectors.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from mwjax.tasks import get_task

N_GOALS = 50

MT10 = (
    "reach-v3",
    "push-v3",
    "pick-place-v3",
    "door-open-v3",
    "drawer-open-v3",
    "drawer-close-v3",
    "button-press-topdown-v3",
    "peg-insert-side-v3",
    "window-open-v3",
    "window-close-v3",
)

TASK_SETS: dict[str, tuple[str, ...]] = {"MT10": MT10}


def task_names(benchmark: str | Sequence[str]) -> tuple[str, ...]:
    """The tasks of a named set ("MT10", "MT1:<task>") or an explicit list of task names."""
    if isinstance(benchmark, str):
        if benchmark.startswith("MT1:"):
            names: tuple[str, ...] = (benchmark[4:],)
        elif benchmark in TASK_SETS:
            names = TASK_SETS[benchmark]
        else:
            known = ", ".join([*TASK_SETS, "MT1:<task>"])
            raise ValueError(f"unknown benchmark {benchmark!r}; known: {known}, or a task list")
    else:
        names = tuple(benchmark)
    if not names:
        raise ValueError("a benchmark needs at least one task")
    if len(set(names)) != len(names):
        raise ValueError(f"duplicate task names in {names}")
    for name in names:
        get_task(name)
    return names


def sample_goal_variants(names: Sequence[str], seed: int, n_goals: int = N_GOALS) -> dict[str, np.ndarray]:
    """The reference's `_make_tasks` draws, task by task in order, from one seeded RNG."""
    rng = np.random.RandomState(seed)
    variants = {}
    for name in names:
        spec = get_task(name)
        low, high = np.asarray(spec.random_low), np.asarray(spec.random_high)
        vecs = []
        for _ in range(n_goals):
            for _reset_model_call in range(2):
                vec = rng.uniform(low, high, size=low.size)
                while not spec.rand_vec_valid(vec):
                    vec = rng.uniform(low, high, size=low.size)
            vecs.append(vec)
        variants[name] = np.stack(vecs)
    return variants
