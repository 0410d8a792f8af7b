"""The evaluation protocol: the jax experts through the functional evaluator and the reference-
style `evaluation`, `metalearning_evaluation` with a trivial adapting agent on ML10-test, and
the aggregate statistics."""

from __future__ import annotations

import logging

import gymnasium as gym
import jax
import numpy as np
import pytest
import scipy.stats

import mwjax
from mwjax import policies, stats
from mwjax.benchmarks import ML10_TEST
from mwjax.evaluation import evaluation, evaluator, metalearning_evaluation

# Tasks on which the reference experts solve all 50 seed-42 goals (benchmarks/results/reference/
# reference-experts-seed42.json); two share a scene. The experts need well under 150 steps on
# them; a shorter horizon keeps the CPU rollouts short.
EXPERT_TASKS = ["reach-v3", "drawer-open-v3", "drawer-close-v3"]
HORIZON = 150


def test_experts_solve_their_tasks_in_the_functional_evaluator():
    env = mwjax.make(EXPERT_TASKS, seed=42, max_episode_steps=HORIZON)
    run = jax.jit(evaluator(env, policies.expert_policy(env.replace(envs_per_task=2)), 2))
    result = run(None, jax.random.key(0))
    assert result.success.shape == (3, 2) and result.returns.shape == (3, 2)
    np.testing.assert_array_equal(np.asarray(result.success_rate), [1.0, 1.0, 1.0])
    lengths = np.asarray(result.lengths)
    assert np.all((lengths > 1) & (lengths < HORIZON))  # episodes end at success
    assert np.all(np.asarray(result.returns) > 0)
    assert result.dropped.shape == (3, 2) and not np.asarray(result.dropped).any()  # default buffers


class ExpertAgent:
    """A reference-style agent (NumPy in and out) around the jax experts."""

    def __init__(self, env):
        self.policy = jax.jit(policies.expert_policy(env))
        self.resets = 0

    def eval_action(self, observations):
        return np.asarray(self.policy(None, observations, None))

    def reset(self, env_mask):
        self.resets += int(np.sum(env_mask))


def test_reference_style_evaluation_matches_the_functional_one():
    envs = gym.make_vec("mwjax/MT1", env_name="reach-v3", seed=42, max_episode_steps=HORIZON)
    core = envs.unwrapped.env
    eval_core = core.replace(envs_per_task=4)
    agent = ExpertAgent(eval_core)
    mean_success, mean_return, per_task, returns = evaluation(agent, envs, num_episodes=4)
    assert mean_success == 1.0 and per_task == {"reach-v3": 1.0}
    assert len(returns["reach-v3"]) == 4 and mean_return == pytest.approx(np.mean(returns["reach-v3"]))
    assert agent.resets == 4 + 4  # the start, then each episode's end
    # Jitted as it is meant to run: eagerly, each of its operations compiles a program of its own
    # (7 s more on a 2-core CPU).
    functional = jax.jit(evaluator(core, policies.expert_policy(eval_core), 4))(None, jax.random.key(0))
    np.testing.assert_allclose(returns["reach-v3"], np.asarray(functional.returns[0]), rtol=1e-5)


class BestRandomActionAgent:
    """Adapts trivially: during adaptation it tries random constant actions per env and keeps,
    per env, the one with the best reward; evaluation replays it."""

    def __init__(self, num_envs, seed=0):
        self.rng = np.random.default_rng(seed)
        self.num_envs = num_envs
        self.calls = {"init": 0, "adapt": 0, "step": 0}

    def init(self):
        self.calls["init"] += 1
        self.best_reward = np.full(self.num_envs, -np.inf)
        self.best_action = np.zeros((self.num_envs, 4), np.float32)
        self.episodes = np.zeros(self.num_envs, int)

    def adapt_action(self, observations):
        assert observations.shape == (self.num_envs, 39) and not np.any(observations[:, 36:])
        actions = self.rng.uniform(-1, 1, (self.num_envs, 4)).astype(np.float32)
        return actions, {"log_prob": np.zeros(self.num_envs)}

    def step(self, timestep):
        self.calls["step"] += 1
        better = timestep.reward > self.best_reward
        self.best_reward = np.where(better, timestep.reward, self.best_reward)
        self.best_action[better] = timestep.action[better]
        self.episodes += timestep.terminated | timestep.truncated

    def adapt(self):
        self.calls["adapt"] += 1

    def eval_action(self, observations):
        return self.best_action

    def reset(self, env_mask):
        pass


def test_metalearning_evaluation_on_ml10_test(caplog):
    envs = gym.make_vec("mwjax/ML10-test", meta_batch_size=5, max_episode_steps=4, seed=0)
    agent = BestRandomActionAgent(envs.num_envs)
    with jax.log_compiles(), caplog.at_level(logging.WARNING, logger="jax"):
        mean_success, mean_return, per_task = metalearning_evaluation(
            agent, envs, num_evals=2, adaptation_steps=1, adaptation_episodes=2, evaluation_episodes=2
        )
    # Adaptation and evaluation (which ends episodes at success) share one step program.
    compiled = [r.message for r in caplog.records if r.message.startswith("Finished XLA compilation")]
    assert sum(" jit(step) " in m for m in compiled) == 1, compiled
    assert agent.calls["init"] == 2 and agent.calls["adapt"] == 2
    assert agent.calls["step"] == 2 * 2 * 4  # 2 evals x 2 episodes x 4 steps, no early termination
    assert list(per_task) == list(ML10_TEST)
    assert all(0.0 <= rate <= 1.0 for rate in per_task.values())
    assert 0.0 <= mean_success <= 1.0 and np.isfinite(mean_return) and mean_return > 0


def test_iqm_and_stratified_bootstrap():
    rng = np.random.default_rng(0)
    scores = rng.uniform(0, 1, (10, 8))
    assert stats.iqm(scores) == pytest.approx(scipy.stats.trim_mean(scores.ravel(), 0.25))
    estimate = stats.stratified_bootstrap_ci(scores, reps=500)
    assert estimate.low < estimate.value < estimate.high
    wide = stats.stratified_bootstrap_ci(scores[:3], reps=500)
    assert wide.high - wide.low > estimate.high - estimate.low
    flat = stats.stratified_bootstrap_ci(np.full((5, 4), 0.7), reps=100)
    assert flat.low == pytest.approx(0.7) and flat.high == pytest.approx(0.7)
    with pytest.raises(ValueError):
        stats.stratified_bootstrap_ci(np.ones(5))


def test_probability_of_improvement_is_the_mean_per_task_mann_whitney_u():
    rng = np.random.default_rng(1)
    # Success rates on a grid of 0.1 so that ties occur, as with 50 evaluation episodes.
    x, y = rng.integers(0, 11, (5, 6)) / 10, rng.integers(0, 11, (7, 6)) / 10
    u = [scipy.stats.mannwhitneyu(x[:, t], y[:, t]).statistic / (len(x) * len(y)) for t in range(6)]
    estimate = stats.probability_of_improvement(x, y, reps=300)
    assert estimate.value == pytest.approx(np.mean(u))
    assert estimate.low <= estimate.value <= estimate.high
    assert stats.probability_of_improvement(y, x, reps=10).value == pytest.approx(1 - estimate.value)
    assert stats.probability_of_improvement(x + 2, x, reps=10) == (1.0, 1.0, 1.0)
    with pytest.raises(ValueError, match="same tasks"):
        stats.probability_of_improvement(x, y[:, :5])
