"""Parity with the reference (metaworld 3.1.1 on mujoco 3.3.0), from recorded fixtures.

Given the same physics state, mwjax must produce the reference's observation (1e-5), V2 reward
(1e-4 x max(1, |reference|) on >= 99% of recorded steps) and success flag. Reset states and goal
variants are compared too, and free-running trajectories must stay close for 10 steps.
"""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np
import pytest
from reference import load, rand_vec_rows, recorded_tasks, replay_recorded_states

from mwjax.benchmarks import MT10, sample_goal_variants
from mwjax.tasks import TASKS

# Every ported task that has a reference recording; MT10 must be among them.
PORTED = [task for task in recorded_tasks() if task in TASKS]

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
    "lever-pull-v3": 1e-3,
    "door-lock-v3": 1e-3,  # read after its in-reset mj_steps, before their kinematics
}

# The reference's settled state depends on the reset history in these tasks: while the hand
# settles, the arm or the object rests against a fixture that the previous episode moved, or the
# object keeps the previous episode's orientation. mwjax starts every episode from the first
# episode's settled state, which the first recorded reset reproduces: reset and free-run checks
# use that reset, and given-state rewards read the reference's own init_tcp.
HISTORY_DEPENDENT_SETTLE = {
    "handle-press-side-v3": "arm touches the moved box (9e-6 rad by the 4th reset)",
    "handle-pull-side-v3": "arm touches the moved box (9e-6 rad by the 4th reset)",
    "handle-press-v3": "arm touches the moved box (3e-3 rad)",
    "handle-pull-v3": "arm touches the moved box (3e-3 rad)",
    "door-lock-v3": "arm touches the moved door (7e-2 rad)",
    "door-unlock-v3": "arm touches the moved door (7e-2 rad)",
    "box-close-v3": "the lid settles on the box, already at this episode's goal (1e-3 in its quaternion)",
    "disassemble-v3": "the nut keeps the previous episode's yaw (up to 27 degrees)",
    "peg-unplug-side-v3": "the plug keeps the previous episode's angular velocity (up to 6.8 rad/s)",
}

FREE_RUN_STEPS = 10
# Warp's float32 solver vs the reference's float64 one, through 50 physics substeps.
FREE_RUN_OBS_TOL = 5e-3
# Where MuJoCo 3.17 itself (C, float64) departs from 3.3.0 more than that, and why (bounds: the
# largest drift measured, rounded up).
ENGINE_VERSION_DRIFT = {
    # The box starts 2 cm inside the table; 3.3.0's box-box collider reports 1 cm of penetration,
    # 3.17's the full 2 cm, so the box is pushed up faster.
    "hand-insert-v3": 1e-2,
    # The door starts at its hinge limit, 1 mm inside the door-lock frame. In the reference the frame
    # is static (weld id 0), so those contacts push the door closed; our frame is a mocap body (its
    # own weld root), and MuJoCo's parent-child filter drops the contacts.
    "door-close-v3": 0.1,
    # Same family, unconfirmed: the lever rests against the moved box, whose parent-child contacts
    # MuJoCo filters in our scene and not in the reference's; the drift peaks at step 7, then decays.
    "handle-press-v3": 2e-2,
    # coffee's reset zeroes qvel[9:15], which in this scene are arm joints (reproduced): the arm,
    # still settling, is stopped mid-motion and lurches in the first steps (peak at step 3).
    "coffee-pull-v3": 3e-2,
    "coffee-push-v3": 3e-2,
}


def test_every_ported_task_is_recorded_and_covers_mt10():
    assert set(MT10) <= set(PORTED)
    assert set(PORTED) == set(TASKS), f"ported without a recording: {sorted(set(TASKS) - set(PORTED))}"


@pytest.fixture(scope="module")
def replay():
    return replay_recorded_states(PORTED, reference_init_tcp=list(HISTORY_DEPENDENT_SETTLE))


@pytest.fixture(scope="module")
def replay_v1():
    return replay_recorded_states(PORTED, "v1", reference_init_tcp=list(HISTORY_DEPENDENT_SETTLE))


@pytest.fixture(scope="module")
def free_run(all_tasks):
    """mwjax's own trajectory from each recorded reset, driven by the recorded actions."""
    env = all_tasks.env
    state = all_tasks.reset_to(jnp.asarray(rand_vec_rows(env, 1)))
    reset_state = state
    actions = np.concatenate([load(t)["action"][:, :FREE_RUN_STEPS] for t in env.task_list])
    obs = []
    for t in range(FREE_RUN_STEPS):
        state = all_tasks.step(state, jnp.asarray(actions[:, t]))
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


@pytest.mark.parametrize("task", PORTED)
def test_reward_v1_given_state(task, replay_v1):
    _assert_rewards_match(replay_v1.reward[task], load(task)["reward_v1"])


@pytest.mark.parametrize("task", PORTED)
def test_success_v1_given_state(task, replay_v1):
    np.testing.assert_array_equal(replay_v1.success[task], load(task)["success_v1"] > 0)


# box-close and door-lock run 5 physics substeps inside their reset (float32 Warp here, float64
# MuJoCo 3.3.0 there), so their reset state is compared like a free-run step: (qpos, qvel) bounds.
PHYSICS_IN_RESET_TOL = (1e-4, 1e-2)


def _comparable_resets(task: str) -> slice:
    return slice(0, 1) if task in HISTORY_DEPENDENT_SETTLE else slice(None)


@pytest.mark.parametrize("task", PORTED)
def test_reset_state(task, free_run):
    env, state, _ = free_run
    kin = env.kinematics(state, task)
    resets = _comparable_resets(task)
    qpos_tol, qvel_tol = PHYSICS_IN_RESET_TOL if TASKS[task].reset_env_steps else (1e-6, 1e-5)
    np.testing.assert_allclose(np.asarray(kin.qpos)[resets], load(task)["reset_qpos"][resets], atol=qpos_tol)
    np.testing.assert_allclose(
        np.asarray(kin.qvel)[resets], load(task)["reset_qvel"][resets], atol=qvel_tol, rtol=1e-6
    )


@pytest.mark.parametrize("task", PORTED)
def test_reset_obs(task, free_run):
    env, state, _ = free_run
    resets = _comparable_resets(task)
    ours = np.asarray(state.obs[env.task_rows(task)])[resets]
    err = np.abs(ours - load(task)["reset_obs"][resets]).max()
    assert err < STALE_RESET_OBS.get(task, OBS_TOL), f"reset obs error {err:.3g}"


@pytest.mark.parametrize("task", PORTED)
def test_free_running_drift(task, free_run):
    _, _, obs = free_run
    resets = _comparable_resets(task)
    # The stacked previous frame is left out: at step 1 it is the reset frame (see test_reset_obs).
    current = np.r_[0:18, 36:39]
    recorded = load(task)["obs"][resets, :FREE_RUN_STEPS]
    drift = np.abs(obs[task][resets] - recorded)[..., current].max(axis=(0, 2))
    print(f"{task}: obs drift per step", " ".join(f"{d:.1e}" for d in drift))
    tol = ENGINE_VERSION_DRIFT.get(task, FREE_RUN_OBS_TOL)
    assert drift.max() < tol, f"drift {drift.max():.3g} after {drift.argmax() + 1} steps"
