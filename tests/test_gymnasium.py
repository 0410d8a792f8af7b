"""The Gymnasium adapter: registration, spaces, both autoreset modes, one-hot ids, partial
observability, truncation, terminate_on_success, ML goal cycling, seeding, Gymnasium's checker."""

from __future__ import annotations

import dataclasses
import importlib.util

import gymnasium as gym
import jax.numpy as jnp
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env, data_equivalence
from gymnasium.vector import AutoresetMode

import mwjax  # noqa: F401  (registers the ids)
from mwjax import policies

HORIZON = 3
TASKS = ["reach-v3", "push-v3"]


def _rollout(envs, seed, steps):
    obs, _ = envs.reset(seed=seed)
    out = [obs]
    rng = np.random.default_rng(seed)
    for _ in range(steps):
        obs, *_ = envs.step(rng.uniform(-1, 1, (envs.num_envs, 4)).astype(np.float32))
        out.append(obs)
    return out


@pytest.fixture(scope="module")
def same_step():
    return gym.make_vec(
        "mwjax/custom-mt-envs",
        envs_list=TASKS,
        num_envs=4,
        max_episode_steps=HORIZON,
        use_one_hot=True,
        seed=1,
    )


@pytest.fixture(scope="module")
def next_step():
    return gym.make_vec(
        "mwjax/custom-mt-envs",
        envs_list=TASKS,
        num_envs=4,
        max_episode_steps=HORIZON,
        autoreset_mode=AutoresetMode.NEXT_STEP,
        seed=1,
    )


def test_registered_ids_mirror_the_reference():
    for name in ("MT1", "MT10", "MT25", "MT50", "custom-mt-envs", "custom-ml-envs"):
        assert f"mwjax/{name}" in gym.registry
    for name in ("ML1", "ML10", "ML25", "ML45"):
        for split in ("train", "test"):
            assert f"mwjax/{name}-{split}" in gym.registry


def test_spaces_and_one_hot(same_step):
    envs = same_step
    assert isinstance(envs.unwrapped, gym.vector.VectorEnv) and envs.num_envs == 4
    assert envs.single_observation_space.shape == (39 + 2,)
    assert envs.single_action_space.shape == (4,)
    obs, info = envs.reset(seed=0)
    assert isinstance(obs, np.ndarray) and obs.dtype == np.float32 and obs.shape == (4, 41)
    assert envs.observation_space.contains(obs)
    np.testing.assert_array_equal(obs[:, 39:], np.repeat(np.eye(2, dtype=np.float32), 2, axis=0))
    assert envs.unwrapped.task_names == ("reach-v3", "reach-v3", "push-v3", "push-v3")
    # MT sets show the goal.
    assert np.all(np.any(obs[:, 36:39] != 0, axis=1))


def test_same_step_autoreset_and_truncation(same_step):
    envs = same_step
    obs, _ = envs.reset(seed=2)
    actions = np.zeros((4, 4), np.float32)
    for step in range(1, HORIZON + 1):
        prev = obs
        obs, reward, terminated, truncated, info = envs.step(actions)
        assert isinstance(reward, np.ndarray) and reward.dtype == np.float32
        assert not terminated.any()
        assert truncated.all() == (step == HORIZON)
    assert info["_final_obs"].all() and info["_final_info"].all()
    # The returned obs starts a new episode (its previous frame equals its current one); the
    # finished episode's last obs continues the one before it.
    np.testing.assert_array_equal(obs[:, :18], obs[:, 18:36])
    np.testing.assert_array_equal(info["final_obs"][:, 18:36], prev[:, :18])
    np.testing.assert_array_equal(info["final_obs"][:, 39:], obs[:, 39:])
    assert set(info["final_info"]) >= {"success", "_success", "episode", "_episode"}
    np.testing.assert_array_equal(info["final_info"]["episode"]["l"], [HORIZON] * 4)
    assert info["final_info"]["episode"]["r"].shape == (4,)
    assert not info["_success"].any()  # top-level info belongs to the new episodes
    obs, _, _, truncated, info = envs.step(actions)
    assert not truncated.any() and not info["_final_obs"].any()


def test_next_step_autoreset(next_step):
    envs = next_step
    envs.reset(seed=2)
    actions = np.zeros((4, 4), np.float32)
    for _ in range(HORIZON):
        obs, reward, terminated, truncated, info = envs.step(actions)
    assert truncated.all() and info["_episode"].all()
    np.testing.assert_array_equal(info["episode"]["l"], [HORIZON] * 4)
    assert "final_obs" not in info
    last = obs
    obs, reward, terminated, truncated, info = envs.step(actions)  # the reset step
    np.testing.assert_array_equal(reward, np.zeros(4, np.float32))
    assert not (terminated | truncated).any()
    np.testing.assert_array_equal(obs[:, :18], obs[:, 18:36])
    assert not np.array_equal(obs, last)
    obs2, *_ = envs.step(actions)
    np.testing.assert_array_equal(obs2[:, 18:36], obs[:, :18])


def test_the_adapter_continues_from_a_state_it_is_given(same_step):
    """A state set on the adapter is where its next step starts (here every episode one step from
    its end, as the throughput benchmark staggers them); anything but a state of its batch is refused."""
    envs = same_step
    envs.reset(seed=3)
    adapter = envs.unwrapped
    last_step = dataclasses.replace(adapter.state, steps=jnp.full_like(adapter.state.steps, HORIZON - 1))
    adapter.state = last_step
    _, _, _, truncated, info = envs.step(np.zeros((4, 4), np.float32))
    assert truncated.all()
    np.testing.assert_array_equal(info["final_info"]["episode"]["l"], [HORIZON] * 4)
    with pytest.raises(ValueError, match="4 envs"):
        adapter.state = dataclasses.replace(adapter.state, obs=adapter.state.obs[:2])
    with pytest.raises(ValueError, match="4 envs"):
        adapter.state = {"obs": np.zeros((4, 39))}


def test_numpy_final_obs_is_the_devices_with_only_the_finished_rows_copied(same_step, monkeypatch):
    """The NumPy adapter copies only the finished envs' rows of `final_obs` from the device and
    takes the rest from the observation: what it returns must be the device's array, in steps
    where different envs' episodes end."""
    from mwjax.wrappers.gymnasium import NumpyVectorEnv

    numpy_env = same_step
    while not isinstance(numpy_env, NumpyVectorEnv):
        numpy_env = numpy_env.env
    inner, dense = numpy_env.env, []

    def step(actions):
        out = type(inner).step(inner, actions)
        dense.append(np.asarray(out[4]["final_obs"]))
        return out

    monkeypatch.setattr(inner, "step", step)
    same_step.reset(seed=4)
    adapter = same_step.unwrapped
    ends = [0, HORIZON - 1, 0, HORIZON - 2]  # envs 1 and 3 end at the first and second step
    adapter.state = dataclasses.replace(adapter.state, steps=jnp.asarray(ends, adapter.state.steps.dtype))
    finished = []
    for _ in range(HORIZON):
        *_, info = same_step.step(np.random.default_rng(0).uniform(-1, 1, (4, 4)).astype(np.float32))
        np.testing.assert_array_equal(info["final_obs"], dense[-1])
        finished.append(np.flatnonzero(info["_final_obs"]).tolist())
    assert finished == [[1], [3], [0, 2]]


def test_same_seed_gives_identical_observations(same_step):
    first = _rollout(same_step, seed=5, steps=4)
    second = _rollout(same_step, seed=5, steps=4)
    other = _rollout(same_step, seed=6, steps=4)
    assert all(data_equivalence(a, b, exact=True) for a, b in zip(first, second, strict=True))
    assert not all(np.array_equal(a, b) for a, b in zip(first, other, strict=True))


def test_bad_arguments_are_refused(same_step):
    same_step.reset(seed=0)
    # NumPy actions are checked on the host, jax arrays on the device: both refuse the same.
    for xp, envs in ((np, same_step), (jnp, same_step.unwrapped)):
        with pytest.raises(ValueError, match="shape"):
            envs.step(xp.zeros((3, 4), np.float32))
        with pytest.raises(ValueError, match="NaN"):
            envs.step(xp.full((4, 4), np.nan, np.float32))
        with pytest.raises(ValueError, match="NaN"):
            envs.step(xp.full((4, 4), np.inf, np.float32))
        with pytest.raises(ValueError, match="floating point"):
            envs.step(xp.zeros((4, 4), np.int32))
    with pytest.raises(ValueError, match="floating point"):
        same_step.step([[None] * 4] * 4)
    for bad in (-1, 1.5, True):
        with pytest.raises(ValueError, match="seed must be a non-negative int"):
            same_step.reset(seed=bad)
    with pytest.raises(ValueError, match="multiple"):
        gym.make_vec("mwjax/MT10", num_envs=15)
    for bad in (0, -10, 2.5, True):
        with pytest.raises(ValueError, match="num_envs .* must be a positive int"):
            gym.make_vec("mwjax/MT10", num_envs=bad)
    with pytest.raises(ValueError, match="envs_per_task must be a positive int"):
        gym.make_vec("mwjax/MT10", envs_per_task=0)
    with pytest.raises(ValueError, match="meta_batch_size must be a positive int"):
        gym.make_vec("mwjax/ML10-train", meta_batch_size=0)
    with pytest.raises(ValueError, match="multiple"):
        gym.make_vec("mwjax/ML10-train", meta_batch_size=15)
    with pytest.raises(ValueError, match="cannot contain"):
        gym.make_vec("mwjax/custom-ml-envs", train_envs=TASKS, test_envs=["push-v3"])
    with pytest.raises(ValueError, match="unknown task"):
        gym.make_vec("mwjax/MT1", env_name="reach-v2")


def test_torch_arrays_need_the_torch_extra():
    if importlib.util.find_spec("torch") is not None:
        pytest.skip("PyTorch is installed")
    with pytest.raises(ModuleNotFoundError, match=r"mwjax\[torch\]"):
        gym.make_vec("mwjax/MT10", array_type="torch")


def test_physics_settings_reach_the_env():
    physics = mwjax.PhysicsConfig(graph_mode="none", contacts_per_env=16)
    envs = gym.make_vec("mwjax/MT1", env_name="reach-v3", physics=physics, array_type="jax")
    assert envs.unwrapped.env.physics.config == physics


@pytest.fixture(scope="module")
def ml_test():
    # The reference's default meta_batch_size (20) crashes ML1 (50 goals don't split into 20
    # equal shares); here the 20 envs get 3 or 2 goals each.
    return gym.make_vec(
        "mwjax/ML1-test", env_name="reach-v3", seed=4, max_episode_steps=150, array_type="jax"
    )


def test_ml_goals_are_hidden_fixed_and_cycled(ml_test):
    envs = ml_test
    assert envs.num_envs == 20
    obs, _ = envs.reset(seed=0)
    assert not np.any(np.asarray(obs[:, 36:39]))
    core = envs.unwrapped.env
    variants = [np.asarray(envs.unwrapped.state.variant)]
    # The test split's goals are the ML1 test goals (sampled with seed + 1), not the train goals.
    assert not np.array_equal(
        core.goal_variants["reach-v3"], mwjax.make("ML1", task="reach-v3", seed=4).goal_variants["reach-v3"]
    )
    for _ in range(3):
        envs.sample_tasks()
        variants.append(np.asarray(envs.unwrapped.state.variant))
    variants = np.stack(variants)  # (4, 20)
    # Env i owns goals i and i + 20 (and i + 40 for i < 10): within a cycle it never repeats one.
    for i in range(20):
        owned = set(range(i, 50, 20))
        assert set(variants[:, i]) <= owned
        cycle = len(owned)
        assert len(set(variants[:cycle, i])) == cycle


def test_terminate_on_success_in_ml_test_envs(ml_test):
    envs = ml_test
    expert = policies.expert_policy(envs.unwrapped.env)
    obs, _ = envs.reset(seed=1)
    terminated_any = np.zeros(20, bool)
    for _ in range(150):
        # The goal is hidden; give the scripted expert the true goal.
        seen = obs.at[:, 36:39].set(envs.unwrapped.state.target_pos)
        obs, _, terminated, truncated, info = envs.step(expert(None, seen, None))
        assert np.array_equal(
            np.asarray(terminated),
            np.asarray(info["final_info"]["success"]) & np.asarray(info["_final_info"]),
        )
        terminated_any |= np.asarray(terminated)
        if terminated_any.all():  # the expert needs far fewer than 150 steps on every goal
            break
    assert terminated_any.all()


def test_single_env_passes_gymnasium_check():
    env = gym.make("mwjax/MT1", env_name="reach-v3", seed=0, max_episode_steps=20)
    check_env(env.unwrapped, skip_render_check=True)
    obs, _ = env.reset(seed=0)
    assert env.observation_space.contains(obs)
    with pytest.raises(ValueError, match="floating point"):
        env.step(np.zeros(4, np.int64))
    for step in range(20):
        obs, reward, terminated, truncated, info = env.step(env.action_space.sample())
        assert isinstance(reward, float) and truncated == (step == 19)
    assert set(info) >= {"success", "near_object", "episode_return"}


def test_default_truncation_is_500():
    envs = gym.make_vec("mwjax/MT1", env_name="reach-v3", num_envs=2, array_type="jax")
    envs.reset(seed=0)
    actions = jnp.zeros((2, 4))
    for step in range(1, 501):
        _, _, _, truncated, info = envs.step(actions)
        assert bool(truncated.all()) == (step == 500)
    assert np.asarray(info["final_info"]["episode"]["l"]).tolist() == [500, 500]


def test_the_adapter_uses_warp_staged_graphs_on_one_gpu_only(monkeypatch):
    """Where the caller leaves Warp's graph mode to MJX, the adapter asks for the staged mode on
    one GPU (its Python-stepped calls then replay their graphs), with the scenes side by side
    unless the caller or MWJAX_CONCURRENT_SCENES=0 chose otherwise, and leaves it alone on the CPU,
    over several devices, in the deterministic mode and where the caller chose a mode."""
    from types import SimpleNamespace

    from mwjax import determinism
    from mwjax.wrappers import gymnasium as adapter

    gpu, cpu = SimpleNamespace(platform="gpu"), SimpleNamespace(platform="cpu")
    chosen = mwjax.PhysicsConfig(graph_mode="none", contacts_per_env=32)
    monkeypatch.setattr(adapter, "local_device", lambda: gpu)
    monkeypatch.delenv("MWJAX_CONCURRENT_SCENES", raising=False)
    staged = adapter._adapter_physics(mwjax.PhysicsConfig(contacts_per_env=32), None)
    assert staged == mwjax.PhysicsConfig(
        graph_mode="warp_staged_ex", contacts_per_env=32, concurrent_scenes=True
    )
    in_turn = mwjax.PhysicsConfig(concurrent_scenes=False)
    assert adapter._adapter_physics(in_turn, None).concurrent_scenes is False
    monkeypatch.setenv("MWJAX_CONCURRENT_SCENES", "0")
    assert adapter._adapter_physics(None, None) == mwjax.PhysicsConfig(
        graph_mode="warp_staged_ex", concurrent_scenes=False
    )
    monkeypatch.delenv("MWJAX_CONCURRENT_SCENES")
    assert adapter._adapter_physics(None, [gpu]).graph_mode == "warp_staged_ex"
    assert adapter._adapter_physics(None, [gpu, gpu]).graph_mode is None
    assert adapter._adapter_physics(None, [cpu]).graph_mode is None
    assert adapter._adapter_physics(chosen, None) == chosen
    monkeypatch.setattr(determinism, "enabled", lambda: True)
    assert adapter._adapter_physics(None, None).graph_mode is None
    monkeypatch.setattr(adapter, "local_device", lambda: cpu)
    monkeypatch.setattr(determinism, "enabled", lambda: False)
    assert adapter._adapter_physics(None, None).graph_mode is None
