"""Whole-episode parity: mwjax's free runs against recorded reference episodes.

Each recorded episode (tools/record_episodes.py: random actions, then the reference's experts plus
noise) is replayed open loop in mwjax from mwjax's own reset to the same goal. The yardstick is
the engine-only baseline (tools/reference_baseline.py): the reference's own code on MuJoCo C 3.17
started from the recorded reset state, i.e. what changing the engine version alone does to the
same episodes. Contact-rich episodes also bifurcate: a push that barely catches an object in one
run misses it in another. The reference's own sensitivity is the chaos floor: the reference (MuJoCo
3.3.0) replaying the same episodes with every joint speed of the reset state nudged by 1e-4 rad/s
(`tools/reference_baseline.py --perturb 1e-4`, run in the reference's venv), about one env step of
float32 Warp's difference from it (a substep from the same state: 1e-5 rad/s without contacts,
1e-3 with). mwjax must agree with the reference about as well as these do:

- per-step success agreement at least the baseline's minus `SUCCESS_MARGIN`;
- the V2 episode return's error, the median over a task's episodes, at most the larger of the
  baseline's and the chaos floor's plus `RETURN_MARGIN`. The median, because one bifurcating
  episode of four decides a mean: in shelf-place's fourth episode the reference places the block
  and both MuJoCo 3.17 engines (mwjax and the baseline) lose it at the same step;
- reset states as in test_parity, on this other seed.

`MWJAX_EPISODE_FIXTURES`, `MWJAX_EPISODE_BASELINE` and `MWJAX_EPISODE_PERTURBED` point the suite at
another recording (any seed; see tools/README_reference.md), e.g. one made fresh to check unseen
goals.
"""

from __future__ import annotations

import numpy as np
import pytest
from reference import BASELINE, EPISODES, PERTURBED, all_task_runs_child, free_runs, load_episodes
from test_parity import assert_reset_matches

from mwjax.tasks import TASKS

TASK_NAMES = sorted(p.stem for p in EPISODES.glob("*-v3.npz"))

# Float32 Warp against the baseline's float64 C: a one-step shift of a success boundary in one of
# the R x T recorded steps is 1/800; the margin allows eight.
SUCCESS_MARGIN = 0.01
# The V2 return is a sum of ~200 rewards in [0, 10]; 2% of it is a few steps' reward.
RETURN_MARGIN = 0.02


# On the CPU the free run runs in a child started at collection (shared with test_parity's free
# run: `reference.all_task_runs`), on the second core while the parent runs the rest of the suite;
# these tests run last (`late`) and read its arrays.
pytestmark = pytest.mark.late


@pytest.fixture(scope="module")
def free_run(request):
    return free_runs(request, "episodes")


@pytest.mark.child.with_args(all_task_runs_child)
def test_the_free_run_covers_every_task(free_run):
    assert set(free_run) == set(TASK_NAMES)
    assert all(free_run[task]["success"].shape == free_run[task]["reward"].shape for task in TASK_NAMES)


def _agreement(ours: np.ndarray, ref: np.ndarray) -> float:
    return float(np.mean(ours == ref))


def _return_error(ours: np.ndarray, ref: np.ndarray) -> float:
    """Median over episodes of |return - reference return| / max(1, |reference return|)."""
    ours, ref = ours.sum(axis=-1), ref.sum(axis=-1)
    return float(np.median(np.abs(ours - ref) / np.maximum(1.0, np.abs(ref))))


def test_recording_covers_every_task():
    assert set(TASK_NAMES) == set(TASKS)
    assert {p.stem for p in BASELINE.glob("*-v3.npz")} == set(TASK_NAMES)
    assert {p.stem for p in PERTURBED.glob("*-v3.npz")} == set(TASK_NAMES)


@pytest.mark.parametrize("task", TASK_NAMES)
def test_success_agreement_at_least_baseline(task, free_run):
    ref, base = load_episodes(EPISODES, task), load_episodes(BASELINE, task)
    ours = _agreement(free_run[task]["success"], ref["success_v2"])
    baseline = _agreement(base["success_v2"], ref["success_v2"])
    print(f"{task}: success agreement mwjax {ours:.3f} baseline {baseline:.3f}")
    assert ours >= baseline - SUCCESS_MARGIN


@pytest.mark.parametrize("task", TASK_NAMES)
def test_return_error_within_baseline_or_chaos_floor(task, free_run):
    ref = load_episodes(EPISODES, task)
    ours = _return_error(free_run[task]["reward"], ref["reward_v2"])
    baseline = _return_error(load_episodes(BASELINE, task)["reward_v2"], ref["reward_v2"])
    floor = _return_error(load_episodes(PERTURBED, task)["reward_v2"], ref["reward_v2"])
    print(f"{task}: V2 return error mwjax {ours:.4f} baseline {baseline:.4f} chaos floor {floor:.4f}")
    assert ours <= max(baseline, floor) + RETURN_MARGIN


@pytest.mark.parametrize("task", TASK_NAMES)
def test_reset_state_on_this_seed(task, free_run):
    ours = free_run[task]
    assert_reset_matches(
        task, ours["reset_qpos"], ours["reset_qvel"], ours["reset_obs"], load_episodes(EPISODES, task)
    )
