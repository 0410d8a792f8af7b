"""Parity with the reference (metaworld 3.1.1 on mujoco 3.3.0), from recorded fixtures.

Given the same physics state, mwjax must produce the reference's observation (1e-5), V2 reward
(1e-4 x max(1, |reference|) on >= 99% of recorded steps) and success flag. Reset states and goal
variants are compared too, and free-running trajectories must stay close for 10 steps.
"""

from __future__ import annotations

from importlib import resources

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from reference import load, recorded_tasks, replay_recorded_states

import mwjax
from mwjax.benchmarks import MT10, sample_goal_variants
from mwjax.models import load_scene
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
    return replay_recorded_states(PORTED)


@pytest.fixture(scope="module")
def replay_v1():
    return replay_recorded_states(PORTED, "v1")


@pytest.fixture(scope="module")
def free_run(all_tasks):
    """mwjax's own trajectory from each recorded reset, driven by the recorded actions."""
    env = all_tasks.env
    state = all_tasks.reset_to_recorded(first_variant=0)
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


# Resets that run physics (float32 Warp here, float64 MuJoCo 3.3.0 there) are compared like a
# free-run step, (qpos, qvel) bounds: box-close and door-lock step 5 substeps inside their reset,
# and the tasks that settle per goal run the hand's 250-substep settling with the arm touching a
# fixture (the largest error measured across seeds, rounded up: 3e-4 rad, 7e-3 rad/s).
PHYSICS_IN_RESET_TOL = (1e-3, 1e-2)
RECORDED_RESET_TOL = (1e-6, 1e-5)


@pytest.mark.parametrize("task", PORTED)
def test_reset_state(task, free_run):
    env, state, _ = free_run
    kin = env.kinematics(state, task)
    spec = TASKS[task]
    physics_in_reset = spec.reset_env_steps or spec.settle_per_goal
    qpos_tol, qvel_tol = PHYSICS_IN_RESET_TOL if physics_in_reset else RECORDED_RESET_TOL
    np.testing.assert_allclose(np.asarray(kin.qpos), load(task)["reset_qpos"], atol=qpos_tol)
    np.testing.assert_allclose(np.asarray(kin.qvel), load(task)["reset_qvel"], atol=qvel_tol, rtol=1e-6)


_ARM_JOINTS = [f"right_j{i}" for i in range(7)] + ["r_close", "l_close"]


def _settled_arm(task: str) -> tuple[np.ndarray, np.ndarray]:
    """The recorded settled arm qpos of `task` and the arm's qpos addresses in its scene."""
    spec = TASKS[task]
    model = load_scene(spec.scene, spec.moved_bodies)
    arm = np.array([model.joint(name).qposadr[0] for name in _ARM_JOINTS])
    with resources.as_file(resources.files("mwjax.tasks") / "settled_states.npz") as path, np.load(path) as f:
        return f[f"{task}/qpos"][arm], arm


# The settled arm survives the reset in every task but those that step physics after settling.
SETTLED_ARM_KEPT = [task for task in PORTED if not TASKS[task].reset_env_steps]


@pytest.mark.parametrize("task", SETTLED_ARM_KEPT)
def test_settled_arm_is_recorded_unless_it_depends_on_the_goal(task):
    """The reference's arm right after reset is the recorded settled arm in every goal, except in
    the tasks that settle per goal, where it differs between goals: the flag is right."""
    settled, arm = _settled_arm(task)
    reset_arm = load(task)["reset_qpos"][:, arm]
    if TASKS[task].settle_per_goal:
        assert np.abs(reset_arm - reset_arm[:1]).max() > 0
    else:
        np.testing.assert_array_equal(reset_arm, np.broadcast_to(settled, reset_arm.shape))


def test_reset_to_goal_vectors_settles_as_the_goal_variants():
    """`reset_to` takes goals as vectors and settles the tasks that settle per goal inside the
    reset; it must give the state that the settled states precomputed for the env's goal variants
    give for the same goals."""
    task = "handle-press-v3"
    goals = load(task)["rand_vec"]
    env = mwjax.make([task], envs_per_task=len(goals), goal_variants={task: goals})
    by_vector = jax.jit(env.reset_to)(jnp.asarray(goals, jnp.float32))
    by_variant = jax.jit(env.reset_with_variants)(jnp.arange(len(goals)))
    assert TASKS[task].settle_per_goal
    for ours, theirs in zip(jax.tree.leaves(by_vector), jax.tree.leaves(by_variant), strict=True):
        if jnp.issubdtype(ours.dtype, jnp.floating):
            np.testing.assert_array_equal(np.asarray(ours), np.asarray(theirs))


@pytest.mark.parametrize("task", PORTED)
def test_reset_obs(task, free_run):
    env, state, _ = free_run
    ours = np.asarray(state.obs[env.task_rows(task)])
    err = np.abs(ours - load(task)["reset_obs"]).max()
    assert err < STALE_RESET_OBS.get(task, OBS_TOL), f"reset obs error {err:.3g}"


@pytest.mark.parametrize("task", PORTED)
def test_free_running_drift(task, free_run):
    _, _, obs = free_run
    # The stacked previous frame is left out: at step 1 it is the reset frame (see test_reset_obs).
    current = np.r_[0:18, 36:39]
    recorded = load(task)["obs"][:, :FREE_RUN_STEPS]
    drift = np.abs(obs[task] - recorded)[..., current].max(axis=(0, 2))
    print(f"{task}: obs drift per step", " ".join(f"{d:.1e}" for d in drift))
    tol = ENGINE_VERSION_DRIFT.get(task, FREE_RUN_OBS_TOL)
    assert drift.max() < tol, f"drift {drift.max():.3g} after {drift.argmax() + 1} steps"
