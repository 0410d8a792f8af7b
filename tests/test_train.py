"""CPU smoke test of the jitted multi-task PPO loop (`examples/train_mt_ppo.py`); the real run is
a GPU benchmark. Two tasks of one scene, a tiny batch and 10-step episodes keep it short."""

import contextlib
import dataclasses
import json
import os
import sys
import time
from pathlib import Path
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from examples import train_mt_ppo as ppo
from mwjax import distributed, kernels
from mwjax.stats import iqm

CONFIG = ppo.Config(
    task_set=("reach-v3", "push-v3"),
    envs_per_task=2,
    unroll=6,
    minibatches=2,
    epochs=2,
    max_episode_steps=10,
    architecture="shared",
)


@pytest.fixture(scope="module")
def trainer():
    return ppo.Trainer(CONFIG)


def test_updates_are_finite_and_change_the_policy(trainer):
    carry = trainer.init(jax.random.key(0))
    before = jax.tree.map(np.array, carry.params)
    types = jax.tree.map(jax.typeof, carry)
    carry, metrics = trainer.train_chunk(carry, 2)
    # The carry comes back as it went in (dtypes, weak types): the next chunk does not compile again.
    assert jax.tree.map(jax.typeof, carry) == types
    after = jax.tree.map(np.array, carry.params)
    assert np.isfinite(metrics.loss) and np.isfinite(metrics.approx_kl)
    # The loss is its terms' weighted sum, up to the entropy bonus (its coefficient times at most
    # 4 action dims' entropies, which moved a little over the minibatches).
    assert metrics.value_loss > 0
    bonus = CONFIG.entropy_coef * 4 * (np.abs(after.log_std).max() + 1.5)
    assert abs(metrics.loss - metrics.policy_loss - CONFIG.value_coef * metrics.value_loss) <= bonus
    pairs = list(zip(jax.tree.leaves(before), jax.tree.leaves(after), strict=True))
    assert all(np.all(np.isfinite(new)) for _, new in pairs)
    assert any(not np.array_equal(old, new) for old, new in pairs)
    # 2 updates of 6 steps of 10-step episodes: every env ended exactly one episode.
    np.testing.assert_array_equal(metrics.episodes, [CONFIG.envs_per_task] * 2)
    assert np.all(metrics.successes <= metrics.episodes)
    # The observation statistics saw every observation of both rollouts.
    assert float(carry.norm.obs.count) == 2 * CONFIG.unroll * trainer.env.num_envs
    assert np.all(np.asarray(carry.norm.returns.var) > 0)


def test_shared_normalization_gives_every_task_one_reward_scale(trainer):
    # reach and push return on different scales: per task their running statistics differ.
    own, _ = trainer.train_chunk(trainer.init(jax.random.key(0)), 1)
    own_mean, own_var = np.asarray(own.norm.returns.mean), np.asarray(own.norm.returns.var)
    assert own_var[0] != own_var[1]
    shared = ppo.Trainer(dataclasses.replace(CONFIG, normalization="shared"))
    carry, metrics = shared.train_chunk(shared.init(jax.random.key(0)), 1)
    var = np.asarray(carry.norm.returns.var)
    assert var[0] == var[1] and np.isfinite(metrics.loss)
    # The first rollout does not depend on the normalization, so the shared statistic is the
    # pooled one of the two tasks' (equally many samples each).
    np.testing.assert_allclose(var[0], own_var.mean() + own_mean.var(), rtol=1e-5)


def test_checkpoints_round_trip(trainer, tmp_path):
    carry, _ = trainer.train_chunk(trainer.init(jax.random.key(3)), 2)
    curve = [{"updates": 2, "loss": 0.5}]
    ppo.save_checkpoint(tmp_path / "ckpt", carry, 2, curve)
    restored, updates, restored_curve = ppo.restore_checkpoint(
        tmp_path / "ckpt", trainer.init(jax.random.key(4))
    )
    assert updates == 2 and restored_curve == curve
    learner = [jax.tree.map(np.asarray, ppo._learner(c)) for c in (carry, restored)]
    for a, b in zip(*map(jax.tree.leaves, learner), strict=True):
        np.testing.assert_array_equal(a, b)
    restored, metrics = trainer.train_chunk(restored, 2)  # the restored learner trains on
    assert np.isfinite(metrics.loss)
    other = ppo.Trainer(dataclasses.replace(CONFIG, hidden=(8, 8, 8)))
    with pytest.raises(ValueError, match="another configuration's"):
        ppo.restore_checkpoint(tmp_path / "ckpt", other.init(jax.random.key(4)))


def test_a_save_cut_short_leaves_the_previous_checkpoint_whole(trainer, tmp_path, monkeypatch):
    """A run stopped while it saves (or a copy taken meanwhile) must still find a checkpoint to
    resume from: the one saved before, not a truncated file."""
    carry = trainer.init(jax.random.key(3))
    ppo.save_checkpoint(tmp_path / "ckpt", carry, 2, [{"updates": 2}])
    saved = (tmp_path / "ckpt.npz").read_bytes()

    def cut_short(file, *arrays, **named):
        with contextlib.ExitStack() as stack:
            if isinstance(file, (str, os.PathLike)):
                file = stack.enter_context(open(file, "wb"))
            file.write(saved[: len(saved) // 2])
            raise KeyboardInterrupt

    monkeypatch.setattr(np, "savez", cut_short)
    with pytest.raises(KeyboardInterrupt):
        ppo.save_checkpoint(tmp_path / "ckpt", carry, 4, [{"updates": 2}, {"updates": 4}])
    monkeypatch.undo()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["ckpt.json", "ckpt.npz"]
    _, updates, curve = ppo.restore_checkpoint(tmp_path / "ckpt", trainer.init(jax.random.key(4)))
    assert updates == 2 and curve == [{"updates": 2}]


def test_a_checkpoint_saved_before_its_npz_held_the_curve_still_resumes(trainer, tmp_path):
    """Checkpoints of earlier versions kept the update count and curve only in the JSON."""
    carry = trainer.init(jax.random.key(3))
    ppo.save_checkpoint(tmp_path / "ckpt", carry, 2, [{"updates": 2}])
    with np.load(tmp_path / "ckpt.npz") as data:
        arrays = {name: data[name] for name in data.files if name != "meta"}
    np.savez(tmp_path / "ckpt.npz", **arrays)
    _, updates, curve = ppo.restore_checkpoint(tmp_path / "ckpt", trainer.init(jax.random.key(4)))
    assert updates == 2 and curve == [{"updates": 2}]


def test_a_chunk_whose_loss_is_not_finite_stops_the_run_before_its_checkpoint(trainer):
    """A learner gone NaN (here its exploration scale) stops the chunk loop with a clear error
    instead of training on for the rest of the budget; the caller saves no checkpoint of it."""
    carry = trainer.init(jax.random.key(5))
    log_std = carry.params.log_std.at[0, 0].set(np.nan)
    loop = ppo._Loop(carry._replace(params=carry.params._replace(log_std=log_std)), updates=4)
    chunks = ppo._chunks(trainer.train_chunk, loop, time.perf_counter(), 600.0, 2, 6)
    with pytest.raises(FloatingPointError, match="updates 5-6 is not finite"):
        next(chunks)
    assert loop.updates == 4


@pytest.mark.slow
def test_train_resumes_from_its_checkpoint(tmp_path):
    """A second run on the same stem goes on from the first's updates, its curve and wall clock."""
    stem = tmp_path / "run"
    first = ppo.train(CONFIG, 60.0, log_every=1, max_updates=1, eval_episodes=1, checkpoint=stem)
    second = ppo.train(CONFIG, 60.0, log_every=1, max_updates=2, eval_episodes=1, checkpoint=stem)
    assert [r["updates"] for r in second["curve"]] == [1, 2]
    assert (
        second["curve"][0] == first["curve"][0] and second["curve"][1]["wall_s"] > first["curve"][0]["wall_s"]
    )
    # A run lost in its evaluation: the same stem with `max_updates` at the checkpoint's count
    # trains no further and evaluates the saved learner as the lost run would have.
    again = ppo.train(CONFIG, 60.0, log_every=1, max_updates=2, eval_episodes=1, checkpoint=stem)
    assert again["curve"] == second["curve"]
    assert again["eval_success_per_task"] == second["eval_success_per_task"]
    assert jax.tree.all(jax.tree.map(np.array_equal, again["params"], second["params"]))


def test_the_trained_policy_runs_through_the_evaluator(trainer):
    carry = trainer.init(jax.random.key(1))
    result = trainer.evaluator(num_episodes=2)((carry.params, carry.norm), jax.random.key(2))
    assert result.success.shape == (2, 2)
    assert np.all(np.asarray(result.lengths) <= CONFIG.max_episode_steps)
    assert np.all(np.isfinite(np.asarray(result.returns)))


def _actions(trainer, carry, params):
    obs = np.asarray(carry.env_state.obs)
    with_task = np.concatenate([obs, trainer.env.task_one_hot()], axis=-1)
    return np.asarray(trainer.policy((params, carry.norm), with_task, None))


@pytest.mark.parametrize(("architecture", "layer"), [("multi-head", -1), ("per-task", 0)])
def test_a_tasks_own_layers_answer_for_that_task_alone(architecture, layer):
    trainer = ppo.Trainer(dataclasses.replace(CONFIG, architecture=architecture))
    carry = trainer.init(jax.random.key(3))
    w, b = carry.params.policy[layer]
    assert w.shape[0] == b.shape[0] == 2  # one per task
    # Move only the second task's copy of the layer.
    policy = list(carry.params.policy)
    policy[layer] = (w, b.at[1].add(0.5))
    before = _actions(trainer, carry, carry.params)
    after = _actions(trainer, carry, carry.params._replace(policy=policy))
    first, second = slice(0, CONFIG.envs_per_task), slice(CONFIG.envs_per_task, None)
    np.testing.assert_array_equal(after[first], before[first])
    assert np.all(after[second] != before[second])


def test_the_learner_and_the_rollouts_can_be_timed_alone(trainer):
    carry = trainer.init(jax.random.key(4))
    assert trainer.learner_seconds(carry, 1) > 0
    assert trainer.rollout_seconds(carry, 1) > 0


def test_staggered_starts_cut_each_first_episode_once_then_run_full_length():
    config = dataclasses.replace(CONFIG, envs_per_task=4, unroll=2, staggered_starts=True)
    trainer = ppo.Trainer(config)
    carry = trainer.init(jax.random.key(5))
    first_cut = np.asarray(carry.first_cut)
    assert len(set(first_cut.tolist())) > 1, "the first episodes should end at different steps"
    rollout = jax.jit(trainer._rollout)
    truncated, counted = [], 0
    for _ in range(2 * config.max_episode_steps // config.unroll):
        carry, batch, (episodes, _, _) = rollout(carry)
        truncated.append(np.asarray(batch.truncated))
        counted += int(np.asarray(episodes).sum())
    truncated = np.concatenate(truncated)  # (steps, envs)
    full_length = 0
    for env, cut in enumerate(first_cut):
        ends = np.flatnonzero(truncated[:, env]) + 1  # as env steps taken so far
        start = cut if cut > 0 else config.max_episode_steps
        expected = np.arange(start, len(truncated) + 1, config.max_episode_steps)
        np.testing.assert_array_equal(ends, expected, err_msg=f"env {env}, first cut at {cut}")
        full_length += len(expected) - (cut > 0)
    # Only full-length episodes count toward training success.
    assert counted == full_length


def test_policy_frames_show_one_episode_of_each_task(trainer):
    carry = trainer.init(jax.random.key(6))
    # The mean action saturated at +1: the hand moves a centimetre per step.
    w, b = carry.params.policy[-1]
    params = carry.params._replace(policy=[*carry.params.policy[:-1], (w, b + 2.0)])
    frames = trainer.policy_frames((params, carry.norm), jax.random.key(7), size=32)
    # The reset frame and every step of the episode, an image per task.
    assert frames.shape == (CONFIG.max_episode_steps + 1, 2, 32, 32, 3) and frames.dtype == np.uint8
    assert all(frames[0, task].std() > 10 for task in range(2))  # a scene, not a blank image
    assert np.abs(frames[-1].astype(int) - frames[0]).max() > 50  # the arm moved
    still = trainer.policy_frames((carry.params, carry.norm), jax.random.key(7), size=32)
    assert not np.array_equal(frames[-1], still[-1])  # the policy's actions drove it


def test_several_gpus_train_in_one_process_each(monkeypatch):
    launched = []
    monkeypatch.delenv("JAX_PLATFORMS", raising=False)
    monkeypatch.delenv(distributed.PROCESS_ID, raising=False)
    monkeypatch.setattr(distributed, "visible_gpus", lambda: ["0", "1", "2", "3"])
    monkeypatch.setattr(distributed, "launch", lambda command, n: launched.append((command, n)) or 0)
    monkeypatch.setattr(sys, "argv", ["train_mt_ppo.py", "--devices", "all"])
    assert ppo.one_process_per_gpu("all") == 0
    assert launched == [([ppo.__file__, "--devices", "all"], 4)]
    assert ppo.one_process_per_gpu("2") == 0 and launched[-1][1] == 2
    assert ppo.one_process_per_gpu("1") is None  # one GPU: trains here
    monkeypatch.setenv(distributed.PROCESS_ID, "0")
    assert ppo.one_process_per_gpu("all") is None  # already one of the processes
    monkeypatch.delenv(distributed.PROCESS_ID)
    monkeypatch.setattr(distributed, "visible_gpus", lambda: [])
    assert ppo.one_process_per_gpu("all") is None  # host devices (no GPU): one process


class _Build:
    """A kernel build under way (`kernels.start_build`'s result) that logs when it is waited for."""

    def __init__(self, log: list, tasks: Any = None) -> None:
        self.log, self.done = log, False
        if tasks is not None:
            log.append(tasks)

    def wait(self) -> None:
        self.log.append("built")
        self.done = True


def test_the_first_chunk_compiles_while_the_kernels_build(trainer):
    """With a kernel build under way, the first chunk's program compiles before the build is
    waited for, runs after it, and serves the chunks of its size; the chunks learn what they
    learn without the build."""
    events: list = []

    class Chunk:  # the trainer's jitted chunk, its compiles and calls logged
        def lower(self, carry, n):
            events.append(("lower", n))
            return trainer.train_chunk.lower(carry, n)

        def __call__(self, carry, n):
            events.append(("call", n))
            return trainer.train_chunk(carry, n)

    carry = trainer.init(jax.random.key(7))
    copy = jax.tree.map(jnp.copy, carry)
    ahead = list(ppo._chunks(Chunk(), ppo._Loop(carry, 0), time.perf_counter(), 600.0, 2, 5, _Build(events)))
    assert events == [("lower", 2), "built", ("call", 1)]  # 2 + 2 from the compiled program, then 1
    plain = list(ppo._chunks(trainer.train_chunk, ppo._Loop(copy, 0), time.perf_counter(), 600.0, 2, 5))
    for got, want in zip(ahead, plain, strict=True):
        np.testing.assert_array_equal(got.loss, want.loss)
        np.testing.assert_array_equal(got.successes, want.successes)


def _fake_seed_run(command: list[str], log: Path) -> None:
    """What a seed's child run leaves: its JSON at its `--out` and its log."""
    seed = int(command[len(command) - 1 - command[::-1].index("--seeds") + 1])
    out = command[len(command) - 1 - command[::-1].index("--out") + 1]
    rates = {"reach-v3": 0.5 + seed / 4, "push-v3": 0.25}
    row = {"updates": 1, "env_steps": 8, "wall_s": 1.0, "train_success": None, "loss": 0.1}
    row |= {"train_success_per_task": rates, "approx_kl": 0.0}
    config = {"task_set": ("reach-v3", "push-v3"), "reward_version": "v2", "seed": seed}
    run = {"config": config, "curve": [row], "eval_success": sum(rates.values()) / 2}
    run |= {"eval_success_per_task": rates, "train_s": 1.0, "eval_s": 1.0}
    Path(f"{out}.json").write_text(json.dumps({"device": "test device", "runs": [run]}))
    log.write_text(f"seed {seed} trained\n")


def test_seeds_in_parallel_make_one_summary(tmp_path, monkeypatch):
    """`--parallel 2` on GPUs: Warp's kernels are built first, once; then each seed is this
    script run on its own with that seed; their results, faked here, become one summary with the
    IQM over seeds, each seed's log beside it."""
    started = []

    def run_each(commands, logs, parallel, cpu=False):
        started.append(parallel)
        for command, log in zip(commands, logs, strict=True):
            _fake_seed_run(command, log)
        return [0] * len(commands)

    monkeypatch.setattr(distributed, "run_independent", run_each)
    monkeypatch.setattr(ppo, "_gpus", lambda: ["0", "1"])
    monkeypatch.setattr(kernels, "start_build", lambda tasks: _Build(started, tasks))
    stem = tmp_path / "run"
    argv = ["train_mt_ppo.py", "--set", "reach-v3,push-v3", "--seeds", "0", "1", "--parallel", "2"]
    monkeypatch.setattr(sys, "argv", [*argv, "--out", str(stem)])
    with pytest.raises(SystemExit) as exit:
        ppo.main()
    assert exit.value.code == 0 and started == [("reach-v3", "push-v3"), "built", 2]
    summary = json.loads(Path(f"{stem}.json").read_text())
    assert [r["config"]["seed"] for r in summary["runs"]] == [0, 1]
    assert summary["device"] == "test device" and summary["eval_success"] == [0.375, 0.5]
    assert "iqm" in summary and len(summary["iqm_ci95"]) == 2
    assert Path(f"{stem}-seed1.log").read_text() == "seed 1 trained\n"


def _seed_file(tmp_path: Path, seed: int, commit: str = "abc1234", **config) -> Path:
    """A one-seed result as an earlier invocation (`--seeds k --out STEM`) writes it."""
    out = tmp_path / f"seed{seed}"
    _fake_seed_run(["--seeds", str(seed), "--out", str(out)], tmp_path / f"seed{seed}.log")
    data = json.loads(Path(f"{out}.json").read_text())
    data["runs"][0]["config"] |= {"learning_rate": 3e-4} | config
    data |= {"commit": commit, "command": f"python train_mt_ppo.py --seeds {seed}", "date": "2026-11-26"}
    Path(f"{out}.json").write_text(json.dumps(data))
    return Path(f"{out}.json")


def test_combine_makes_one_summary_of_seeds_run_separately(tmp_path, monkeypatch):
    """`--combine`: seeds trained by separate invocations (one per device call) become the same
    summary one invocation of them all writes, with their commit and commands, training nothing."""
    monkeypatch.setattr(kernels, "start_build", lambda tasks: pytest.fail("--combine builds nothing"))
    files = [_seed_file(tmp_path, seed) for seed in (0, 1, 2)]
    stem = tmp_path / "all"
    monkeypatch.setattr(sys, "argv", ["train_mt_ppo.py", "--combine", *map(str, files), "--out", str(stem)])
    ppo.main()
    summary = json.loads(Path(f"{stem}.json").read_text())
    assert [r["config"]["seed"] for r in summary["runs"]] == [0, 1, 2]
    assert summary["eval_success"] == [0.375, 0.5, 0.625] and summary["commit"] == "abc1234"
    assert summary["device"] == "test device"
    assert [s["command"] for s in summary["combined_from"]] == [
        f"python train_mt_ppo.py --seeds {k}" for k in range(3)
    ]
    scores = np.array([[0.5 + seed / 4, 0.25] for seed in range(3)])  # seeds x tasks
    assert summary["iqm"] == pytest.approx(iqm(scores))
    assert summary["iqm_ci95"][0] <= summary["iqm"] <= summary["iqm_ci95"][1]


@pytest.mark.parametrize(
    ("other", "message"),
    [
        ({"seed": 0, "learning_rate": 1e-3}, "differ in learning_rate"),
        ({"seed": 0}, "a seed appears twice"),
        ({"seed": 1, "commit": "def5678"}, "different commits"),
    ],
)
def test_combine_refuses_runs_of_different_recipes(tmp_path, monkeypatch, usage_error, other, message):
    for folder in ("a", "b"):
        (tmp_path / folder).mkdir()
    first = _seed_file(tmp_path / "a", 0)
    seed, commit = other.pop("seed"), other.pop("commit", "abc1234")
    second = _seed_file(tmp_path / "b", seed, commit, **other)
    monkeypatch.setattr(sys, "argv", ["train_mt_ppo.py", "--combine", str(first), str(second)])
    assert message in usage_error(ppo.main)


def test_combine_across_commits_records_every_commit(tmp_path, monkeypatch):
    """`--across-commits` combines seeds of two commits (of one recipe), and says so: the summary's
    commit names both and every source keeps its own; other differences are still refused."""
    for folder in ("a", "b", "c"):
        (tmp_path / folder).mkdir()
    first, second = _seed_file(tmp_path / "a", 0), _seed_file(tmp_path / "b", 1, "def5678")
    stem = tmp_path / "all"
    argv = ["train_mt_ppo.py", "--combine", str(first), str(second), "--across-commits", "--out", str(stem)]
    monkeypatch.setattr(sys, "argv", argv)
    ppo.main()
    summary = json.loads(Path(f"{stem}.json").read_text())
    assert summary["commit"] == "abc1234+def5678"
    assert [s["commit"] for s in summary["combined_from"]] == ["abc1234", "def5678"]
    other = _seed_file(tmp_path / "c", 2, "def5678", learning_rate=1e-3)
    with pytest.raises(ValueError, match="differ in learning_rate"):
        ppo.combine_runs([first, other], across_commits=True)


def test_seeds_stopped_by_a_time_limit_still_leave_the_finished_ones_summary(tmp_path, monkeypatch):
    """A SIGTERM stops `run_independent` with seed 0 done, seed 1 stopped mid-run and seed 2 never
    started: the summary holds seed 0, the logs that exist lie beside it, the exit code is 1."""

    def stopped(commands, logs, parallel, cpu=False):
        _fake_seed_run(commands[0], logs[0])
        logs[1].write_text("seed 1 training\n")
        return [0, -15, -15]

    monkeypatch.setattr(distributed, "run_independent", stopped)
    stem = tmp_path / "run"
    argv = ["train_mt_ppo.py", "--set", "reach-v3,push-v3", "--seeds", "0", "1", "2", "--parallel", "2"]
    monkeypatch.setattr(sys, "argv", [*argv, "--out", str(stem)])
    with pytest.raises(SystemExit) as exit:
        ppo.main()
    assert exit.value.code == 1
    summary = json.loads(Path(f"{stem}.json").read_text())
    assert [r["config"]["seed"] for r in summary["runs"]] == [0]
    assert Path(f"{stem}-seed1.log").read_text() == "seed 1 training\n"
    assert not Path(f"{stem}-seed2.log").exists()


def test_seeds_in_one_program_train_as_each_seed_alone(trainer):
    """`train_seeds` (`--vmap-seeds`): two seeds stacked and vmapped through one program end
    where each seed's own run on the same env ends, up to float rounding of batched matmuls,
    which Adam can turn into up to a step (lr 3e-4) per update for weights of near-zero gradient."""
    runs = ppo.train_seeds(CONFIG, [0, 3], minutes=60, log_every=2, max_updates=2, eval_episodes=1)
    assert [r["config"]["seed"] for r in runs] == [0, 3]
    assert all(r["one_program"] == {"seeds": [0, 3], "env_seed": CONFIG.seed} for r in runs)
    for run, seed in zip(runs, (0, 3), strict=True):
        alone, metrics = trainer.train_chunk(trainer.init(jax.random.key(seed)), 2)
        for ours, theirs in zip(jax.tree.leaves(run["params"]), jax.tree.leaves(alone.params), strict=True):
            np.testing.assert_allclose(ours, theirs, rtol=1e-3, atol=2 * 3e-4, err_msg=f"seed {seed}")
        assert [r["updates"] for r in run["curve"]] == [2]
        assert run["curve"][0]["loss"] == pytest.approx(float(metrics.loss), rel=1e-3, abs=1e-5)
        assert set(run["eval_success_per_task"]) == set(CONFIG.task_set)
    first, second = (jax.tree.leaves(r["params"]) for r in runs)
    assert any(not np.allclose(a, b) for a, b in zip(first, second, strict=True))  # two seeds, not one


def test_seeds_in_one_program_checkpoint_and_resume_together(trainer, tmp_path):
    stem = tmp_path / "seeds"
    carry, updates, curves = ppo.start_or_resume(trainer, [0, 3], stem)
    assert updates == 0 and curves == [[], []]
    assert all(x.shape[0] == 2 for x in jax.tree.leaves(ppo._learner(carry)))
    curves = [[{"updates": 2, "wall_s": 1.0}], [{"updates": 2, "wall_s": 1.0}]]
    ppo.save_checkpoint(stem, carry, 2, curves)
    restored, updates, restored_curves = ppo.start_or_resume(trainer, [0, 3], stem)
    assert updates == 2 and restored_curves == curves
    learner = [jax.tree.map(np.asarray, ppo._learner(c)) for c in (carry, restored)]
    for a, b in zip(*map(jax.tree.leaves, learner), strict=True):
        np.testing.assert_array_equal(a, b)
    with pytest.raises(ValueError, match="holds 2 seeds' runs, this run has 3"):
        ppo.start_or_resume(trainer, [0, 3, 4], stem)


@pytest.mark.slow
def test_seeds_in_one_program_resume_from_their_checkpoint(tmp_path):
    def run(updates):
        return ppo.train_seeds(
            CONFIG, [0, 3], 60.0, log_every=1, max_updates=updates, eval_episodes=1, checkpoint=tmp_path / "s"
        )

    first, second = run(1), run(2)
    for before, after in zip(first, second, strict=True):
        assert [r["updates"] for r in after["curve"]] == [1, 2] and after["curve"][0] == before["curve"][0]
        assert after["curve"][1]["wall_s"] > before["curve"][0]["wall_s"]


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["--set", "MT11"], "unknown benchmark 'MT11'"),
        (["--envs-per-task", "0"], "envs_per_task must be a positive int"),
        (["--reward-version", "v3"], "reward_version must be 'v1' or 'v2'"),
    ],
)
def test_bad_arguments_end_in_a_usage_error_before_any_work(monkeypatch, usage_error, argv, message):
    monkeypatch.setattr(sys, "argv", ["train_mt_ppo.py", *argv])
    monkeypatch.setattr(ppo, "train", lambda *args, **kwargs: pytest.fail("a refused run trains nothing"))
    assert message in usage_error(ppo.main)


def test_seeds_in_one_program_refuse_per_seed_options(monkeypatch, usage_error):
    argv = ["train_mt_ppo.py", "--seeds", "0", "1", "--vmap-seeds", "--video", "v", "--parallel", "2"]
    monkeypatch.setattr(sys, "argv", argv)
    monkeypatch.setattr(kernels, "start_build", lambda tasks: pytest.fail("a refused run builds nothing"))
    assert "drop --parallel, --video" in usage_error(ppo.main)


def test_task_curves_follow_each_task_of_each_seed():
    """The per-task PNG's series, from two committed MT10 runs: every task, a series per seed,
    over the curve points where every task had finished an episode."""
    results = Path(__file__).parents[1] / "benchmarks/results/train"
    files = sorted(results.glob("train-MT10-ppo-v2-9min-entropy-0.01-seed[01]-5870e15-*.json"))
    runs = [json.loads(path.read_text())["runs"][0] for path in files]
    curves = ppo.task_curves(runs)
    assert list(curves) == list(runs[0]["eval_success_per_task"]) and len(curves) == 10
    for index, run in enumerate(runs):
        points = [row for row in run["curve"] if row["train_success"] is not None]
        assert 0 < len(points) < len(run["curve"])  # the first chunks end before every task has
        for task, series in curves.items():
            seed, steps, success = series[index]
            assert seed == run["config"]["seed"] and len(steps) == len(success) == len(points)
            assert success == [row["train_success_per_task"][task] for row in points]
            assert steps == [row["env_steps"] / 1e6 for row in points]
