"""Whole-episode parity: mwjax's free runs against recorded reference episodes.

Each recorded episode (tools/record_episodes.py: random actions, then the reference's experts plus
noise) is replayed open loop in mwjax from mwjax's own reset to the same goal. The yardstick is
the engine-only baseline (tools/reference_baseline.py): the reference's own code on MuJoCo C 3.17
started from the recorded reset state, i.e. what changing the engine version alone does to the
same episodes. mwjax must agree with the reference about as well as that baseline does:

- per-step success agreement at least the baseline's minus `SUCCESS_MARGIN`;
- the V2 episode return's error at most the baseline's plus `RETURN_MARGIN` (relative);
- reset states as in test_parity, on this other seed.

`MWJAX_EPISODE_FIXTURES` / `MWJAX_EPISODE_BASELINE` point the suite at another recording (any seed;
see tools/README_reference.md), e.g. one made fresh to check unseen goals.
"""

from __future__ import annotations

import numpy as np
import pytest
from reference import BASELINE, EPISODES, episode_free_run, load_episodes
from test_parity import OBS_TOL, PHYSICS_IN_RESET_TOL, RECORDED_RESET_TOL, STALE_RESET_OBS

from mwjax.tasks import TASKS

TASK_NAMES = sorted(p.stem for p in EPISODES.glob("*-v3.npz"))

# Float32 Warp against the baseline's float64 C: a one-step shift of a success boundary in one of
# the R x T recorded steps is 1/800; the margin allows eight.
SUCCESS_MARGIN = 0.01
# The V2 return is a sum of ~200 rewards in [0, 10]; 2% of it is a few steps' reward.
RETURN_MARGIN = 0.02


@pytest.fixture(scope="module")
def free_run(all_tasks):
    return episode_free_run(all_tasks, TASK_NAMES)


def _agreement(ours: np.ndarray, ref: np.ndarray) -> float:
    return float(np.mean(ours == ref))


def _return_error(ours: np.ndarray, ref: np.ndarray) -> float:
    """Mean over episodes of |return - reference return| / max(1, |reference return|)."""
    ours, ref = ours.sum(axis=-1), ref.sum(axis=-1)
    return float(np.mean(np.abs(ours - ref) / np.maximum(1.0, np.abs(ref))))


def test_recording_covers_every_task():
    assert set(TASK_NAMES) == set(TASKS)
    assert {p.stem for p in BASELINE.glob("*-v3.npz")} == set(TASK_NAMES)


@pytest.mark.parametrize("task", TASK_NAMES)
def test_success_agreement_at_least_baseline(task, free_run):
    ref, base = load_episodes(EPISODES, task), load_episodes(BASELINE, task)
    ours = _agreement(free_run[task]["success"], ref["success_v2"])
    baseline = _agreement(base["success_v2"], ref["success_v2"])
    print(f"{task}: success agreement mwjax {ours:.3f} baseline {baseline:.3f}")
    assert ours >= baseline - SUCCESS_MARGIN


@pytest.mark.parametrize("task", TASK_NAMES)
def test_return_error_within_baseline(task, free_run):
    ref, base = load_episodes(EPISODES, task), load_episodes(BASELINE, task)
    ours = _return_error(free_run[task]["reward"], ref["reward_v2"])
    baseline = _return_error(base["reward_v2"], ref["reward_v2"])
    print(f"{task}: V2 return error mwjax {ours:.4f} baseline {baseline:.4f}")
    assert ours <= baseline + RETURN_MARGIN


@pytest.mark.parametrize("task", TASK_NAMES)
def test_reset_state_on_this_seed(task, free_run):
    ref, spec = load_episodes(EPISODES, task), TASKS[task]
    physics_in_reset = spec.reset_env_steps or spec.settle_per_goal
    qpos_tol, qvel_tol = PHYSICS_IN_RESET_TOL if physics_in_reset else RECORDED_RESET_TOL
    np.testing.assert_allclose(free_run[task]["reset_qpos"], ref["reset_qpos"], atol=qpos_tol)
    np.testing.assert_allclose(free_run[task]["reset_qvel"], ref["reset_qvel"], atol=qvel_tol, rtol=1e-6)
    err = np.abs(free_run[task]["reset_obs"] - ref["reset_obs"]).max()
    assert err < STALE_RESET_OBS.get(task, OBS_TOL), f"reset obs error {err:.3g}"
