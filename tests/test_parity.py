"""Parity with the reference (metaworld 3.1.1 on mujoco 3.3.0), from recorded fixtures.

Given the same physics state, mwjax must produce the reference's observation (1e-5), V2 reward
(1e-4 x max(1, |reference|) on >= 99% of recorded steps) and success flag. Reset states and goal
variants are compared too, and free-running trajectories must stay close for 10 steps.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from reference import load, rand_vec_rows, recorded_tasks, replay_recorded_states, shape

import mwjax
from mwjax.benchmarks import MT10, sample_goal_variants
from mwjax.tasks import TASKS

# Every ported task that has a reference recording; MT10 must be among them.
PORTED = [task for task in recorded_tasks() if task in TASKS]
PORTED_V1 = [task for task in PORTED if TASKS[task].reward_v1 is not None]

OBS_TOL = 1e-5
REWARD_TOL = 1e-4
REWARD_PASS_FRACTION = 0.99

# The reference computes these tasks' reset observation before refreshing kinematics (no
# mj_forward after moving the fixture), so its reset obs shows the hand one physics substep
# (and window-close's handle one joint write) behind the state it returns. mwjax reports the
# state it returns. Bound: the largest difference measured, rounded up.
STALE_RESET_OBS = {
    "drawer-open-v3": 1e-3,
    "window-open-v3": 1e-3,
    "window-close-v3": 0.25,
    "faucet-open-v3": 1e-3,
    "dial-turn-v3": 1e-3,
}

# In the sideways handle scene the reference's settled arm drifts with the reset history: its
# fourth recorded reset starts 9e-6 rad and 2e-4 rad/s away from the first, whose settled state
# mwjax ships. Rewards and success still match on every recorded step. (qpos, qvel) tolerances:
HISTORY_DEPENDENT_SETTLE = {"handle-press-side-v3": (2e-5, 5e-4), "handle-pull-side-v3": (2e-5, 5e-4)}

FREE_RUN_STEPS = 10
# Warp's float32 solver vs the reference's float64 one, through 50 physics substeps.
FREE_RUN_OBS_TOL = 5e-3


def test_every_ported_task_is_recorded_and_covers_mt10():
    assert set(MT10) <= set(PORTED)
    assert set(PORTED) == set(TASKS), f"ported without a recording: {sorted(set(TASKS) - set(PORTED))}"


@pytest.fixture(scope="module")
def replay():
    return replay_recorded_states(PORTED)


@pytest.fixture(scope="module")
def replay_v1():
    return replay_recorded_states(PORTED_V1, reward_version="v1")


@pytest.fixture(scope="module")
def free_run():
    """mwjax's own trajectory from each recorded reset, driven by the recorded actions."""
    resets = shape(PORTED[0])[0]
    env = mwjax.make(PORTED, envs_per_task=resets)
    state = jax.jit(env.reset_to)(jnp.asarray(rand_vec_rows(env, 1)))
    reset_state = state
    actions = np.concatenate([load(t)["action"][:, :FREE_RUN_STEPS] for t in env.task_list])
    step = jax.jit(env.step)
    obs = []
    for t in range(FREE_RUN_STEPS):
        state = step(state, jnp.asarray(actions[:, t]))
        obs.append(np.asarray(state.obs))
    obs = np.stack(obs, axis=1)
    return env, reset_state, {t: obs[env.task_rows(t)] for t in env.task_list}


@pytest.mark.parametrize("task", PORTED)
def test_goal_variants_equal_reference(task):
    recorded = load(task)["rand_vec"]
    ours = sample_goal_variants([task], seed=load(task)["meta"]["seed"])[task][: len(recorded)]
    np.testing.assert_array_equal(ours, recorded)


@pytest.mark.parametrize("task", PORTED)
def test_obs_given_state(task, replay):
    err = np.abs(replay.obs[task] - load(task)["obs"])
    assert err.max() < OBS_TOL, (
        f"max obs error {err.max():.3g} at {np.unravel_index(err.argmax(), err.shape)}"
    )


def _assert_rewards_match(ours: np.ndarray, ref: np.ndarray) -> None:
    ok = np.abs(ours - ref) <= REWARD_TOL * np.maximum(1.0, np.abs(ref))
    bad = np.argwhere(~ok)
    assert ok.mean() >= REWARD_PASS_FRACTION, (
        f"{ok.mean():.2%} within tolerance; first misses (reset, step, ours, ref): "
        + ", ".join(f"({r}, {t}, {ours[r, t]:.6g}, {ref[r, t]:.6g})" for r, t in bad[:5])
    )


@pytest.mark.parametrize("task", PORTED)
def test_reward_v2_given_state(task, replay):
    _assert_rewards_match(replay.reward[task], load(task)["reward_v2"])


@pytest.mark.parametrize("task", PORTED)
def test_success_given_state(task, replay):
    np.testing.assert_array_equal(replay.success[task], load(task)["success_v2"] > 0)


@pytest.mark.parametrize("task", PORTED_V1)
def test_reward_v1_given_state(task, replay_v1):
    _assert_rewards_match(replay_v1.reward[task], load(task)["reward_v1"])


@pytest.mark.parametrize("task", PORTED_V1)
def test_success_v1_given_state(task, replay_v1):
    np.testing.assert_array_equal(replay_v1.success[task], load(task)["success_v1"] > 0)


@pytest.mark.parametrize("task", PORTED)
def test_reset_state(task, free_run):
    env, state, _ = free_run
    kin = env.kinematics(state, task)
    qpos_tol, qvel_tol = HISTORY_DEPENDENT_SETTLE.get(task, (1e-6, 1e-5))
    np.testing.assert_allclose(np.asarray(kin.qpos), load(task)["reset_qpos"], atol=qpos_tol)
    np.testing.assert_allclose(np.asarray(kin.qvel), load(task)["reset_qvel"], atol=qvel_tol, rtol=1e-6)


@pytest.mark.parametrize("task", PORTED)
def test_reset_obs(task, free_run):
    env, state, _ = free_run
    err = np.abs(np.asarray(state.obs[env.task_rows(task)]) - load(task)["reset_obs"]).max()
    assert err < STALE_RESET_OBS.get(task, OBS_TOL), f"reset obs error {err:.3g}"


@pytest.mark.parametrize("task", PORTED)
def test_free_running_drift(task, free_run):
    _, _, obs = free_run
    # The stacked previous frame is left out: at step 1 it is the reset frame (see test_reset_obs).
    current = np.r_[0:18, 36:39]
    drift = np.abs(obs[task] - load(task)["obs"][:, :FREE_RUN_STEPS])[..., current].max(axis=(0, 2))
    print(f"{task}: obs drift per step", " ".join(f"{d:.1e}" for d in drift))
    assert drift.max() < FREE_RUN_OBS_TOL, f"drift {drift.max():.3g} after {drift.argmax() + 1} steps"
