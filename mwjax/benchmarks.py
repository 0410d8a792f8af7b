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

# The reference's MT50 order (metaworld's ALL_V3_ENVIRONMENTS).
MT50 = (
    "assembly-v3",
    "basketball-v3",
    "bin-picking-v3",
    "box-close-v3",
    "button-press-topdown-v3",
    "button-press-topdown-wall-v3",
    "button-press-v3",
    "button-press-wall-v3",
    "coffee-button-v3",
    "coffee-pull-v3",
    "coffee-push-v3",
    "dial-turn-v3",
    "disassemble-v3",
    "door-close-v3",
    "door-lock-v3",
    "door-open-v3",
    "door-unlock-v3",
    "hand-insert-v3",
    "drawer-close-v3",
    "drawer-open-v3",
    "faucet-open-v3",
    "faucet-close-v3",
    "hammer-v3",
    "handle-press-side-v3",
    "handle-press-v3",
    "handle-pull-side-v3",
    "handle-pull-v3",
    "lever-pull-v3",
    "pick-place-wall-v3",
    "pick-out-of-hole-v3",
    "pick-place-v3",
    "plate-slide-v3",
    "plate-slide-side-v3",
    "plate-slide-back-v3",
    "plate-slide-back-side-v3",
    "peg-insert-side-v3",
    "peg-unplug-side-v3",
    "soccer-v3",
    "stick-push-v3",
    "stick-pull-v3",
    "push-v3",
    "push-wall-v3",
    "push-back-v3",
    "reach-v3",
    "reach-wall-v3",
    "shelf-place-v3",
    "sweep-into-v3",
    "sweep-v3",
    "window-open-v3",
    "window-close-v3",
)

TASK_SETS: dict[str, tuple[str, ...]] = {"MT10": MT10, "MT50": MT50}


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
