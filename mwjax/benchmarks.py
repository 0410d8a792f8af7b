"""Meta-World task sets and their goal variants, sampled on the host like the reference.

`metaworld==3.1.1` builds each benchmark's 50 goal variants per task from numpy's global RNG
(`np.random.seed(seed)` once, then per task and per variant one `env.reset()`, whose two
`reset_model` calls each draw `uniform(low, high)` and redraw until the task's constraint holds).
We replay that draw sequence with a seeded `RandomState`, so a seed gives the reference's vectors.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence

import numpy as np

from mwjax.tasks import TASKS, get_task

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

# The reference's ML splits (metaworld.env_dict). ML25 lists basketball-v3 in both of its splits
# in the reference; we keep its lists as they are (see README).
ML10_TRAIN = (
    "reach-v3",
    "push-v3",
    "pick-place-v3",
    "door-open-v3",
    "drawer-close-v3",
    "button-press-topdown-v3",
    "peg-insert-side-v3",
    "window-open-v3",
    "sweep-v3",
    "basketball-v3",
)
ML10_TEST = ("drawer-open-v3", "door-close-v3", "shelf-place-v3", "sweep-into-v3", "lever-pull-v3")
MT25 = MT10 + (
    "coffee-pull-v3",
    "pick-out-of-hole-v3",
    "disassemble-v3",
    "pick-place-wall-v3",
    "basketball-v3",
    "stick-pull-v3",
    "button-press-wall-v3",
    "faucet-open-v3",
    "door-lock-v3",
    "lever-pull-v3",
    "sweep-into-v3",
    "faucet-close-v3",
    "coffee-button-v3",
    "button-press-topdown-wall-v3",
    "dial-turn-v3",
)
ML25_TRAIN = MT25
ML25_TEST = ("basketball-v3", "door-close-v3", "shelf-place-v3", "sweep-v3", "button-press-v3")
ML45_TEST = ("bin-picking-v3", "box-close-v3", "hand-insert-v3", "door-lock-v3", "door-unlock-v3")
# The reference's ML45 train order is MT50's with a few neighbours swapped.
ML45_TRAIN = (
    "assembly-v3",
    "basketball-v3",
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
    "door-open-v3",
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
    "push-back-v3",
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
    "push-wall-v3",
    "push-v3",
    "reach-wall-v3",
    "reach-v3",
    "shelf-place-v3",
    "sweep-into-v3",
    "sweep-v3",
    "window-open-v3",
    "window-close-v3",
)


@dataclasses.dataclass(frozen=True)
class Benchmark:
    """A task set: its train tasks, its test tasks (empty for MT sets), and whether it is a
    meta-learning set (goals hidden from observations, goals fixed until explicitly resampled)."""

    name: str
    train: tuple[str, ...]
    test: tuple[str, ...] = ()
    meta_learning: bool = False
    # The reference samples ML1's test goals with `seed + 1` and every other split with `seed`.
    test_seed_offset: int = 0

    def tasks(self, split: str) -> tuple[str, ...]:
        if split not in ("train", "test"):
            raise ValueError(f"split must be 'train' or 'test', got {split!r}")
        if split == "test" and not self.test:
            raise ValueError(f"{self.name} has no test split")
        return self.train if split == "train" else self.test


_NAMED = {
    "MT10": Benchmark("MT10", MT10),
    "MT25": Benchmark("MT25", MT25),
    "MT50": Benchmark("MT50", MT50),
    "ML10": Benchmark("ML10", ML10_TRAIN, ML10_TEST, meta_learning=True),
    "ML25": Benchmark("ML25", ML25_TRAIN, ML25_TEST, meta_learning=True),
    "ML45": Benchmark("ML45", ML45_TRAIN, ML45_TEST, meta_learning=True),
}
BENCHMARKS = ("MT1", *_NAMED, "ML1")


def benchmark(name: str | Sequence[str] | Benchmark, task: str | None = None) -> Benchmark:
    """The task set `name`: "MT1"/"ML1" (with `task=`), "MT10", "MT25", "MT50", "ML10", "ML25",
    "ML45", "MT1:<task>", a list of task names (a custom MT set), or a `Benchmark` (e.g. from
    `custom_ml`)."""
    if isinstance(name, Benchmark):
        bench = name
    elif isinstance(name, str) and name in ("MT1", "ML1"):
        if task is None:
            raise ValueError(f"{name} needs task=<task name>")
        _check_tasks((task,))
        meta = name == "ML1"
        bench = Benchmark(
            name, (task,), (task,) if meta else (), meta_learning=meta, test_seed_offset=int(meta)
        )
    elif isinstance(name, str) and name.startswith("MT1:"):
        return benchmark("MT1", task=name[4:])
    elif isinstance(name, str):
        if name not in _NAMED:
            raise ValueError(f"unknown benchmark {name!r}; known: {', '.join(BENCHMARKS)}, or a task list")
        bench = _NAMED[name]
    else:
        bench = custom_mt(name)
    if task is not None and bench.name not in ("MT1", "ML1"):
        raise ValueError(f"task= is only for MT1 and ML1, not {bench.name}")
    return bench


def custom_mt(tasks: Sequence[str]) -> Benchmark:
    """A multi-task set of the given tasks, in the given order."""
    names = _check_tasks(tuple(tasks))
    return Benchmark("custom-mt", names)


def custom_ml(train: Sequence[str], test: Sequence[str]) -> Benchmark:
    """A meta-learning set; like the reference, its train and test tasks must not overlap."""
    train_names, test_names = _check_tasks(tuple(train)), _check_tasks(tuple(test))
    overlap = sorted(set(train_names) & set(test_names))
    if overlap:
        raise ValueError(f"the test tasks cannot contain any of the train tasks: {overlap}")
    return Benchmark("custom-ml", train_names, test_names, meta_learning=True)


def task_names(
    name: str | Sequence[str] | Benchmark, split: str = "train", task: str | None = None
) -> tuple[str, ...]:
    """The tasks of one split of a task set (see `benchmark`)."""
    return benchmark(name, task).tasks(split)


def goal_variants(
    name: str | Sequence[str] | Benchmark, seed: int = 0, split: str = "train", task: str | None = None
) -> dict[str, np.ndarray]:
    """The reference's 50 goal variants (`rand_vec`s) of every task of a split, `{task: (50, d)}`,
    identical to `metaworld.<Benchmark>(seed=seed)`'s `train_tasks` / `test_tasks`, in order:
    `goal_variants("MT10", seed=42)`, `goal_variants("ML1", seed=0, split="test", task="reach-v3")`."""
    if not isinstance(seed, (int, np.integer)) or isinstance(seed, bool):
        raise ValueError(f"seed must be an int, got {seed!r}")
    bench = benchmark(name, task)
    names = bench.tasks(split)
    offset = bench.test_seed_offset if split == "test" else 0
    return sample_goal_variants(names, int(seed) + offset)


def mt1_goal_variants(names: Sequence[str], seed: int) -> dict[str, np.ndarray]:
    """Every task's own MT1 goal variants, `{task: metaworld.MT1(task, seed).train_tasks}`: the
    goals the reference's per-task runs (its scripted experts, MT1 training) see. A set such as
    MT50 draws its tasks' variants from one RNG in turn, so only its first task's match these."""
    return {name: goal_variants("MT1", seed, task=name)[name] for name in names}


def parse_tasks(text: str) -> str | list[str]:
    """A set as a command line spells it, as `benchmark` and `mwjax.make` take it: a set name
    ("MT10", "MT1:<task>") or task names separated by commas (one task alone is a one-task set)."""
    return text.split(",") if "," in text or text in TASKS else text


def _check_tasks(names: tuple[str, ...]) -> tuple[str, ...]:
    if not names:
        raise ValueError("a task set needs at least one task")
    if len(set(names)) != len(names):
        raise ValueError(f"duplicate task names in {names}")
    for name in names:
        get_task(name)
    return names


def sample_goal_variants(names: Sequence[str], seed: int, n_goals: int = N_GOALS) -> dict[str, np.ndarray]:
    """The reference's `_make_tasks`: task by task in order, from one RNG seeded once."""
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
