"""RL² on Meta-World's ML sets (ML10, ML45, ML1), entirely on device: trials, a GRU policy, PPO and
the meta-test in jitted loops.

    python examples/train_ml_rl2.py --set ML10      # the GPU run (docs/training.md: results so far)
    python examples/train_ml_rl2.py --set ML10 --seeds 0 1 2 3 --parallel 4  # four seeds, a GPU each
    python examples/train_ml_rl2.py --set ML1 --task reach-v3 --envs-per-task 2 --max-episode-steps 10 \
        --episodes-per-trial 2 --unroll 10 --minibatches 2 --updates 2 --eval-envs-per-task 2  # CPU smoke run

RL² (Duan et al. 2016) meta-learns with an ordinary RL algorithm on a recurrent policy: each env
keeps one goal for a *trial* of `--episodes-per-trial` episodes, and the policy's GRU state runs on
across the episodes of a trial (reset only at trial boundaries), seeing the observation, the
previous action, the previous reward and whether an episode just ended, so that what it learned
about the goal in one episode can pay off in the next. Goals stay fixed within a trial because ML
envs resample goals only on request (`goal_sampling="on_request"`): an episode's autoreset restarts
on the same goal, and at its trial's end an env moves on to the next goal of its own share of the
variants (`Env.restart` after advancing its goal cursor). Training episodes never end early; with
`--staggered-starts` (the default) each env starts at a random point of a trial, so that the envs'
trials and episodes are out of step (as in the PPO example).

PPO learns on whole trials: the discounting and GAE run across the episode boundaries within a
trial (only a trial's end is terminal), which is what rewards exploring in early episodes. Each
update rolls out `--unroll` steps of every env and trains on those sequences by truncated BPTT:
the loss re-runs the GRU over the chunk from the hidden state the rollout started it with (held
fixed), zeroing it where a trial began inside the chunk; minibatches are sets of whole env
sequences. The policy never sees a task id: inferring the task is the point.

The meta-test follows the paper's protocol (`mwjax.evaluation.metalearning_evaluation`) as one
jitted program (`Trainer.meta_tester`; the host loop would make ~65,000 device round trips): on
the test tasks, each env starts a trial on a fresh goal, adapts for `--adaptation-episodes` full
episodes acting stochastically, then runs `--evaluation-episodes` more on the same goal with its
hidden state carried on and the mean action, each ending at success; meta-test success is the
success rate of those evaluation episodes. `--eval-envs-per-task` envs per test task (each its own
goal) times `--eval-rounds` rounds are the goals per task (the paper: 10).
`--meta-test-train-tasks` also runs it on the train tasks (their training goals), a diagnostic.

Checkpoints (`--checkpoint STEM`) hold the learner (parameters, optimizer, normalizers, key) and
the curve; resuming starts fresh trials. Needs the `train` extra (optax); the PNG needs matplotlib.
"""

from __future__ import annotations

import argparse
import dataclasses
import functools
import math
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any, NamedTuple

import jax
import jax.numpy as jnp
import numpy as np
import optax

import mwjax
from mwjax import progress
from mwjax.benchmarks import Benchmark, benchmark
from mwjax.config import EnvConfig
from mwjax.observation import OBS_SIZE

try:  # imported as `examples.train_ml_rl2` (tests) or run as a script from examples/
    from examples import train_mt_ppo as ppo
except ModuleNotFoundError:
    import train_mt_ppo as ppo  # type: ignore[no-redef]

Array = jax.Array
# The policy's input: the observation, the previous action, reward and "an episode just ended".
INPUT_SIZE = OBS_SIZE + 4 + 1 + 1


@dataclasses.dataclass(frozen=True)
class Config:
    # "ML10", "ML45", "ML1" (with `task`), or a `Benchmark` (e.g. `mwjax.benchmarks.custom_ml`).
    task_set: str | Benchmark = "ML10"
    task: str | None = None
    envs_per_task: int = 1024
    # As long as the meta-test's trials (10 adaptation + 3 evaluation episodes), whose evaluated
    # episodes are a trial's 11th-13th: a policy trained on shorter trials never reached them.
    episodes_per_trial: int = 13
    max_episode_steps: int = 500
    # Steps per update, and the length of the truncated BPTT.
    unroll: int = 50
    # Of the envs: a minibatch is a set of whole `unroll`-step sequences.
    minibatches: int = 8
    epochs: int = 4
    learning_rate: float = 3e-4
    gamma: float = 0.99
    gae_lambda: float = 0.95
    clip: float = 0.2
    value_coef: float = 0.5
    entropy_coef: float = 1e-3
    max_grad_norm: float = 1.0
    embed: int = 256
    hidden: int = 256
    # Hidden layers of the policy and value heads after the GRU. Empty: each head is one linear
    # layer on the GRU state. Otherwise each is an MLP on the GRU state and the input embedding
    # side by side, so the current observation also reaches the action by a feed-forward path
    # (the PPO example's networks are 3 x 256 MLPs).
    head: tuple[int, ...] = ()
    init_log_std: float = -0.5
    # Start the envs at random points of their trials (`Trainer.stagger`); otherwise in lockstep.
    staggered_starts: bool = True
    # Normalize the advantages per train task (as the PPO example does) instead of over all envs,
    # so that no task's gradient drowns out another's. The learner knows each env's task; the
    # policy still does not (its inputs are the same either way).
    per_task_advantages: bool = True
    # Scale the learning signal (value targets, advantages) by each train task's running return
    # std instead of one for all, as the PPO example does. The reward the policy sees keeps the
    # one scale (a per-task scale would give the task away).
    per_task_returns: bool = True
    reward_version: str = "v2"
    seed: int = 0
    # The meta-test (the paper: 10 goals per test task, 10 adaptation and 3 evaluation episodes).
    adaptation_episodes: int = 10
    evaluation_episodes: int = 3
    eval_envs_per_task: int = 10
    eval_rounds: int = 1
    # Also meta-test on the train tasks (their training goals): a diagnostic the paper does not
    # report, telling a policy that adapts but does not generalize from one that does not adapt.
    meta_test_train_tasks: bool = False


class Params(NamedTuple):
    embed: tuple[Array, Array]
    # A GRU cell (PyTorch's gate layout: reset, update, candidate): input and hidden weights, biases.
    gru_x: tuple[Array, Array]
    gru_h: tuple[Array, Array]
    # Layers `(w, b)`: one on the GRU state, or with `Config.head` an MLP on `[state, embedding]`.
    policy: list[tuple[Array, Array]]
    value: list[tuple[Array, Array]]
    log_std: Array  # (4,)


class Transition(NamedTuple):
    obs: Array  # raw, for the observation statistics
    inputs: Array  # the policy's input as the rollout saw it (normalized)
    reset: Array  # a trial began at this step, so the hidden state started at zero
    action: Array  # unclipped Gaussian sample
    log_prob: Array
    value: Array
    reward: Array  # raw
    trial_end: Array  # the env's trial ended at this step (terminal)


class Normalizers(NamedTuple):
    obs: ppo.RunningStats
    returns: ppo.RunningStats  # one scale for all tasks: the reward in the policy's input
    task_returns: ppo.RunningStats  # per train task: the learning signal with `per_task_returns`


class Carry(NamedTuple):
    params: Params
    opt_state: Any
    norm: Normalizers
    env_state: mwjax.State
    hidden: Array  # (num_envs, hidden)
    prev_action: Array
    prev_reward: Array
    first: Array  # per env: the observation starts an episode
    trial_step: Array  # per env: steps into its current trial
    first_cut: Array  # per env: the step at which its first episode is cut short, or -1
    running_return: Array  # per env, for the reward scale
    episode_success: Array
    key: Array


# The PPO example's, its counts per train task: the curve rows (`ppo._row`) read them alike.
Metrics = ppo.Metrics


class MetaTestResult(NamedTuple):
    success_rate: Array  # (test tasks,)
    success: Array  # (test tasks, envs * rounds): each goal's evaluation success rate


def _dense_init(key: Array, fan_in: int, fan_out: int, scale: float) -> tuple[Array, Array]:
    return ppo._orthogonal(key, (fan_in, fan_out), scale), jnp.zeros(fan_out)


def _per_task(x: Array, tasks: int) -> Array:
    """`(unroll, num_envs)` as `(unroll, tasks, envs per task)`: the envs lie task by task."""
    return x.reshape(x.shape[0], tasks, -1)


def _log_prob(mean: Array, log_std: Array, action: Array) -> Array:
    """`ppo._log_prob` (which takes per-task batches) for one shared `log_std`."""
    flat = ppo._log_prob(mean.reshape(1, -1, 4), log_std[None], action.reshape(1, -1, 4))
    return flat.reshape(mean.shape[:-1])


class Trainer:
    """The jitted pieces of a run: `init(key)`, `train_chunk(carry, n)` and `meta_tester()`."""

    def __init__(self, config: Config) -> None:
        self.config = config
        self.env = self._make_env(config.envs_per_task, "train")
        self.n_tasks = len(self.env.task_list)
        self.trial_length = config.episodes_per_trial * config.max_episode_steps
        if self.env.num_envs % config.minibatches:
            raise ValueError(f"{self.env.num_envs} envs do not split into {config.minibatches} minibatches")
        self.optimizer = optax.chain(
            optax.clip_by_global_norm(config.max_grad_norm), optax.adam(config.learning_rate)
        )
        self._init_rest = jax.jit(self._init_rest_of_carry)
        self.train_chunk = jax.jit(self._train_chunk, static_argnums=1, donate_argnums=0)

    def _make_env(self, envs_per_task: int, split: str) -> Any:
        cfg = self.config
        return mwjax.make(
            cfg.task_set,
            task=cfg.task,
            split=split,
            envs_per_task=envs_per_task,
            seed=cfg.seed,
            reward_version=cfg.reward_version,
            max_episode_steps=cfg.max_episode_steps,
            goal_sampling="on_request",
        )

    # -- the policy ---------------------------------------------------------------------------

    def init_params(self, key: Array) -> Params:
        """Host-side, like the PPO example's (`ppo._orthogonal`)."""
        cfg = self.config
        keys = jax.random.split(key, 5)
        h = cfg.hidden
        sizes = (h + cfg.embed, *cfg.head) if cfg.head else (h,)

        def mlp(key: Array, out: int, out_scale: float) -> list[tuple[Array, Array]]:
            keys = jax.random.split(key, len(sizes))
            scales = [math.sqrt(2.0)] * (len(sizes) - 1) + [out_scale]
            return [
                _dense_init(k, n_in, n_out, scale)
                for k, n_in, n_out, scale in zip(keys, sizes, (*sizes[1:], out), scales, strict=True)
            ]

        return Params(
            embed=_dense_init(keys[0], INPUT_SIZE, cfg.embed, math.sqrt(2.0)),
            gru_x=_dense_init(keys[1], cfg.embed, 3 * h, 1.0),
            gru_h=_dense_init(keys[2], h, 3 * h, 1.0),
            policy=mlp(keys[3], 4, 0.01),
            value=mlp(keys[4], 1, 1.0),
            log_std=jnp.full(4, cfg.init_log_std, jnp.float32),  # not weak: one compile
        )

    @staticmethod
    def core(params: Params, hidden: Array, inputs: Array) -> tuple[Array, Array, Array]:
        """One step of the recurrent policy: `(hidden', action mean, value)`."""
        x = jax.nn.swish(inputs @ params.embed[0] + params.embed[1])
        gx = x @ params.gru_x[0] + params.gru_x[1]
        gh = hidden @ params.gru_h[0] + params.gru_h[1]
        (rx, zx, nx), (rh, zh, nh) = jnp.split(gx, 3, axis=-1), jnp.split(gh, 3, axis=-1)
        r, z = jax.nn.sigmoid(rx + rh), jax.nn.sigmoid(zx + zh)
        hidden = (1 - z) * jnp.tanh(nx + r * nh) + z * hidden
        features = jnp.concatenate([hidden, x], axis=-1) if len(params.policy) > 1 else hidden

        def mlp(layers: list[tuple[Array, Array]]) -> Array:
            y = features
            for w, b in layers[:-1]:
                y = jax.nn.swish(y @ w + b)
            return y @ layers[-1][0] + layers[-1][1]

        return hidden, mlp(params.policy), mlp(params.value)[..., 0]

    def sequence(self, params: Params, hidden: Array, inputs: Array, reset: Array) -> tuple[Array, Array]:
        """The policy over `(steps, envs, ...)` inputs from `hidden`, zeroed where `reset`:
        action means and values, as the rollout computed them step by step."""

        def step(h: Array, xs: tuple[Array, Array]) -> tuple[Array, tuple[Array, Array]]:
            x, r = xs
            h, mean, value = self.core(params, jnp.where(r[:, None], 0.0, h), x)
            return h, (mean, value)

        _, (mean, value) = jax.lax.scan(step, hidden, (inputs, reset))
        return mean, value

    @staticmethod
    def inputs(norm: Normalizers, obs: Array, prev_action: Array, prev_reward: Array, first: Array) -> Array:
        reward = prev_reward / jnp.sqrt(norm.returns.var + 1e-8)
        return jnp.concatenate(
            [
                ppo.Trainer._normalize(norm, obs),
                prev_action,
                reward[:, None],
                first[:, None].astype(jnp.float32),
            ],
            axis=-1,
        )

    # -- state ----------------------------------------------------------------------------------

    def init(self, key: Array) -> Carry:
        params_key, env_key, stagger_key, key = jax.random.split(key, 4)
        carry = self._init_rest(self.init_params(params_key), env_key, key)
        return self.stagger(carry, stagger_key) if self.config.staggered_starts else carry

    def stagger(self, carry: Carry, key: Array) -> Carry:
        """Every env starts at a random multiple of `unroll` steps into a trial, its first episode
        cut short to end where that trial's episodes end (the PPO example's staggered starts, for
        the same reason: in lockstep every update would learn from one slice of every trial)."""
        cfg = self.config
        slots = max(self.trial_length // cfg.unroll, 1)
        trial_step = jax.random.randint(key, (self.env.num_envs,), 0, slots) * cfg.unroll
        into_episode = trial_step % cfg.max_episode_steps
        first_cut = jnp.where(into_episode > 0, cfg.max_episode_steps - into_episode, -1)
        return carry._replace(trial_step=trial_step.astype(jnp.int32), first_cut=first_cut.astype(jnp.int32))

    def _init_rest_of_carry(self, params: Params, env_key: Array, key: Array) -> Carry:
        n = self.env.num_envs
        norm = Normalizers(
            ppo.RunningStats.zeros((OBS_SIZE,)),
            ppo.RunningStats.zeros((1,)),
            ppo.RunningStats.zeros((self.n_tasks,)),
        )
        zeros = jnp.zeros(n)
        return Carry(
            params=params,
            opt_state=self.optimizer.init(params),
            norm=norm,
            env_state=self.env.reset(env_key),
            hidden=jnp.zeros((n, self.config.hidden)),
            prev_action=jnp.zeros((n, 4)),
            prev_reward=zeros,
            first=jnp.ones(n, bool),
            trial_step=jnp.zeros(n, jnp.int32),
            first_cut=jnp.full(n, -1, jnp.int32),
            running_return=zeros,
            episode_success=zeros.astype(bool),
            key=key,
        )

    # -- one PPO update -------------------------------------------------------------------------

    def rollout(self, carry: Carry) -> tuple[Carry, Transition, Array, tuple[Array, Array, Array]]:
        """`unroll` steps of every env: the carry after them, the transitions, the hidden state
        the chunk started from, and per-step `(unroll, envs)` full-length episodes ended, those
        of them that succeeded (at any step), and physics resets (`info["physics_reset"]`)."""
        params, env = carry.params, self.env

        def step(c: Carry, key: Array) -> tuple[Carry, tuple[Transition, Array, Array]]:
            x = self.inputs(c.norm, c.env_state.obs, c.prev_action, c.prev_reward, c.first)
            hidden, mean, value = self.core(params, c.hidden, x)
            action = mean + jnp.exp(params.log_std) * jax.random.normal(key, mean.shape)
            clipped = jnp.clip(action, -1.0, 1.0)
            stepped = env.step(c.env_state, clipped)
            success = c.episode_success | stepped.info["success"]
            full_length = stepped.truncated  # same-step autoreset: obs is the next episode's start
            cut = stepped.steps == c.first_cut
            trial_step = c.trial_step + 1
            trial_end = trial_step == self.trial_length
            restart = cut | trial_end
            next_state = jax.lax.cond(
                jnp.any(restart), lambda s: self._next_episode(s, restart, trial_end), lambda s: s, stepped
            )
            transition = Transition(
                c.env_state.obs, x, c.trial_step == 0, action, _log_prob(mean, params.log_std, action), value,
                stepped.reward, trial_end,
            )  # fmt: skip
            # A new trial forgets the last one: the hidden state starts at zero, as at `init`.
            keep = ~trial_end
            episode_end = full_length | cut
            c = c._replace(
                env_state=next_state,
                hidden=hidden * keep[:, None],
                prev_action=clipped * keep[:, None],
                prev_reward=stepped.reward * keep,
                first=episode_end,
                trial_step=jnp.where(trial_end, 0, trial_step),
                first_cut=jnp.where(cut, -1, c.first_cut),
                episode_success=success & ~episode_end,
            )
            # Training success counts full-length episodes only; cut ones had less time.
            return c, (transition, (full_length, full_length & success, stepped.info["physics_reset"]))

        key, rollout_key = jax.random.split(carry.key)
        keys = jax.random.split(rollout_key, self.config.unroll)
        end, (batch, counts) = jax.lax.scan(step, carry, keys)
        return end._replace(key=key), batch, carry.hidden, counts

    def _next_episode(self, state: mwjax.State, restart: Array, trial_end: Array) -> mwjax.State:
        """Fresh episodes in the `restart` rows, on each env's next goal where its trial ended
        (it cycles through its share of the goal variants) and on the same goal elsewhere."""
        cursor = state.goal_cursor
        following = jnp.where(cursor + 1 >= self.env.goals.pool_sizes, 0, cursor + 1)
        state = dataclasses.replace(state, goal_cursor=jnp.where(trial_end, following, cursor))
        return self.env.restart(state, restart)

    def _advantages(self, carry: Carry, batch: Transition, rewards: Array) -> tuple[Array, Array]:
        """GAE over the trial: only a trial's end is terminal; episode ends inside it are not."""
        cfg = self.config
        x = self.inputs(carry.norm, carry.env_state.obs, carry.prev_action, carry.prev_reward, carry.first)
        last_value = self.core(carry.params, carry.hidden, x)[2]
        next_values = jnp.concatenate([batch.value[1:], last_value[None]])
        next_values = next_values * ~batch.trial_end
        deltas = rewards + cfg.gamma * next_values - batch.value

        def backward(advantage: Array, xs: tuple[Array, Array]) -> tuple[Array, Array]:
            delta, end = xs
            advantage = delta + cfg.gamma * cfg.gae_lambda * jnp.where(end, 0.0, advantage)
            return advantage, advantage

        _, advantages = jax.lax.scan(
            backward, jnp.zeros_like(last_value), (deltas, batch.trial_end), reverse=True
        )
        return advantages, advantages + batch.value

    def reward_scale(self, norm: Normalizers) -> Array:
        """What the learner divides rewards by: the running std of the discounted return, one for
        all tasks, or per env its train task's with `per_task_returns` (envs lie task by task)."""
        if self.config.per_task_returns:
            return jnp.repeat(jnp.sqrt(norm.task_returns.var + 1e-8), self.config.envs_per_task)
        return jnp.sqrt(norm.returns.var + 1e-8)

    def _normalized(self, advantages: Array) -> Array:
        """`(unroll, envs)` advantages to mean 0 and std 1, per train task (envs lie task by
        task) with `per_task_advantages`, else over all."""
        axes = (0, 2) if self.config.per_task_advantages else (0, 1, 2)
        a = _per_task(advantages, self.n_tasks)
        a = (a - a.mean(axis=axes, keepdims=True)) / (a.std(axis=axes, keepdims=True) + 1e-8)
        return a.reshape(advantages.shape)

    def _loss(
        self, params: Params, h0: Array, mb: Transition, advantages: Array, targets: Array
    ) -> tuple[Array, tuple[Array, Array, Array]]:
        """The PPO loss of a minibatch of trials; also the approximate KL, the policy loss and
        the value loss."""
        cfg = self.config
        mean, value = self.sequence(params, h0, mb.inputs, mb.reset)
        log_prob = _log_prob(mean, params.log_std, mb.action)
        ratio = jnp.exp(log_prob - mb.log_prob)
        policy_loss = -jnp.minimum(
            ratio * advantages, jnp.clip(ratio, 1 - cfg.clip, 1 + cfg.clip) * advantages
        ).mean()
        value_loss = 0.5 * ((value - targets) ** 2).mean()
        entropy = jnp.sum(params.log_std + 0.5 * math.log(2 * math.pi * math.e))
        loss = policy_loss + cfg.value_coef * value_loss - cfg.entropy_coef * entropy
        return loss, ((mb.log_prob - log_prob).mean(), policy_loss, value_loss)

    def _update(self, carry: Carry, _: None) -> tuple[Carry, Metrics]:
        cfg = self.config
        carry, batch, h0, counts = self.rollout(carry)

        # Rewards divided by the running std of the discounted return within a trial.
        def accumulate(running: Array, xs: tuple[Array, Array]) -> tuple[Array, Array]:
            reward, end = xs
            running = running * cfg.gamma + reward
            return jnp.where(end, 0.0, running), running

        running, returns = jax.lax.scan(accumulate, carry.running_return, (batch.reward, batch.trial_end))
        by_task = _per_task(returns, self.n_tasks).transpose(0, 2, 1)  # (unroll, E, tasks)
        norm = carry.norm._replace(
            returns=carry.norm.returns.merge(returns[..., None], (0, 1)),
            task_returns=carry.norm.task_returns.merge(by_task, (0, 1)),
        )
        advantages, targets = self._advantages(carry, batch, batch.reward / self.reward_scale(norm))
        advantages = self._normalized(advantages)
        norm = norm._replace(obs=norm.obs.merge(batch.obs, (0, 1)))

        def epoch(c: tuple, key: Array) -> tuple[tuple, tuple[Array, ...]]:
            order = jax.random.permutation(key, self.env.num_envs).reshape(cfg.minibatches, -1)

            def minibatch(c: tuple, idx: Array) -> tuple[tuple, tuple[Array, ...]]:
                params, opt_state = c
                mb = jax.tree.map(lambda x: x[:, idx], batch)
                grad_fn = jax.value_and_grad(self._loss, has_aux=True)
                (loss, aux), grads = grad_fn(params, h0[idx], mb, advantages[:, idx], targets[:, idx])
                updates, opt_state = self.optimizer.update(grads, opt_state, params)
                return (optax.apply_updates(params, updates), opt_state), (loss, *aux)

            return jax.lax.scan(minibatch, c, order)

        key, epoch_key = jax.random.split(carry.key)
        (params, opt_state), losses = jax.lax.scan(
            epoch, (carry.params, carry.opt_state), jax.random.split(epoch_key, cfg.epochs)
        )
        carry = carry._replace(params=params, opt_state=opt_state, norm=norm, running_return=running, key=key)
        per_task = (_per_task(x, self.n_tasks).sum(axis=(0, 2)) for x in counts)
        return carry, Metrics(*per_task, *(x.mean() for x in losses))

    def _train_chunk(self, carry: Carry, updates: int) -> tuple[Carry, Metrics]:
        carry, metrics = jax.lax.scan(self._update, carry, None, length=updates)
        return carry, ppo.chunk_metrics(metrics)

    @property
    def steps_per_update(self) -> int:
        return self.env.num_envs * self.config.unroll

    # -- the meta-test --------------------------------------------------------------------------

    @functools.cached_property
    def test_env(self) -> Any:
        """The test tasks, `eval_envs_per_task` envs each (built on first use: tests of training
        alone skip building and compiling it)."""
        return self._make_env(self.config.eval_envs_per_task, "test")

    @functools.cached_property
    def train_tasks_eval_env(self) -> Any:
        """The train tasks on their training goals, `eval_envs_per_task` envs each (built on first use)."""
        return self._make_env(self.config.eval_envs_per_task, "train")

    def meta_test_env(self, split: str = "test") -> Any:
        """The env the meta-test runs on: `test_env`, or with `split="train"` `train_tasks_eval_env`."""
        if split not in ("test", "train"):
            raise ValueError(f"split must be 'test' or 'train', got {split!r}")
        return self.test_env if split == "test" else self.train_tasks_eval_env

    def meta_tester(self, split: str = "test") -> Callable[[Params, Normalizers, Array], MetaTestResult]:
        """A jitted `(params, norm, key) -> MetaTestResult` on the test tasks (module docstring),
        or with `split="train"` the same protocol on the train tasks."""
        cfg = self.config
        env = self.meta_test_env(split)
        n = env.num_envs
        horizon = cfg.max_episode_steps

        def run(params: Params, norm: Normalizers, key: Array) -> MetaTestResult:
            reset_key, key = jax.random.split(key)

            def one_round(state: mwjax.State, xs: tuple[Array, Array]) -> tuple[mwjax.State, Array]:
                index, key = xs
                state = jax.lax.cond(index > 0, env.sample_goals, lambda s: s, state)

                def adapt(c: tuple, key: Array) -> tuple[tuple, None]:
                    state, h, prev_action, prev_reward, first = c
                    h, mean, _ = self.core(
                        params, h, self.inputs(norm, state.obs, prev_action, prev_reward, first)
                    )
                    action = jnp.clip(
                        mean + jnp.exp(params.log_std) * jax.random.normal(key, mean.shape), -1, 1
                    )
                    state = env.step(state, action)
                    return (state, h, action, state.reward, state.truncated), None

                zeros = jnp.zeros(n)
                c = (state, jnp.zeros((n, cfg.hidden)), jnp.zeros((n, 4)), zeros, jnp.ones(n, bool))
                steps = cfg.adaptation_episodes * horizon
                (state, h, prev_action, prev_reward, first), _ = jax.lax.scan(
                    adapt, c, jax.random.split(key, steps)
                )

                # The last adaptation step truncated every episode: `state` starts a fresh one.
                def evaluate(c: tuple, _: None) -> tuple[tuple, None]:
                    state, h, prev_action, prev_reward, first, episodes, successes = c
                    h, mean, _ = self.core(
                        params, h, self.inputs(norm, state.obs, prev_action, prev_reward, first)
                    )
                    action = jnp.clip(mean, -1.0, 1.0)
                    state = env.step(state, action)
                    solved = state.info["success"]
                    ended = solved | state.truncated
                    successes = successes + (solved & (episodes < cfg.evaluation_episodes))
                    # An episode ends at success (the reference's evaluation env terminates on it).
                    restart = solved & ~state.truncated
                    reward = state.reward
                    state = jax.lax.cond(
                        jnp.any(restart), lambda s: env.restart(s, restart), lambda s: s, state
                    )
                    return (state, h, action, reward, ended, episodes + ended, successes), None

                count = jnp.zeros(n, jnp.int32)
                (state, *_, successes), _ = jax.lax.scan(
                    evaluate,
                    (state, h, prev_action, prev_reward, first, count, count),
                    None,
                    length=cfg.evaluation_episodes * horizon,
                )
                return state, successes / cfg.evaluation_episodes

            keys = jax.random.split(key, cfg.eval_rounds)
            _, rates = jax.lax.scan(one_round, env.reset(reset_key), (jnp.arange(cfg.eval_rounds), keys))
            # (rounds, envs) -> (tasks, envs * rounds), the envs laid out task by task.
            per_goal = rates.reshape(cfg.eval_rounds, -1, cfg.eval_envs_per_task).transpose(1, 2, 0)
            per_goal = per_goal.reshape(per_goal.shape[0], -1)
            return MetaTestResult(per_goal.mean(axis=1), per_goal)

        return jax.jit(run)


# -- the run --------------------------------------------------------------------------------------


def train(
    config: Config,
    minutes: float = 8.0,
    log_every: int = 10,
    max_updates: int | None = None,
    checkpoint: str | Path | None = None,
    kernels: Any = None,
) -> dict:
    """Train until `minutes` of wall clock (compile included) or `max_updates` in all (counting a
    resumed checkpoint's), saving `checkpoint` after every chunk if given; then meta-test.
    `kernels`: a Warp kernel build under way (`ppo.start_kernels`), which the first chunk's
    compile overlaps."""
    start = time.perf_counter()
    trainer = Trainer(config)
    carry, updates, curve = ppo.start_or_resume(trainer, config.seed, checkpoint)
    # The curve's wall clock runs on across resumed runs.
    start -= curve[-1]["wall_s"] if curve else 0.0
    budget = minutes * 60 + (curve[-1]["wall_s"] if curve else 0.0)
    print(
        f"{trainer.env.benchmark.name}: {trainer.env.num_envs} envs, {trainer.steps_per_update:,} env steps "
        f"per update, trials of {trainer.trial_length} steps",
        flush=True,
    )
    loop = ppo._Loop(carry, updates)
    for metrics in ppo._chunks(trainer.train_chunk, loop, start, budget, log_every, max_updates, kernels):
        row = ppo._row(metrics, loop.updates, trainer, time.perf_counter() - start)
        curve.append(row)
        ppo._progress(row, budget, metrics.episodes)
        if checkpoint is not None:
            ppo.save_checkpoint(checkpoint, loop.carry, loop.updates, curve)
    carry = loop.carry
    train_s = time.perf_counter() - start
    t0 = time.perf_counter()
    run = {"config": dataclasses.asdict(config), "curve": curve, "train_s": train_s}
    key = jax.random.key(config.seed + 1000)
    for split in ("test", "train") if config.meta_test_train_tasks else ("test",):
        with progress.phase(f"meta-test on the {split} tasks"):
            result = trainer.meta_tester(split)(carry.params, carry.norm, key)
            success = np.asarray(result.success_rate)
        env = trainer.meta_test_env(split)
        name = "meta_test_success" if split == "test" else "meta_test_success_train_tasks"
        run[f"{name}_per_task"] = dict(zip(env.task_list, success.tolist(), strict=True))
        run[name] = float(success.mean())
        # Printed as each one ends: a run stopped in the next still shows this one.
        print(
            f"meta-test on the {split} tasks: success {run[name]:.3f} {run[f'{name}_per_task']}", flush=True
        )
    return run | {"eval_s": time.perf_counter() - t0, "params": carry.params}


def _plot(runs: list[dict], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6, 4))
    for run in runs:
        points = [r for r in run["curve"] if r["train_success"] is not None]
        label = f"seed {run['config']['seed']} (meta-test {run['meta_test_success']:.2f})"
        ax.plot([r["env_steps"] / 1e6 for r in points], [r["train_success"] for r in points], label=label)
    ax.set_xlabel("env steps (millions)")
    ax.set_ylabel("mean success, training episodes")
    ax.set_ylim(0, 1)
    ax.grid(alpha=0.3)
    ax.legend()
    ax.set_title(f"{runs[0]['name']} RL² ({runs[0]['config']['reward_version']} rewards)")
    fig.tight_layout()
    fig.savefig(path, dpi=120)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    d = Config()
    parser.add_argument("--set", default=d.task_set, help="ML10, ML45, ML1 (with --task)")
    parser.add_argument("--task", default=None, help="the task of ML1")
    parser.add_argument("--envs-per-task", type=int, default=d.envs_per_task)
    parser.add_argument("--episodes-per-trial", type=int, default=d.episodes_per_trial)
    parser.add_argument("--max-episode-steps", type=int, default=d.max_episode_steps)
    parser.add_argument("--unroll", type=int, default=d.unroll, help="steps per update (the BPTT length)")
    parser.add_argument("--minibatches", type=int, default=d.minibatches)
    parser.add_argument("--epochs", type=int, default=d.epochs)
    parser.add_argument("--lr", type=float, default=d.learning_rate)
    parser.add_argument("--gamma", type=float, default=d.gamma)
    parser.add_argument("--entropy-coef", type=float, default=d.entropy_coef)
    parser.add_argument("--hidden", type=int, default=d.hidden, help="GRU size")
    parser.add_argument(
        "--head",
        type=int,
        nargs="*",
        default=list(d.head),
        help="hidden layers of the policy and value heads, on the GRU state and the input embedding "
        "(none: one linear layer on the GRU state)",
    )
    parser.add_argument("--reward-version", default=d.reward_version)
    parser.add_argument("--adaptation-episodes", type=int, default=d.adaptation_episodes)
    parser.add_argument("--evaluation-episodes", type=int, default=d.evaluation_episodes)
    parser.add_argument("--eval-envs-per-task", type=int, default=d.eval_envs_per_task)
    parser.add_argument("--eval-rounds", type=int, default=d.eval_rounds)
    parser.add_argument(
        "--meta-test-train-tasks",
        action="store_true",
        help="also meta-test on the train tasks (their training goals): does the policy adapt at all?",
    )
    parser.add_argument(
        "--staggered-starts",
        action=argparse.BooleanOptionalAction,
        default=d.staggered_starts,
        help="start each env at a random point of its first trial",
    )
    parser.add_argument(
        "--per-task-advantages",
        action=argparse.BooleanOptionalAction,
        default=d.per_task_advantages,
        help="normalize advantages per train task (the learner's knowledge; the policy sees no task)",
    )
    parser.add_argument(
        "--per-task-returns",
        action=argparse.BooleanOptionalAction,
        default=d.per_task_returns,
        help="scale the learning signal by each train task's return std (the input reward keeps one scale)",
    )
    ppo.add_run_arguments(parser, 8.0, "wall clock per seed, compile included")
    parser.add_argument(
        "--checkpoint", default=None, help="stem to save to after every chunk and resume from"
    )
    ppo.add_combine_argument(parser)
    args = parser.parse_args()
    if ppo.combined(parser, args, lambda runs, device, origin: write_results(runs, args, device, origin)):
        return
    try:
        bench = benchmark(args.set, task=args.task)
        if not bench.meta_learning:
            raise ValueError(f"RL² trains on a meta-learning set (ML10, ML25, ML45, ML1), not {args.set}")
        # The env's arguments first: on the CPU nothing else reads them before the first seed.
        EnvConfig(
            bench,
            envs_per_task=args.envs_per_task,
            reward_version=args.reward_version,
            max_episode_steps=args.max_episode_steps,
        )
        kernels = ppo.start_kernels(bench)
    except ValueError as error:
        parser.error(str(error))
    if args.parallel > 1 and len(args.seeds) > 1:
        if kernels is not None:
            kernels.wait()  # before the seeds' processes, which find the modules in Warp's cache
        try:
            code = ppo.seeds_in_parallel(
                args,
                __file__,
                lambda runs, device: write_results(runs, args, device),
                lambda run: f"meta-test success {run['meta_test_success']:.3f}",
            )
        except ValueError as error:
            parser.error(str(error))
        sys.exit(code)

    runs = []
    for seed in args.seeds:
        config = Config(
            task_set=args.set,
            task=args.task,
            envs_per_task=args.envs_per_task,
            episodes_per_trial=args.episodes_per_trial,
            max_episode_steps=args.max_episode_steps,
            unroll=args.unroll,
            minibatches=args.minibatches,
            epochs=args.epochs,
            learning_rate=args.lr,
            gamma=args.gamma,
            entropy_coef=args.entropy_coef,
            hidden=args.hidden,
            head=tuple(args.head),
            staggered_starts=args.staggered_starts,
            per_task_advantages=args.per_task_advantages,
            per_task_returns=args.per_task_returns,
            reward_version=args.reward_version,
            seed=seed,
            adaptation_episodes=args.adaptation_episodes,
            evaluation_episodes=args.evaluation_episodes,
            eval_envs_per_task=args.eval_envs_per_task,
            eval_rounds=args.eval_rounds,
            meta_test_train_tasks=args.meta_test_train_tasks,
        )
        checkpoint = None if args.checkpoint is None else f"{args.checkpoint}-seed{seed}"
        run = train(config, args.minutes, args.log_every, args.updates, checkpoint, kernels)
        run.pop("params")
        run["name"] = args.set if args.task is None else f"{args.set}:{args.task}"
        print(
            f"seed {seed}: meta-test success {run['meta_test_success']:.3f} ({run['eval_s']:.0f}s)",
            flush=True,
        )
        runs.append(run)
    device = jax.devices()[0]
    write_results(runs, args, getattr(device, "device_kind", str(device)))


def write_results(runs: list[dict], args: argparse.Namespace, device: str, origin: dict | None = None) -> str:
    """The runs' JSON (with the IQM of the per-test-task meta-test success and its CI over
    seeds) and learning-curve PNG; returns their path without the suffix."""
    default = f"train-{runs[0]['name']}-rl2-{device}-{ppo._today()}".replace(" ", "_")
    return ppo.write_summary(
        runs, device, args.out or str(ppo.RESULTS / default), _plot, "meta_test_success", origin
    )


if __name__ == "__main__":
    main()
