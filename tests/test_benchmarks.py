"""Task sets and goal variants against the reference's own benchmark objects (recorded by
tools/record_goal_variants.py: MT10/MT50/ML10/ML45/ML1 at seeds 0, 1, 42, MT25/ML25 at 0)."""

from __future__ import annotations

from collections import defaultdict

import numpy as np
import pytest
from reference import FIXTURES

from mwjax import benchmarks


def _recorded() -> dict[tuple[str, int, str], dict[str, np.ndarray]]:
    out: dict[tuple[str, int, str], dict[str, np.ndarray]] = defaultdict(dict)
    with np.load(FIXTURES / "goal_variants.npz") as archive:
        for key in archive.files:  # insertion order = the reference's task order
            if key == "meta":
                continue
            name, seed, split, task = key.split("/")
            out[(name, int(seed), split)][task] = archive[key]
    return dict(out)


RECORDED = _recorded()


def _resolve(name: str) -> tuple[str, str | None]:
    return (name[:3], name[4:]) if name.startswith("ML1:") else (name, None)


@pytest.mark.parametrize("case", sorted(RECORDED), ids=lambda c: f"{c[0]}-seed{c[1]}-{c[2]}")
def test_goal_variants_equal_reference(case):
    name, seed, split = case
    bench, task = _resolve(name)
    ours = benchmarks.goal_variants(bench, seed=seed, split=split, task=task)
    reference = RECORDED[case]
    assert list(ours) == list(reference), "tasks or their order differ"
    for task_name, vecs in reference.items():
        assert ours[task_name].shape == vecs.shape
        assert np.array_equal(ours[task_name], vecs), task_name


def test_fixture_covers_the_required_sets():
    covered = {(name.split(":")[0], seed) for name, seed, _ in RECORDED}
    for name in ("MT10", "MT50", "ML10", "ML45", "ML1"):
        for seed in (0, 1, 42):
            assert (name, seed) in covered


def test_ml_splits_are_the_references():
    for name in ("ML10", "ML25", "ML45"):
        for split in ("train", "test"):
            assert benchmarks.task_names(name, split) == tuple(RECORDED[(name, 0, split)])
    assert benchmarks.task_names("MT25") == tuple(RECORDED[("MT25", 0, "train")])
    assert benchmarks.task_names("MT50") == benchmarks.MT50 and len(set(benchmarks.MT50)) == 50


def test_ml1_test_goals_differ_from_train_goals():
    train = benchmarks.goal_variants("ML1", seed=3, task="reach-v3")["reach-v3"]
    test = benchmarks.goal_variants("ML1", seed=3, split="test", task="reach-v3")["reach-v3"]
    assert not np.any(np.all(train[:, None] == test[None], axis=-1))


def test_bad_benchmarks_are_refused():
    with pytest.raises(ValueError, match="unknown benchmark"):
        benchmarks.benchmark("MT11")
    with pytest.raises(ValueError, match="needs task="):
        benchmarks.benchmark("ML1")
    with pytest.raises(ValueError, match="only for MT1 and ML1"):
        benchmarks.benchmark("MT10", task="reach-v3")
    with pytest.raises(ValueError, match="no test split"):
        benchmarks.goal_variants("MT10", split="test")
    with pytest.raises(ValueError, match="split must be"):
        benchmarks.goal_variants("ML10", split="validation")
    with pytest.raises(ValueError, match="unknown task|not a|no task"):
        benchmarks.custom_mt(["reach-v3", "fly-v3"])
    with pytest.raises(ValueError, match="duplicate"):
        benchmarks.custom_mt(["reach-v3", "reach-v3"])
    with pytest.raises(ValueError, match="cannot contain any of the train tasks"):
        benchmarks.custom_ml(["reach-v3", "push-v3"], ["push-v3"])
    with pytest.raises(ValueError, match="seed must be an int"):
        benchmarks.goal_variants("MT10", seed=1.5)


def test_custom_sets_sample_like_the_reference_does():
    custom = benchmarks.custom_ml(["reach-v3", "push-v3"], ["door-open-v3"])
    assert custom.meta_learning and benchmarks.task_names(custom, "test") == ("door-open-v3",)
    # The reference's CustomML samples each split from its own seeded RNG, task by task.
    train = benchmarks.goal_variants(custom, seed=5)
    assert np.array_equal(
        train["push-v3"], benchmarks.sample_goal_variants(["reach-v3", "push-v3"], 5)["push-v3"]
    )


def test_mt1_goal_variants_are_each_tasks_own():
    # MT1 and ML1's train split draw a task's variants alike (the partial-observability override
    # touches no draw), so the recorded ML1 train goals are the reference's MT1 goals.
    tasks = ["door-lock-v3", "bin-picking-v3", "pick-place-v3"]
    ours = benchmarks.mt1_goal_variants(tasks, 42)
    assert list(ours) == tasks
    for task in tasks:
        assert np.array_equal(ours[task], RECORDED[(f"ML1:{task}", 42, "train")][task]), task
    # In a set, only the first task draws first from the seeded RNG.
    mt10 = RECORDED[("MT10", 42, "train")]
    first, second = list(mt10)[:2]
    assert np.array_equal(benchmarks.mt1_goal_variants([first], 42)[first], mt10[first])
    assert not np.array_equal(benchmarks.mt1_goal_variants([second], 42)[second], mt10[second])
