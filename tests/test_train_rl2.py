"""CPU smoke test of the jitted RL² loop (`examples/train_ml_rl2.py`); the real run is a GPU
benchmark. A custom ML set of two tasks of one scene (reach to train, push to test), a tiny batch,
4-step episodes and 2-episode trials keep it short; the envs start in lockstep (their staggered
starts have their own test) so that every two updates end an episode and every four a trial."""

import dataclasses
import json
import sys
import types
from pathlib import Path
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import mwjax
from examples import train_ml_rl2 as rl2
from mwjax import distributed, policies
from mwjax.benchmarks import custom_ml

EPISODE = 4
CONFIG = rl2.Config(
    task_set=custom_ml(["reach-v3"], ["push-v3"]),
    envs_per_task=4,
    episodes_per_trial=2,
    max_episode_steps=EPISODE,
    unroll=EPISODE // 2,
    staggered_starts=False,
    minibatches=2,
    epochs=2,
    embed=16,
    hidden=8,
    adaptation_episodes=1,
    evaluation_episodes=1,
    eval_envs_per_task=2,
    eval_rounds=2,
)


@pytest.fixture(scope="module")
def trainer():
    return rl2.Trainer(CONFIG)


def _leaves(tree):
    return [np.array(x) for x in jax.tree.leaves(tree)]


def test_updates_are_finite_and_change_the_policy(trainer):
    carry = trainer.init(jax.random.key(0))
    before = _leaves(carry.params)
    types = jax.tree.map(jax.typeof, carry)
    for _ in range(2):
        carry, metrics = trainer.train_chunk(carry, 2)
        # The carry comes back as it went in (dtypes, weak types): later chunks do not compile again.
        assert jax.tree.map(jax.typeof, carry) == types
        assert np.isfinite(metrics.loss) and np.isfinite(metrics.approx_kl)
        # The loss is its terms' weighted sum, up to the entropy bonus (its coefficient times at
        # most 4 action dims' entropies, which moved a little over the minibatches).
        assert metrics.value_loss > 0
        bonus = CONFIG.entropy_coef * 4 * (np.abs(carry.params.log_std).max() + 1.5)
        assert abs(metrics.loss - metrics.policy_loss - CONFIG.value_coef * metrics.value_loss) <= bonus
        # Two updates are one episode: every env ended exactly one.
        np.testing.assert_array_equal(metrics.episodes, [CONFIG.envs_per_task])
        assert np.all(metrics.successes <= metrics.episodes)
        # The chunk's metrics make a learning-curve row as `train` logs it.
        row = rl2.ppo._row(metrics, 2, trainer, 0.0)
        assert row["env_steps"] == 2 * trainer.steps_per_update and row["train_success"] is not None
        assert (row["policy_loss"], row["value_loss"]) == (metrics.policy_loss, metrics.value_loss)
    after = _leaves(carry.params)
    assert all(np.all(np.isfinite(x)) for x in after)
    assert any(not np.array_equal(old, new) for old, new in zip(before, after, strict=True))
    assert float(carry.norm.obs.count) == 2 * EPISODE * trainer.env.num_envs
    # One train task: its own return statistics are the one scale's.
    for own, shared in zip(carry.norm.task_returns, carry.norm.returns, strict=True):
        np.testing.assert_allclose(np.asarray(own), np.asarray(shared))


def test_the_hidden_state_runs_on_within_a_trial_and_resets_between_trials(trainer):
    carry = trainer.init(jax.random.key(1))
    goals = np.asarray(carry.env_state.goal_cursor)
    # Two updates: the trial's first episode ends; its second starts on the same goal.
    carry, _ = trainer.train_chunk(carry, 2)
    np.testing.assert_array_equal(np.asarray(carry.trial_step), EPISODE)
    assert np.all(np.abs(np.asarray(carry.hidden)).sum(axis=1) > 0), "hidden state kept across episodes"
    assert np.all(np.asarray(carry.first)), "the done flag marks the new episode"
    assert np.any(np.asarray(carry.prev_reward) != 0), "the previous reward is carried over"
    np.testing.assert_array_equal(np.asarray(carry.env_state.goal_cursor), goals)
    # The carried hidden state changes what the policy does at the next episode's first step.
    x = trainer.inputs(carry.norm, carry.env_state.obs, carry.prev_action, carry.prev_reward, carry.first)
    _, carried, _ = trainer.core(carry.params, carry.hidden, x)
    _, fresh, _ = trainer.core(carry.params, jnp.zeros_like(carry.hidden), x)
    assert not np.allclose(np.asarray(carried), np.asarray(fresh))
    # Two more: the trial ends; every env moves to its next goal with a zero hidden state.
    carry, _ = trainer.train_chunk(carry, 2)
    np.testing.assert_array_equal(np.asarray(carry.trial_step), 0)
    np.testing.assert_array_equal(np.asarray(carry.hidden), 0.0)
    np.testing.assert_array_equal(np.asarray(carry.prev_action), 0.0)
    np.testing.assert_array_equal(np.asarray(carry.prev_reward), 0.0)
    np.testing.assert_array_equal(np.asarray(carry.env_state.goal_cursor), goals + 1)


def test_the_learner_replays_the_rollouts_policy_across_a_trial_boundary(trainer):
    """The loss re-runs the GRU from the chunk's first hidden state, zeroing it where a trial
    began: on the rollout's own parameters that gives back the rollout's log-probabilities."""
    rollout = jax.jit(trainer.rollout)
    carry = trainer.init(jax.random.key(2))
    resets = []
    for _ in range(5):  # the fifth chunk starts the second trial
        start = carry
        carry, batch, h0, _ = rollout(carry)
        mean, value = trainer.sequence(carry.params, h0, batch.inputs, batch.reset)
        log_prob = rl2._log_prob(mean, carry.params.log_std, batch.action)
        np.testing.assert_allclose(np.asarray(log_prob), np.asarray(batch.log_prob), rtol=1e-5, atol=1e-5)
        np.testing.assert_allclose(np.asarray(value), np.asarray(batch.value), rtol=1e-5, atol=1e-5)
        np.testing.assert_array_equal(np.asarray(h0), np.asarray(start.hidden))
        resets.append(np.asarray(batch.reset))
        trial_end = np.asarray(batch.trial_end)
        assert trial_end.all(axis=1).sum() == trial_end.any(axis=1).sum() == (len(resets) == 4)
    resets = np.stack(resets)  # (chunks, steps, envs)
    np.testing.assert_array_equal(resets.all(axis=2)[:, 0], [True, False, False, False, True])
    assert not resets.any(axis=2)[:, 1:].any() and not resets.any(axis=2)[1:4].any()


def test_staggered_starts_put_each_env_at_its_own_point_of_a_trial(trainer):
    carry = trainer.stagger(trainer.init(jax.random.key(7)), jax.random.key(8))
    start = np.asarray(carry.trial_step)
    assert len(set(start.tolist())) > 1, "the envs should start at different points"
    assert np.all(start % CONFIG.unroll == 0)
    goals = np.asarray(carry.env_state.goal_cursor)
    rollout = jax.jit(trainer.rollout)
    trial_ends, firsts, full = [], [], 0
    for _ in range(trainer.trial_length // CONFIG.unroll):  # one trial's steps
        carry, batch, _, (ended, _, _) = rollout(carry)
        trial_ends.append(np.asarray(batch.trial_end))
        firsts.append(np.asarray(batch.inputs[..., -1]))  # the "episode just ended" flag
        full += int(np.asarray(ended).sum())
    trial_ends, firsts = np.concatenate(trial_ends), np.concatenate(firsts)  # (steps, envs)
    for env, s in enumerate(start):
        # Its (first, partial) trial ends after the rest of it, and so does the episode then.
        np.testing.assert_array_equal(np.flatnonzero(trial_ends[:, env]) + 1, [trainer.trial_length - s])
        # Its first episode is cut to end where the trial's episodes end.
        into = s % EPISODE
        episode_starts = np.flatnonzero(firsts[1:, env]) + 1
        expected = np.arange(EPISODE - into if into else EPISODE, trainer.trial_length, EPISODE)
        np.testing.assert_array_equal(episode_starts, expected, err_msg=f"env {env}, started at {s}")
    # Each env moved on to its next goal once; only full-length episodes count toward success.
    np.testing.assert_array_equal(np.asarray(carry.env_state.goal_cursor), goals + 1)
    assert full == sum(
        len(range(EPISODE, trainer.trial_length + 1, EPISODE)) - (s % EPISODE > 0) for s in start
    )


def test_checkpoints_round_trip(trainer, tmp_path):
    carry = trainer.init(jax.random.key(3))
    carry, _ = trainer.train_chunk(carry, 2)
    curve = [{"updates": 2, "loss": 0.5}]
    rl2.ppo.save_checkpoint(tmp_path / "ckpt", carry, 2, curve)
    restored, updates, restored_curve = rl2.ppo.restore_checkpoint(
        tmp_path / "ckpt", trainer.init(jax.random.key(4))
    )
    assert updates == 2 and restored_curve == curve
    saved = (carry.params, carry.opt_state, carry.norm, jax.random.key_data(carry.key))
    loaded = (restored.params, restored.opt_state, restored.norm, jax.random.key_data(restored.key))
    for a, b in zip(_leaves(saved), _leaves(loaded), strict=True):
        np.testing.assert_array_equal(a, b)
    # The restored learner trains on.
    restored, metrics = trainer.train_chunk(restored, 2)
    assert np.isfinite(metrics.loss)


def test_the_meta_test_runs_on_the_test_tasks(trainer):
    carry = trainer.init(jax.random.key(5))
    result = trainer.meta_tester()(carry.params, carry.norm, jax.random.key(6))
    assert trainer.test_env.task_list == ("push-v3",)
    # One test task; 2 envs x 2 rounds = 4 goals, each with one evaluation episode.
    assert result.success.shape == (1, CONFIG.eval_envs_per_task * CONFIG.eval_rounds)
    rate = np.asarray(result.success_rate)
    assert np.all((rate >= 0) & (rate <= 1))
    np.testing.assert_allclose(rate, np.asarray(result.success).mean(axis=1))
    # The same protocol on the train tasks (a diagnostic), on their own env.
    on_train = trainer.meta_tester("train")(carry.params, carry.norm, jax.random.key(6))
    assert trainer.train_tasks_eval_env.task_list == ("reach-v3",)
    assert on_train.success.shape == (1, CONFIG.eval_envs_per_task * CONFIG.eval_rounds)
    with pytest.raises(ValueError, match="split must be"):
        trainer.meta_tester("validation")


class _Scripted(NamedTuple):
    episodes: jax.Array  # how many of a trial's episodes the expert acts in
    log_std: jax.Array


class _ExpertTrainer(rl2.Trainer):
    """The meta-test's protocol driven by reach's scripted expert in place of the GRU, on envs that
    show the goal. The expert acts in a trial's first `params.episodes` episodes (counted in the
    hidden state from the "episode just ended" input) and does nothing after them."""

    def _make_env(self, envs_per_task, split):
        cfg = self.config
        return mwjax.make(
            cfg.task_set, split=split, envs_per_task=envs_per_task, max_episode_steps=cfg.max_episode_steps,
            goal_sampling="on_request", partially_observable=False,
        )  # fmt: skip

    @staticmethod
    def inputs(norm, obs, prev_action, prev_reward, first):
        return jnp.concatenate([obs, first[:, None].astype(jnp.float32)], axis=-1)

    @staticmethod
    def core(params, hidden, inputs):
        episode = hidden[:, 0] + inputs[:, -1]
        action = jax.vmap(policies.expert("reach-v3"))(inputs[:, :-1])
        action = jnp.where((episode <= params.episodes)[:, None], action, 0.0)
        return hidden.at[:, 0].set(episode), action, jnp.zeros(inputs.shape[0])


def test_the_meta_test_counts_each_goals_evaluation_episodes():
    """One adaptation episode, then 3 evaluation episodes, each ending at its success: an expert
    acting throughout solves all 3, one that stops after the first evaluation episode solves 1 of 3
    (an episode that did not restart at success would stay solved), one that never acts none."""
    config = dataclasses.replace(
        CONFIG, task_set=custom_ml(["push-v3"], ["reach-v3"]), max_episode_steps=100,
        adaptation_episodes=1, evaluation_episodes=3, eval_rounds=1,
    )  # fmt: skip
    meta_test = _ExpertTrainer(config).meta_tester()
    quiet = jnp.full(4, -20.0)  # adaptation samples the mean action
    for episodes, rate in [(4, 1.0), (2, 1 / 3), (0, 0.0)]:
        result = meta_test(_Scripted(jnp.float32(episodes), quiet), None, jax.random.key(0))
        np.testing.assert_allclose(np.asarray(result.success), rate, err_msg=f"expert in {episodes} episodes")


@pytest.mark.slow
def test_train_resumes_from_its_checkpoint(tmp_path):
    stem = tmp_path / "run"
    first = rl2.train(CONFIG, log_every=1, max_updates=1, checkpoint=stem)
    assert [r["updates"] for r in first["curve"]] == [1]
    assert 0.0 <= first["meta_test_success"] <= 1.0
    config = dataclasses.replace(CONFIG, meta_test_train_tasks=True)
    second = rl2.train(config, log_every=1, max_updates=2, checkpoint=stem)
    assert [r["updates"] for r in second["curve"]] == [1, 2]
    assert (
        second["curve"][0] == first["curve"][0] and second["curve"][1]["wall_s"] > first["curve"][0]["wall_s"]
    )
    assert list(second["meta_test_success_per_task"]) == ["push-v3"]
    assert list(second["meta_test_success_train_tasks_per_task"]) == ["reach-v3"]
    assert 0.0 <= second["meta_test_success_train_tasks"] <= 1.0


def test_seeds_in_parallel_make_one_summary(tmp_path, monkeypatch):
    """`--parallel 2` (the PPO example's helper): two seeds' results, faked here, become one
    summary with the IQM over seeds."""

    def run_each(commands, logs, parallel, cpu=False):
        for command, log in zip(commands, logs, strict=True):
            seed = int(command[len(command) - command[::-1].index("--seeds")])
            out = command[len(command) - command[::-1].index("--out")]
            per_task = {"push-v3": 0.5 + seed / 4}
            run = {"name": "ML10", "curve": [], "meta_test_success": per_task["push-v3"]}
            run |= {"meta_test_success_per_task": per_task, "config": {"seed": seed}}
            Path(f"{out}.json").write_text(json.dumps({"device": "test device", "runs": [run]}))
            log.write_text("trained\n")
        return [0] * len(commands)

    monkeypatch.setattr(distributed, "run_independent", run_each)
    monkeypatch.setattr(rl2.ppo, "save_plot", lambda plot, runs, path: False)
    stem = tmp_path / "run"
    argv = ["train_ml_rl2.py", "--seeds", "0", "1", "--parallel", "2", "--out", str(stem)]
    monkeypatch.setattr(sys, "argv", argv)
    with pytest.raises(SystemExit) as exit:
        rl2.main()
    assert exit.value.code == 0
    summary = json.loads(Path(f"{stem}.json").read_text())
    assert summary["meta_test_success"] == [0.5, 0.75] and "iqm_ci95" in summary
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run-seed0.log", "run-seed1.log", "run.json"]


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["--set", "MT10"], "RL² trains on a meta-learning set"),
        (["--set", "ML1"], "ML1 needs task="),
        (["--envs-per-task", "0"], "envs_per_task must be a positive int"),
        (["--max-episode-steps", "0"], "max_episode_steps must be a positive int"),
    ],
)
def test_bad_arguments_end_in_a_usage_error_before_any_work(monkeypatch, usage_error, argv, message):
    monkeypatch.setattr(sys, "argv", ["train_ml_rl2.py", *argv])
    monkeypatch.setattr(rl2, "train", lambda *args, **kwargs: pytest.fail("a refused run trains nothing"))
    assert message in usage_error(rl2.main)


def test_combine_summarizes_seeds_trained_by_separate_invocations(tmp_path, monkeypatch):
    """`--combine`: the RL² example's seeds from separate device calls, one summary."""
    files = []
    for seed in (0, 1):
        run = {"name": "ML10", "curve": [], "meta_test_success": 0.25 * seed}
        run |= {"meta_test_success_per_task": {"push-v3": 0.25 * seed}, "config": {"seed": seed}}
        data = {"device": "test device", "commit": "abc1234", "command": f"seed {seed}", "date": "today"}
        files.append(tmp_path / f"seed{seed}.json")
        files[-1].write_text(json.dumps(data | {"runs": [run]}))
    monkeypatch.setattr(rl2.ppo, "save_plot", lambda plot, runs, path: False)
    stem = tmp_path / "all"
    monkeypatch.setattr(sys, "argv", ["train_ml_rl2.py", "--combine", *map(str, files), "--out", str(stem)])
    rl2.main()
    summary = json.loads(Path(f"{stem}.json").read_text())
    assert summary["meta_test_success"] == [0.0, 0.25] and summary["commit"] == "abc1234"
    assert [s["command"] for s in summary["combined_from"]] == ["seed 0", "seed 1"] and "iqm_ci95" in summary


@pytest.mark.parametrize("per_task", [True, False])
def test_advantages_are_normalized_per_train_task(per_task):
    """Two train tasks laid out task by task, one with 100x the other's advantages: per task,
    each gets mean 0 and std 1; over all envs, the small task's advantages shrink to ~0."""
    config = dataclasses.replace(CONFIG, per_task_advantages=per_task)
    learner = types.SimpleNamespace(config=config, n_tasks=2)
    raw = np.random.default_rng(0).normal(size=(3, 2, 4)) * np.array([1.0, 100.0])[None, :, None] + 5.0
    out = np.asarray(rl2.Trainer._normalized(learner, jnp.asarray(raw.reshape(3, 8), jnp.float32)))
    by_task = out.reshape(3, 2, 4)
    if per_task:
        np.testing.assert_allclose(by_task.mean(axis=(0, 2)), 0.0, atol=1e-5)
        np.testing.assert_allclose(by_task.std(axis=(0, 2)), 1.0, atol=1e-4)
    else:
        np.testing.assert_allclose([out.mean(), out.std()], [0.0, 1.0], atol=1e-4)
        assert by_task[:, 0].std() < 0.05


def test_mlp_heads_read_the_gru_state_and_the_input_embedding():
    """`Config.head`: policy and value are MLPs on `[GRU state, embedding]`, trained through."""
    config = dataclasses.replace(CONFIG, head=(12,))
    params = rl2.Trainer.init_params(types.SimpleNamespace(config=config), jax.random.key(0))
    for layers, out in ((params.policy, 4), (params.value, 1)):
        assert [w.shape for w, _ in layers] == [(config.hidden + config.embed, 12), (12, out)]
    inputs = jax.random.normal(jax.random.key(1), (3, rl2.INPUT_SIZE))
    hidden = jax.random.normal(jax.random.key(2), (3, config.hidden))

    def objective(params):
        _, mean, value = rl2.Trainer.core(params, hidden, inputs)
        return jnp.sum(mean**2) + jnp.sum(value**2)

    # Jitted: eagerly, each operation of the forward and backward pass compiles a program of its
    # own (about 60, 3 s on a 2-core CPU).
    grads = jax.jit(jax.grad(objective))(params)
    for w, _ in [*grads.policy, *grads.value, grads.embed]:
        assert np.all(np.isfinite(w)) and np.any(w != 0)
    # Without `head` each is one linear layer on the GRU state, as before.
    plain = rl2.Trainer.init_params(types.SimpleNamespace(config=CONFIG), jax.random.key(0))
    assert [w.shape for w, _ in plain.policy] == [(CONFIG.hidden, 4)]


def test_per_task_returns_scale_each_envs_rewards_by_its_own_tasks_return_std():
    stats = rl2.ppo.RunningStats
    norm = rl2.Normalizers(
        stats.zeros((3,)),
        stats(jnp.array(5.0), jnp.array([1.0]), jnp.array([9.0])),
        stats(jnp.array(5.0), jnp.array([1.0, 2.0]), jnp.array([4.0, 16.0])),
    )

    def scale(per_task_returns):
        config = dataclasses.replace(CONFIG, envs_per_task=3, per_task_returns=per_task_returns)
        return np.asarray(rl2.Trainer.reward_scale(types.SimpleNamespace(config=config), norm))

    np.testing.assert_allclose(scale(True), [2.0, 2.0, 2.0, 4.0, 4.0, 4.0], rtol=1e-6)
    np.testing.assert_allclose(scale(False), [3.0], rtol=1e-6)
