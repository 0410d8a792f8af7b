"""Multi-task PPO on MT10, entirely on device: env steps, policy, GAE and updates in one jitted loop.

    python examples/train_mt_ppo.py                 # the documented run (GPU, one 10-minute call)
    python examples/train_mt_ppo.py --set reach-v3,push-v3 --envs-per-task 2 --unroll 4 \
        --minibatches 2 --updates 2 --eval-episodes 1  # a CPU smoke run
    python examples/train_mt_ppo.py --devices all    # data parallel over every local GPU
    python examples/train_mt_ppo.py --seeds 0 1 2 3 --parallel 4  # four seeds, one GPU each
    python examples/train_mt_ppo.py --video videos/  # and a video of the trained policy per task

One `lax.scan` runs `--log-every` PPO updates (each: `--unroll` steps of every env, GAE, several
epochs of minibatch updates) without leaving the device; the host only prints progress between
those chunks. The policy sees the 39-d observation plus a one-hot task id; observations are
normalized with running statistics and rewards with a running scale per task (the ten tasks' V2
rewards differ in scale), and advantages are normalized per task, so that no task's gradient
drowns out another's (`--normalization shared` normalizes both over all tasks together, keeping
their relative reward scales). At the end the policy's mean action is evaluated with
`mwjax.evaluation.evaluator` (50 episodes per task, one per goal variant, success at any step),
and the learning curve is saved as JSON and PNG in `benchmarks/results/train/`.

`--devices N` (or `all`) splits the envs over N local devices (`mwjax.make(..., devices=)`, an
equal share of every task on each) and runs each update data parallel under `jax.shard_map`:
every device rolls out and learns on its own envs, with the gradients, the normalizers' and the
advantages' statistics and the metrics averaged or summed over the devices (`pmean`/`psum`).
`--envs-per-task` is the total over the devices. On GPUs the script reruns itself as one process
per GPU (`python -m mwjax.distributed`; in one process the update hangs on 4 GPUs).

`--video DIR` then writes one episode of the trained policy's mean action on each task,
`DIR/<task>.mp4` from the reference's `corner` camera (rendered by `mwjax.rendering`).

Needs the `train` extra (optax); the PNG needs matplotlib, the videos the `video` extra.
"""

from __future__ import annotations

import argparse
import contextlib
import dataclasses
import datetime
import json
import math
import os
import shlex
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable, Iterator, Sequence
from pathlib import Path
from typing import Any, Literal, NamedTuple

import jax
import jax.numpy as jnp
import numpy as np
import optax
from jax.sharding import PartitionSpec as P

import mwjax
from mwjax import distributed, progress, rendering
from mwjax.batching import cond_any
from mwjax.benchmarks import benchmark, parse_tasks
from mwjax.config import EnvConfig
from mwjax.evaluation import evaluator
from mwjax.observation import OBS_SIZE
from mwjax.sharding import AXIS
from mwjax.stored_results import write_atomically

RESULTS = Path(__file__).parents[1] / "benchmarks" / "results" / "train"
Array = jax.Array


@dataclasses.dataclass(frozen=True)
class Config:
    task_set: str | tuple[str, ...] = "MT10"
    envs_per_task: int = 3276
    unroll: int = 16
    minibatches: int = 32
    epochs: int = 4
    learning_rate: float = 3e-4
    gamma: float = 0.99
    gae_lambda: float = 0.95
    clip: float = 0.2
    value_coef: float = 0.5
    # A bonus large enough to keep the policy exploring until it finds door-open, which 1e-3
    # rarely did in the same budget (docs/training.md).
    entropy_coef: float = 0.01
    max_grad_norm: float = 1.0
    hidden: tuple[int, ...] = (256, 256, 256)
    init_log_std: float = -0.5
    # Which layers of the policy and value networks each task has to itself (the rest are shared,
    # and see the one-hot task id): "shared" none, "multi-head" the output layer, as in the
    # multi-head agents of Meta-World's baselines (MTMHSAC), "per-task" all of them.
    architecture: Literal["shared", "multi-head", "per-task"] = "multi-head"
    # Cut each env's first episode short at a random multiple of `unroll` steps. Otherwise all
    # envs run their episodes in lockstep and every update learns from one `unroll`-step slice
    # of the episode (the reach, then the grasp, ...), forgetting the others in turn; legged_gym
    # starts its envs at random episode lengths for the same reason. Multiples of `unroll` keep
    # the restarts to a few steps of the first episode (each one resets rows of the whole batch).
    staggered_starts: bool = True
    # What the reward scale and the advantages are normalized over: each task's own samples
    # ("per-task": no task's reward scale drowns out another's), or all tasks' together ("shared":
    # the tasks keep their relative reward scales, as for a learner without per-task statistics).
    normalization: Literal["per-task", "shared"] = "per-task"
    reward_version: str = "v2"
    max_episode_steps: int = 500
    seed: int = 0
    # Local devices to split the envs over (data parallel); 1 runs the single-device program.
    devices: int = 1


class RunningStats(NamedTuple):
    """Mean and variance over everything seen so far (Chan et al.'s parallel merge), per column
    or, for rewards, per task."""

    count: Array
    mean: Array
    var: Array

    @staticmethod
    def zeros(shape: tuple[int, ...]) -> RunningStats:
        return RunningStats(jnp.zeros(shape[:-1] or ()), jnp.zeros(shape), jnp.ones(shape))

    def merge(self, batch: Array, axis: tuple[int, ...], axis_name: str | None = None) -> RunningStats:
        """With `axis_name` (inside a `shard_map`), `batch` is one device's equal share."""
        n = math.prod(batch.shape[a] for a in axis)
        mean, var = batch.mean(axis=axis), batch.var(axis=axis)
        if axis_name is not None:
            n = n * jax.lax.psum(1, axis_name)
            global_mean = jax.lax.pmean(mean, axis_name)
            var = jax.lax.pmean(var + (mean - global_mean) ** 2, axis_name)
            mean = global_mean
        total = self.count + n
        delta = mean - self.mean
        new_mean = self.mean + delta * n / total
        m2 = self.var * self.count + var * n + delta**2 * self.count * n / total
        return RunningStats(total, new_mean, m2 / total)


class Params(NamedTuple):
    """Layers are `(w, b)`; a task's own layer has a leading task axis on both."""

    policy: list[tuple[Array, Array]]
    log_std: Array  # (tasks, 4): each task explores at its own scale
    value: list[tuple[Array, Array]]


class Normalizers(NamedTuple):
    obs: RunningStats
    returns: RunningStats  # per task, of the discounted return accumulated so far


class Transition(NamedTuple):
    obs: Array  # as observed, with the one-hot task id
    action: Array  # unclipped Gaussian sample
    log_prob: Array
    value: Array
    reward: Array  # raw
    truncated: Array
    final_value: Array  # value of the episode's last observation, where it was truncated


class Carry(NamedTuple):
    params: Params
    opt_state: Any
    norm: Normalizers
    env_state: mwjax.State
    running_return: Array  # per env, for the reward scale
    episode_success: Array  # per env: success at any step of the current episode
    first_cut: Array  # per env: the step at which its first episode is cut short, or -1
    key: Array


class Metrics(NamedTuple):
    episodes: Array  # per task, episodes finished
    successes: Array  # per task, of those, ones that succeeded
    physics_resets: Array  # per task, env steps whose physics diverged and was reset (`mwjax.physics`)
    loss: Array
    approx_kl: Array
    # The loss's terms (before their coefficients): which one spikes when training breaks down.
    policy_loss: Array
    value_loss: Array


def chunk_metrics(per_update: Metrics) -> Metrics:
    """A chunk's metrics from its updates' (stacked on a leading axis): the counts summed, the
    losses averaged."""
    return Metrics(
        per_update.episodes.sum(0),
        per_update.successes.sum(0),
        per_update.physics_resets.sum(0),
        per_update.loss.mean(),
        per_update.approx_kl.mean(),
        per_update.policy_loss.mean(),
        per_update.value_loss.mean(),
    )


def _orthogonal(key: Array, shape: tuple[int, ...], scale: float) -> Array:
    """`jax.nn.initializers.orthogonal`'s matrices (the last two axes; any leading ones are a
    batch), with the QR done by NumPy on the host: inside a jitted function on a 2-core CPU, two
    batched LAPACK QRs running at once can each wait for the other's share of XLA's two-thread
    pool, and the program hangs (seen in CI's smoke test)."""
    *batch, n_rows, n_cols = shape
    normal = jax.random.normal(key, (*batch, max(n_rows, n_cols), min(n_rows, n_cols)))
    q, r = np.linalg.qr(np.asarray(normal, np.float64))
    q = q * np.sign(np.diagonal(r, axis1=-2, axis2=-1))[..., None, :]
    if n_rows < n_cols:
        q = np.swapaxes(q, -1, -2)
    return jnp.asarray(scale * q, jnp.float32)


def _mlp_init(
    key: Array, sizes: list[int], last_scale: float, own_layers: int, n_tasks: int
) -> list[tuple[Array, Array]]:
    """An MLP whose last `own_layers` layers are per task (host-side: see `_orthogonal`)."""
    layers = []
    n_layers = len(sizes) - 1
    for i, (fan_in, fan_out) in enumerate(zip(sizes[:-1], sizes[1:], strict=True)):
        key, sub = jax.random.split(key)
        scale = last_scale if i == n_layers - 1 else math.sqrt(2.0)
        tasks = (n_tasks,) if i >= n_layers - own_layers else ()
        layers.append((_orthogonal(sub, (*tasks, fan_in, fan_out), scale), jnp.zeros((*tasks, fan_out))))
    return layers


def _dense(x: Array, w: Array, b: Array) -> Array:
    """`x` is `(tasks, n, features)`; a per-task layer applies each task's weights to its rows."""
    if w.ndim == 2:
        return x @ w + b
    return jnp.einsum("tni,tio->tno", x, w) + b[:, None]


def _mlp(layers: list[tuple[Array, Array]], x: Array) -> Array:
    for w, b in layers[:-1]:
        x = jax.nn.swish(_dense(x, w, b))
    return _dense(x, *layers[-1])


def _log_prob(mean: Array, log_std: Array, action: Array) -> Array:
    """Of `(tasks, n, 4)` actions under `(tasks, 4)` log standard deviations."""
    log_std = log_std[:, None]
    z = (action - mean) * jnp.exp(-log_std)
    return jnp.sum(-0.5 * z**2 - log_std - 0.5 * math.log(2 * math.pi), axis=-1)


class Trainer:
    """The jitted pieces of a run: `init(key)`, `train_chunk(carry, n)` and `evaluator(episodes)`."""

    def __init__(self, config: Config) -> None:
        self.config = config
        # Every device of the run: this process's, or with `python -m mwjax.distributed` every
        # process's (one GPU each).
        self.devices = jax.devices()[: config.devices] if config.devices > 1 else None
        if self.devices is not None and len(self.devices) < config.devices:
            raise ValueError(f"{config.devices} devices asked for, {len(self.devices)} present")
        self.env = mwjax.make(
            config.task_set,
            envs_per_task=config.envs_per_task,
            seed=config.seed,
            reward_version=config.reward_version,
            max_episode_steps=config.max_episode_steps,
            devices=self.devices,
        )
        # Sharded, an update runs under `shard_map` over this axis, each device on its own envs,
        # which `self.rows_per_task` and `self.one_hot` (task by task, as `Env` lays them out) describe.
        self.axis = None if self.devices is None else AXIS
        local_env = self.env if self.devices is None else self.env.local
        self.rows_per_task = local_env.envs_per_task
        self.n_tasks = len(self.env.task_list)
        self.obs_size = OBS_SIZE + self.n_tasks
        self.one_hot = jnp.asarray(local_env.task_one_hot())
        # `policy_frames`' renderer and jitted rollout per (steps, size, camera), built on first use.
        self._frame_programs: dict[tuple[int | None, int, str], tuple[rendering.Renderer, Any]] = {}
        per_task = self.rows_per_task * config.unroll
        if per_task % config.minibatches:
            where = "" if self.devices is None else " on each device"
            raise ValueError(
                f"{per_task} samples per task and update{where} do not split into "
                f"{config.minibatches} minibatches"
            )
        self.optimizer = optax.chain(
            optax.clip_by_global_norm(config.max_grad_norm), optax.adam(config.learning_rate)
        )
        self._init_rest = jax.jit(self._init_rest_of_carry)
        chunk = self._train_chunk if self.axis is None else self._sharded_train_chunk
        self.train_chunk = jax.jit(chunk, static_argnums=1, donate_argnums=0)
        # Several seeds' carries stacked on a leading axis, trained in one program (`train_seeds`).
        self.train_chunks = jax.jit(
            lambda carries, n: jax.vmap(lambda c: self._train_chunk(c, n))(carries),
            static_argnums=1,
            donate_argnums=0,
        )

    # -- data parallel: collectives over the devices (nothing without them) --------------------

    def _pmean(self, x: Any) -> Any:
        return x if self.axis is None else jax.lax.pmean(x, self.axis)

    def _psum(self, x: Any) -> Any:
        return x if self.axis is None else jax.lax.psum(x, self.axis)

    def _step_env(self) -> Any:
        """The env the rollout steps: inside the update's `shard_map`, this device's."""
        return self.env if self.axis is None else self.env.device_env()

    @staticmethod
    def _carry_specs() -> Carry:
        """How a sharded run splits the carry: the envs' rows over the devices, the rest replicated."""
        rows = P(AXIS)
        return Carry(P(), P(), P(), rows, rows, rows, rows, P())

    def _sharded_train_chunk(self, carry: Carry, updates: int) -> tuple[Carry, Metrics]:
        """`_train_chunk` on every device, on its envs; the rest of the carry is replicated."""
        specs = self._carry_specs()
        run = jax.shard_map(
            lambda c: self._train_chunk(c, updates),
            mesh=self.env.mesh,
            in_specs=(specs,),
            out_specs=(specs, P()),
            check_vma=False,
        )
        return run(carry)

    # -- the policy ---------------------------------------------------------------------------

    def init(self, key: Array) -> Carry:
        cfg = self.config
        policy_key, value_key, env_key, cut_key, key = jax.random.split(key, 5)
        sizes = [self.obs_size, *cfg.hidden]
        own = {"shared": 0, "multi-head": 1, "per-task": len(sizes)}[cfg.architecture]
        params = Params(
            policy=_mlp_init(policy_key, [*sizes, 4], 0.01, own, self.n_tasks),
            log_std=jnp.full((self.n_tasks, 4), cfg.init_log_std, jnp.float32),  # not weak: one compile
            value=_mlp_init(value_key, [*sizes, 1], 1.0, own, self.n_tasks),
        )
        carry = self._init_rest(params, env_key, cut_key, key)
        if self.axis is not None:  # placed as `train_chunk` returns it, so it compiles once
            shardings = jax.tree.map(
                lambda spec: jax.sharding.NamedSharding(self.env.mesh, spec),
                self._carry_specs(),
                is_leaf=lambda x: isinstance(x, P),
            )
            carry = jax.device_put(carry, shardings)
        return carry

    def _init_rest_of_carry(self, params: Params, env_key: Array, cut_key: Array, key: Array) -> Carry:
        cfg = self.config
        norm = Normalizers(RunningStats.zeros((OBS_SIZE,)), RunningStats.zeros((self.n_tasks,)))
        env_state = self.env.reset(env_key)
        zeros = jnp.zeros(self.env.num_envs)
        first_cut = jnp.full(self.env.num_envs, -1, jnp.int32)
        if cfg.staggered_starts:
            slots = jax.random.randint(cut_key, first_cut.shape, 0, cfg.max_episode_steps // cfg.unroll)
            first_cut = jnp.where(slots > 0, slots * cfg.unroll, -1)
        return Carry(
            params, self.optimizer.init(params), norm, env_state, zeros, zeros.astype(bool), first_cut, key
        )

    def _with_task(self, obs: Array) -> Array:
        return jnp.concatenate([obs, self.one_hot], axis=-1)

    @staticmethod
    def _normalize(norm: Normalizers, obs: Array) -> Array:
        """Normalizes the env observation; the one-hot task id after it passes through as is."""
        env_obs, task = obs[..., :OBS_SIZE], obs[..., OBS_SIZE:]
        env_obs = jnp.clip((env_obs - norm.obs.mean) / jnp.sqrt(norm.obs.var + 1e-8), -10.0, 10.0)
        return jnp.concatenate([env_obs, task], axis=-1)

    # The networks take `(tasks, n, features)`: every batch here, the evaluator's included, is
    # laid out task by task, so a flat batch of envs splits into equal runs of rows per task.

    def _by_task(self, x: Array) -> Array:
        return x.reshape(self.n_tasks, -1, *x.shape[1:])

    def _mean(self, params: Params, obs: Array) -> Array:
        return _mlp(params.policy, obs)

    def _value(self, params: Params, obs: Array) -> Array:
        return _mlp(params.value, obs)[..., 0]

    def _per_task(self, x: Array) -> Array:
        """`(unroll, num_envs)` as `(unroll, tasks, envs_per_task)` (a device's envs, sharded)."""
        return x.reshape(x.shape[0], self.n_tasks, self.rows_per_task, *x.shape[2:])

    def policy(self, params_and_norm: tuple[Params, Normalizers], obs: Array, key: Array) -> Array:
        """The deterministic (mean) action for a batch of observations with one-hot task ids
        appended, as `mwjax.evaluation.evaluator(..., one_hot=True)` calls a policy: task-major,
        or sharded, device by device (each device's rows task-major)."""
        del key
        return self._mean_action(params_and_norm, obs, 1 if self.devices is None else len(self.devices))

    def _mean_action(self, params_and_norm: tuple[Params, Normalizers], obs: Array, n: int) -> Array:
        """`policy` for a batch laid out in `n` device shares, each task-major."""
        params, norm = params_and_norm
        # (devices, tasks, rows) -> (tasks, devices * rows): each task's rows together.
        obs = self._normalize(norm, obs).reshape(n, self.n_tasks, -1, obs.shape[-1]).swapaxes(0, 1)
        mean = self._mean(params, obs.reshape(self.n_tasks, -1, obs.shape[-1]))
        mean = mean.reshape(self.n_tasks, n, -1, 4).swapaxes(0, 1)
        return jnp.clip(mean.reshape(-1, 4), -1.0, 1.0)

    # -- one PPO update -------------------------------------------------------------------------

    def _rollout(self, carry: Carry) -> tuple[Carry, Transition, Array, Array]:
        params, norm = carry.params, carry.norm
        env = self._step_env()

        def step(c: tuple, key: Array) -> tuple[tuple, tuple[Transition, Array, Array]]:
            env_state, episode_success, first_cut = c
            raw = self._with_task(env_state.obs)
            obs = self._by_task(self._normalize(norm, raw))
            mean = self._mean(params, obs)
            action = mean + jnp.exp(params.log_std)[:, None] * jax.random.normal(key, mean.shape)
            log_prob = _log_prob(mean, params.log_std, action).reshape(-1)
            value = self._value(params, obs).reshape(-1)
            action = action.reshape(-1, 4)
            env_state = env.step(env_state, jnp.clip(action, -1.0, 1.0))
            full_length = env_state.truncated
            cut = env_state.steps == first_cut
            truncated = full_length | cut
            last_obs = jnp.where(cut[:, None], env_state.obs, env_state.info["final_obs"])
            final_obs = self._normalize(norm, self._with_task(last_obs))
            final_value = self._value(params, self._by_task(final_obs)).reshape(-1)
            success = episode_success | env_state.info["success"]
            transition = Transition(
                raw,
                action,
                log_prob,
                value,
                env_state.reward,
                truncated,
                jnp.where(truncated, final_value, 0.0),
            )
            if self.config.staggered_starts:
                # `cond_any`, not `lax.cond`: it stays one branch under `train_seeds`' outer vmap.
                env_state = cond_any(cut, env.restart, lambda s, _: s, env_state)
            # Training success counts full-length episodes only; cut ones had less time.
            ended = full_length & success
            next_c = (env_state, success & ~truncated, jnp.where(truncated, -1, first_cut))
            return next_c, (transition, full_length, ended, env_state.info["physics_reset"])

        key, rollout_key = jax.random.split(carry.key)
        if self.axis is not None:  # each device explores with its own noise
            rollout_key = jax.random.fold_in(rollout_key, jax.lax.axis_index(self.axis))
        keys = jax.random.split(rollout_key, self.config.unroll)
        (env_state, episode_success, first_cut), (batch, ended, ended_success, resets) = jax.lax.scan(
            step, (carry.env_state, carry.episode_success, carry.first_cut), keys
        )
        episodes = self._psum(self._per_task(ended).sum(axis=(0, 2)))
        successes = self._psum(self._per_task(ended_success).sum(axis=(0, 2)))
        resets = self._psum(self._per_task(resets).sum(axis=(0, 2)))
        carry = carry._replace(
            env_state=env_state, episode_success=episode_success, first_cut=first_cut, key=key
        )
        return carry, batch, (episodes, successes, resets)

    def _scaled_rewards(self, carry: Carry, batch: Transition) -> tuple[Carry, Array]:
        """Rewards divided by each task's running std of the discounted return."""

        def accumulate(running: Array, x: tuple[Array, Array]) -> tuple[Array, Array]:
            reward, truncated = x
            running = running * self.config.gamma + reward
            return jnp.where(truncated, 0.0, running), running

        running, returns = jax.lax.scan(accumulate, carry.running_return, (batch.reward, batch.truncated))
        if self.config.normalization == "per-task":
            by_task = self._per_task(returns).transpose(0, 2, 1)  # (unroll, rows, tasks)
        else:  # every task's column sees every task's returns
            by_task = jnp.broadcast_to(returns[..., None], (*returns.shape, self.n_tasks))
        stats = carry.norm.returns.merge(by_task, (0, 1), self.axis)
        scale = jnp.repeat(jnp.sqrt(stats.var + 1e-8), self.rows_per_task)
        norm = carry.norm._replace(returns=stats)
        return carry._replace(norm=norm, running_return=running), batch.reward / scale

    def _advantages(
        self, params: Params, norm: Normalizers, env_state: mwjax.State, batch: Transition, rewards: Array
    ) -> tuple[Array, Array]:
        cfg = self.config
        last_obs = self._normalize(norm, self._with_task(env_state.obs))
        last_value = self._value(params, self._by_task(last_obs)).reshape(-1)
        next_values = jnp.concatenate([batch.value[1:], last_value[None]])
        # At a truncation the next obs is the new episode's: bootstrap from the final obs instead.
        next_values = jnp.where(batch.truncated, batch.final_value, next_values)
        deltas = rewards + cfg.gamma * next_values - batch.value

        def backward(advantage: Array, x: tuple[Array, Array]) -> tuple[Array, Array]:
            delta, truncated = x
            advantage = delta + cfg.gamma * cfg.gae_lambda * jnp.where(truncated, 0.0, advantage)
            return advantage, advantage

        _, advantages = jax.lax.scan(
            backward, jnp.zeros_like(last_value), (deltas, batch.truncated), reverse=True
        )
        return advantages, advantages + batch.value

    def _loss(self, params: Params, mb: Transition, advantages: Array, targets: Array) -> Array:
        cfg = self.config
        mean = self._mean(params, mb.obs)
        log_prob = _log_prob(mean, params.log_std, mb.action)
        ratio = jnp.exp(log_prob - mb.log_prob)
        policy_loss = -jnp.minimum(
            ratio * advantages, jnp.clip(ratio, 1 - cfg.clip, 1 + cfg.clip) * advantages
        ).mean()
        value_loss = 0.5 * ((self._value(params, mb.obs) - targets) ** 2).mean()
        entropy = jnp.sum(params.log_std + 0.5 * math.log(2 * math.pi * math.e)) / self.n_tasks
        loss = policy_loss + cfg.value_coef * value_loss - cfg.entropy_coef * entropy
        return loss, ((mb.log_prob - log_prob).mean(), policy_loss, value_loss)

    def _update(self, carry: Carry, _: None) -> tuple[Carry, Metrics]:
        carry, batch, counts = self._rollout(carry)
        carry, losses = self._learn(carry, batch)
        return carry, Metrics(*counts, *losses)

    def _learn(self, carry: Carry, batch: Transition) -> tuple[Carry, tuple[Array, ...]]:
        """The learner's half of an update: returns, advantages and the epochs of minibatches.
        Also returns the loss, the approximate KL, the policy loss and the value loss, each the
        mean over the update's minibatches."""
        cfg = self.config
        carry, rewards = self._scaled_rewards(carry, batch)
        advantages, targets = self._advantages(carry.params, carry.norm, carry.env_state, batch, rewards)
        per_task = self._per_task(advantages)
        axes = (0, 2) if cfg.normalization == "per-task" else (0, 1, 2)
        if self.axis is None:
            per_task = (per_task - per_task.mean(axis=axes, keepdims=True)) / (
                per_task.std(axis=axes, keepdims=True) + 1e-8
            )
        else:  # the moments over every device's samples
            mean = self._pmean(per_task.mean(axis=axes, keepdims=True))
            var = self._pmean(((per_task - mean) ** 2).mean(axis=axes, keepdims=True))
            per_task = (per_task - mean) / (jnp.sqrt(var) + 1e-8)
        advantages = per_task.reshape(advantages.shape)
        # The loss sees observations as the rollout's policy saw them; the statistics of this
        # rollout then join the running ones, for the next rollouts.
        env_obs = batch.obs[..., :OBS_SIZE]
        norm = carry.norm._replace(obs=carry.norm.obs.merge(env_obs, (0, 1), self.axis))
        batch = batch._replace(obs=self._normalize(carry.norm, batch.obs))

        # `(tasks, unroll * envs_per_task, ...)`: every minibatch takes as many samples of each task.
        by_task = jax.tree.map(
            lambda x: jnp.moveaxis(self._per_task(x), 1, 0).reshape(self.n_tasks, -1, *x.shape[2:]),
            (batch, advantages, targets),
        )
        n = by_task[1].shape[1]

        def epoch(c: tuple, key: Array) -> tuple[tuple, tuple[Array, ...]]:
            order = jax.random.permutation(key, n).reshape(cfg.minibatches, -1)

            def minibatch(c: tuple, idx: Array) -> tuple[tuple, tuple[Array, ...]]:
                params, opt_state = c
                mb, adv, tgt = jax.tree.map(lambda x: x[:, idx], by_task)
                (loss, aux), grads = jax.value_and_grad(self._loss, has_aux=True)(params, mb, adv, tgt)
                grads = self._pmean(grads)  # data parallel: the mean over every device's minibatch
                updates, opt_state = self.optimizer.update(grads, opt_state, params)
                return (optax.apply_updates(params, updates), opt_state), (loss, *aux)

            return jax.lax.scan(minibatch, c, order)

        key, epoch_key = jax.random.split(carry.key)
        (params, opt_state), losses = jax.lax.scan(
            epoch, (carry.params, carry.opt_state), jax.random.split(epoch_key, cfg.epochs)
        )
        carry = carry._replace(params=params, opt_state=opt_state, norm=norm, key=key)
        return carry, tuple(self._pmean(x.mean()) for x in losses)

    def _train_chunk(self, carry: Carry, updates: int) -> tuple[Carry, Metrics]:
        carry, metrics = jax.lax.scan(self._update, carry, None, length=updates)
        return carry, chunk_metrics(metrics)

    def rollout_seconds(self, carry: Carry, updates: int) -> float:
        """Wall time of the rollouts of `updates` updates alone (the policy acting, the env
        stepping; no learning; compile excluded), on one device or sharded: the rest of an
        update's time is the learner's and its collectives'."""

        def rollouts(c: Carry) -> tuple[Carry, Array]:
            def one(c: Carry, _: None) -> tuple[Carry, Array]:
                c, _, (episodes, _, _) = self._rollout(c)
                return c, episodes.sum()

            return jax.lax.scan(one, c, None, length=updates)

        if self.axis is not None:
            specs = self._carry_specs()
            rollouts = jax.shard_map(
                rollouts, mesh=self.env.mesh, in_specs=(specs,), out_specs=(specs, P()), check_vma=False
            )
        compiled = jax.jit(rollouts).lower(carry).compile()
        carry = jax.block_until_ready(compiled(carry))[0]
        t0 = time.perf_counter()
        jax.block_until_ready(compiled(carry))
        return time.perf_counter() - t0

    def learner_seconds(self, carry: Carry, updates: int) -> float:
        """Wall time of the learner's half of `updates` updates alone (compile excluded), on a
        stand-in rollout of the real shapes: what is left of an update is the simulator and the
        policy acting in it."""
        if self.axis is not None:
            raise NotImplementedError("timing the learner alone runs on one device (drop --devices)")
        batch = jax.eval_shape(self._rollout, carry)[1]
        keys = iter(jax.random.split(jax.random.key(0), len(jax.tree.leaves(batch))))
        batch = jax.tree.map(
            lambda s: (
                jax.random.normal(next(keys), s.shape)
                if s.dtype == jnp.float32
                else jnp.zeros(s.shape, s.dtype)
            ),
            batch,
        )
        learn = jax.jit(
            lambda c, b: jax.lax.scan(lambda c, _: (self._learn(c, b)[0], None), c, None, length=updates)[0]
        )
        compiled = learn.lower(carry, batch).compile()
        jax.block_until_ready(compiled(carry, batch))
        t0 = time.perf_counter()
        jax.block_until_ready(compiled(carry, batch))
        return time.perf_counter() - t0

    def evaluator(self, num_episodes: int = 50, stacked: bool = False) -> Any:
        """`(params_and_norm, key) -> EvalResult`; `stacked`: of seeds stacked on a leading axis."""
        run = evaluator(self.env, self.policy, num_episodes, one_hot=True)
        return jax.jit(jax.vmap(run) if stacked else run)

    def policy_frames(
        self,
        params_and_norm: tuple[Params, Normalizers],
        key: Array,
        steps: int | None = None,
        size: int = 128,
        camera: str = "corner",
    ) -> np.ndarray:
        """Frames of one episode of the policy's mean action on each task (one env per task, a
        goal drawn from `key`, no autoreset), `(steps, tasks, size, size, 3)` uint8: the
        rollout and the captures run jitted on device, the images are drawn afterwards."""
        # One env, renderer and program per setting, the parameters an argument: a second call
        # (another policy's frames) compiles nothing.
        setting = (steps, size, camera)
        if setting not in self._frame_programs:
            self._frame_programs[setting] = self._frames_program(steps, size, camera)
        renderer, rollout = self._frame_programs[setting]
        # Through the host: a data-parallel run's parameters are replicated over its devices, the
        # frames' env lives on one.
        return renderer.frames(rollout(jax.tree.map(np.asarray, params_and_norm), key))

    def _frames_program(self, steps: int | None, size: int, camera: str) -> tuple[rendering.Renderer, Any]:
        """`policy_frames`' renderer and its jitted `(params_and_norm, key) -> Capture`."""
        cfg = self.config
        env = mwjax.make(
            self.env.task_list,
            envs_per_task=1,
            seed=cfg.seed,
            reward_version=cfg.reward_version,
            max_episode_steps=cfg.max_episode_steps,
            autoreset="disabled",
        )
        renderer = rendering.Renderer(env, camera=camera, width=size, height=size)
        one_hot = jnp.asarray(env.task_one_hot())

        @jax.jit
        def rollout(params_and_norm: tuple[Params, Normalizers], key: Array) -> rendering.Capture:
            def body(state: mwjax.State, _: None) -> tuple[mwjax.State, rendering.Capture]:
                obs = jnp.concatenate([state.obs, one_hot], axis=-1)
                state = env.step(state, self._mean_action(params_and_norm, obs, 1))
                return state, renderer.capture(state)

            state = env.reset(key)
            _, captures = jax.lax.scan(body, state, None, length=steps or cfg.max_episode_steps)
            first = jax.tree.map(lambda x: x[None], renderer.capture(state))
            return jax.tree.map(lambda a, b: jnp.concatenate([a, b]), first, captures)

        return renderer, rollout

    @property
    def steps_per_update(self) -> int:
        return self.env.num_envs * self.config.unroll


# -- checkpoints (this example's and the RL² example's carries alike) ------------------------------


def _learner(carry: Any) -> tuple:
    """What a checkpoint keeps: the env state and episodes are not (resuming starts new ones)."""
    return (carry.params, carry.opt_state, carry.norm, jax.random.key_data(carry.key))


def save_checkpoint(stem: str | Path, carry: Any, updates: int, curve: list[dict]) -> None:
    """`stem.npz` (the learner's arrays, the update count and curve so far) and `stem.json` (the
    count and curve, to read). Each file is written whole beside its place and then moved there,
    so a run stopped mid-save, or a copy taken while it saves, finds the previous checkpoint
    intact; the npz alone is what resuming reads, so the two can never disagree."""
    meta = json.dumps({"updates": updates, "curve": curve})
    leaves = [np.asarray(x) for x in jax.tree.leaves(_learner(carry))]
    write_atomically(Path(f"{stem}.npz"), lambda file: np.savez(file, *leaves, meta=np.array(meta)))
    write_atomically(Path(f"{stem}.json"), lambda file: file.write(meta.encode()))


def restore_checkpoint(stem: str | Path, template: Any) -> tuple[Any, int, list[dict]]:
    """`template` (a fresh `Trainer.init`) with the checkpoint's learner restored, each array
    placed as the template's is."""
    like = jax.tree.leaves(_learner(template))
    with np.load(f"{stem}.npz") as data:
        arrays = [name for name in data.files if name.startswith("arr_")]
        if len(arrays) != len(like):
            raise ValueError(f"{stem}.npz holds {len(arrays)} arrays, this run's learner {len(like)}")
        meta = _checkpoint_meta(stem, data)
        # An uncommitted template leaf (a single-device run's) stays uncommitted: `train_chunk`
        # compiled for the template would compile again for a carry that mixes the two.
        leaves = [
            jax.device_put(data[f"arr_{i}"], t.sharding) if t.committed else jnp.asarray(data[f"arr_{i}"])
            for i, t in enumerate(like)
        ]
    for saved, expected in zip(leaves, like, strict=True):
        if saved.shape != expected.shape:
            raise ValueError(f"{stem}.npz is another configuration's ({saved.shape} vs {expected.shape})")
    params, opt_state, norm, key = jax.tree.unflatten(jax.tree.structure(_learner(template)), leaves)
    key = jax.random.wrap_key_data(key)
    carry = template._replace(params=params, opt_state=opt_state, norm=norm, key=key)
    return carry, meta["updates"], meta["curve"]


def _checkpoint_meta(stem: str | Path, data: Any) -> dict:
    """The update count and curve of the checkpoint whose open npz is `data`: saved in it, or,
    by a version that saved them only beside it, in `stem.json`."""
    if "meta" in data.files:
        return json.loads(str(data["meta"]))
    return json.loads(Path(f"{stem}.json").read_text())


def start_or_resume(
    trainer: Any, seed: int | Sequence[int], checkpoint: str | Path | None
) -> tuple[Any, int, list]:
    """`(carry, updates done, curve)`: a fresh `trainer.init`, or the learner saved at
    `checkpoint` (if there is one) in a template whose episodes differ from the first run's.
    With a list of seeds (`train_seeds`), their carries stacked and a curve per seed."""
    seeds = [seed] if isinstance(seed, int) else list(seed)

    def fresh(done: int) -> Any:
        keys = [jax.random.key(s) if not done else jax.random.fold_in(jax.random.key(s), done) for s in seeds]
        carries = [trainer.init(key) for key in keys]
        return carries[0] if isinstance(seed, int) else jax.tree.map(lambda *x: jnp.stack(x), *carries)

    if checkpoint is None or not Path(f"{checkpoint}.npz").exists():
        return fresh(0), 0, ([] if isinstance(seed, int) else [[] for _ in seeds])
    with np.load(f"{checkpoint}.npz") as data:
        meta = _checkpoint_meta(checkpoint, data)
    if not isinstance(seed, int) and len(meta["curve"]) != len(seeds):
        raise ValueError(f"{checkpoint} holds {len(meta['curve'])} seeds' runs, this run has {len(seeds)}")
    carry, updates, curve = restore_checkpoint(checkpoint, fresh(meta["updates"]))
    print(f"resumed {checkpoint} at update {updates}", flush=True)
    return carry, updates, curve


def train(
    config: Config,
    minutes: float,
    log_every: int,
    max_updates: int | None = None,
    eval_episodes: int = 50,
    time_learner: bool = False,
    video: Path | None = None,
    video_size: int = 128,
    checkpoint: str | Path | None = None,
    kernels: Any = None,
) -> dict:
    """Train until `minutes` of wall clock (compile included) or `max_updates` in all (counting a
    resumed checkpoint's), saving `checkpoint` after every chunk if given; then evaluate, with
    `time_learner` time the learner alone against the last chunk of updates, and with `video` (a
    folder) write one episode of the trained policy on each task as `<task>.mp4`. `kernels`: a
    Warp kernel build under way (`start_kernels`), which the first chunk's compile overlaps."""
    if checkpoint is not None and config.devices > 1:
        raise ValueError("checkpoints are for one device; train with --devices 1")
    start = time.perf_counter()
    with progress.phase("building the envs and the first state"):
        trainer = Trainer(config)
        carry, updates, curve = start_or_resume(trainer, config.seed, checkpoint)
    # The curve's wall clock runs on across resumed runs.
    start -= curve[-1]["wall_s"] if curve else 0.0
    budget = minutes * 60 + (curve[-1]["wall_s"] if curve else 0.0)
    print(
        f"{config.task_set}: {trainer.env.num_envs} envs, {trainer.steps_per_update:,} env steps per update",
        flush=True,
    )
    loop = _Loop(carry, updates)
    for metrics in _chunks(trainer.train_chunk, loop, start, budget, log_every, max_updates, kernels):
        row = _row(metrics, loop.updates, trainer, time.perf_counter() - start)
        curve.append(row)
        _progress(row, budget, metrics.episodes)
        if checkpoint is not None:
            save_checkpoint(checkpoint, loop.carry, loop.updates, curve)
    carry, n, chunk_s = loop.carry, loop.n, loop.chunk_s
    train_s = time.perf_counter() - start
    t0 = time.perf_counter()
    key = jax.random.key(config.seed + 1000)
    with progress.phase(f"evaluating: {eval_episodes} episodes per task"):
        success = np.asarray(trainer.evaluator(eval_episodes)((carry.params, carry.norm), key).success_rate)
    split = {}
    if time_learner and chunk_s:  # chunk_s is 0 if the only chunk included the compile
        learner_s = trainer.learner_seconds(carry, n)
        split = {"time_split": {"updates": n, "update_s": chunk_s, "learner_s": learner_s}}
        print(
            f"{n} updates: {chunk_s:.1f}s, of which the learner alone {learner_s:.1f}s "
            f"({learner_s / chunk_s:.0%}); simulator and acting the rest",
            flush=True,
        )
    videos = {}
    if video is not None:
        frames = trainer.policy_frames(
            (carry.params, carry.norm), jax.random.key(config.seed + 2000), size=video_size
        )
        for task, task_frames in zip(trainer.env.task_list, frames.swapaxes(0, 1), strict=True):
            videos[task] = str(rendering.write_video(task_frames, Path(video) / f"{task}.mp4"))
        print(f"videos of the trained policy -> {video}/", flush=True)
    return {
        **split,
        **({"videos": videos} if videos else {}),
        "config": dataclasses.asdict(config),
        "curve": curve,
        "train_s": train_s,
        "eval_s": time.perf_counter() - t0,
        "eval_success_per_task": dict(zip(trainer.env.task_list, success.tolist(), strict=True)),
        "eval_success": float(success.mean()),
        "params": carry.params,
    }


def train_seeds(
    config: Config,
    seeds: list[int],
    minutes: float,
    log_every: int,
    max_updates: int | None = None,
    eval_episodes: int = 50,
    kernels: Any = None,
    checkpoint: str | Path | None = None,
) -> list[dict]:
    """Train every seed of `seeds` at once in one program on one device (`--vmap-seeds`): their
    carries stacked on a leading axis, each update `jax.vmap`ped over them, so one device call
    gives a distribution. The seeds share one env, so its goal variants come from `config.seed`;
    each seed has its own initial parameters, resets, exploration and minibatches. One run
    (`train`'s result) per seed; wall clock, training and evaluation time are the program's.
    `checkpoint` holds all the seeds' learners and curves, saved after every chunk and resumed
    from as `train`'s is."""
    if config.devices > 1:
        raise ValueError("seeds in one program run on one device; train with --devices 1")
    start = time.perf_counter()
    with progress.phase(f"building the envs and {len(seeds)} seeds' first states"):
        trainer = Trainer(config)
        carry, updates, curves = start_or_resume(trainer, seeds, checkpoint)
        loop = _Loop(carry, updates)
        del carry
    # The curves' wall clock runs on across resumed runs.
    resumed_s = curves[0][-1]["wall_s"] if curves[0] else 0.0
    start -= resumed_s
    budget = minutes * 60 + resumed_s
    print(
        f"{config.task_set}: {len(seeds)} seeds x {trainer.env.num_envs} envs, "
        f"{len(seeds) * trainer.steps_per_update:,} env steps per update",
        flush=True,
    )
    for metrics in _chunks(trainer.train_chunks, loop, start, budget, log_every, max_updates, kernels):
        wall_s = time.perf_counter() - start
        for i, seed in enumerate(seeds):
            own = jax.tree.map(lambda x, i=i: x[i], metrics)
            curves[i].append(_row(own, loop.updates, trainer, wall_s))
            _progress(curves[i][-1], budget, own.episodes, f"seed {seed} ")
        if checkpoint is not None:
            save_checkpoint(checkpoint, loop.carry, loop.updates, curves)
    train_s = time.perf_counter() - start
    t0 = time.perf_counter()
    carry = loop.carry
    keys = jnp.stack([jax.random.key(seed + 1000) for seed in seeds])
    with progress.phase(f"evaluating {len(seeds)} seeds: {eval_episodes} episodes per task"):
        success = np.asarray(
            trainer.evaluator(eval_episodes, stacked=True)((carry.params, carry.norm), keys).success_rate
        )
    eval_s = time.perf_counter() - t0
    return [
        {
            "config": dataclasses.asdict(dataclasses.replace(config, seed=seed)),
            "one_program": {"seeds": list(seeds), "env_seed": config.seed},
            "curve": curve,
            "train_s": train_s,
            "eval_s": eval_s,
            "eval_success_per_task": dict(zip(trainer.env.task_list, rates.tolist(), strict=True)),
            "eval_success": float(rates.mean()),
            "params": jax.tree.map(lambda x, i=i: x[i], carry.params),
        }
        for i, (seed, curve, rates) in enumerate(zip(seeds, curves, success, strict=True))
    ]


@dataclasses.dataclass
class _Loop:
    """Where a run's chunk loop stands: the carry, the updates so far, and the last chunk's
    updates and seconds (0 for the first, which compiles)."""

    carry: Any
    updates: int
    n: int = 0
    chunk_s: float = 0.0


def _chunks(
    train_chunk: Callable,
    loop: _Loop,
    start: float,
    budget: float,
    log_every: int,
    max_updates: int | None,
    kernels: Any = None,
) -> Iterator[Any]:
    """Chunks of `log_every` updates, advancing `loop`, until `max_updates` in all, or else until
    the next chunk would pass `budget` seconds after `start` (timed by the last one). Yields each
    chunk's metrics, on the host. With `kernels`, a Warp kernel build under way (`start_kernels`),
    the first chunk's program compiles (XLA needs no kernels) while the build runs, and runs once
    the build is done; chunks of that size keep running that program."""
    compiled = False
    ahead: tuple[int, Callable] | None = None
    while max_updates is None or loop.updates < max_updates:
        n = log_every if max_updates is None else min(log_every, max_updates - loop.updates)
        if max_updates is None and time.perf_counter() - start + loop.chunk_s > budget:
            return
        t0 = time.perf_counter()
        if kernels is not None and not kernels.done:
            with progress.phase(f"compiling (XLA) the first {n} updates while the physics kernels build"):
                ahead = (n, train_chunk.lower(loop.carry, n).compile())
            kernels.wait()
        # The first chunk compiles the whole update loop (minutes when sharded): shown, not silent.
        first = f"{'running' if ahead else 'compiling (XLA) and running'} the first {n} updates"
        with progress.phase(first) if not compiled else contextlib.nullcontext():
            if ahead is not None and ahead[0] == n:
                loop.carry, metrics = ahead[1](loop.carry)
            else:
                loop.carry, metrics = train_chunk(loop.carry, n)
            metrics = jax.device_get(metrics)
        if not np.isfinite(metrics.loss).all():
            # Before the caller saves a checkpoint: the last one keeps the learner before this chunk.
            raise FloatingPointError(
                f"training diverged: the loss of updates {loop.updates + 1}-{loop.updates + n} is not "
                f"finite; stopped with the learner of update {loop.updates} (its checkpoint, if any, is kept)"
            )
        loop.chunk_s = time.perf_counter() - t0 if compiled else 0.0
        loop.n, loop.updates = n, loop.updates + n
        compiled = True
        yield metrics


def _row(metrics: Any, updates: int, trainer: Any, wall_s: float) -> dict:
    """One point of a seed's learning curve from its chunk's metrics."""
    rates = metrics.successes / np.maximum(metrics.episodes, 1)
    return {
        "updates": updates,
        "env_steps": updates * trainer.steps_per_update,
        "wall_s": wall_s,
        "train_success": float(rates.mean()) if metrics.episodes.all() else None,
        "train_success_per_task": dict(zip(trainer.env.task_list, rates.tolist(), strict=True)),
        # Envs whose physics diverged and was reset, by task (`info["physics_reset"]`); rare.
        "physics_resets": {
            t: int(n) for t, n in zip(trainer.env.task_list, metrics.physics_resets, strict=True) if n
        },
        "loss": float(metrics.loss),
        "approx_kl": float(metrics.approx_kl),
        "policy_loss": float(metrics.policy_loss),
        "value_loss": float(metrics.value_loss),
    }


def _progress(row: dict, budget: float, episodes: np.ndarray, label: str = "") -> None:
    """A curve row (`_row`) as one progress line; a task with no finished `episodes` shows n/a."""
    done = min(row["wall_s"] / budget, 1.0)
    bar = "#" * int(30 * done) + "." * (30 - int(30 * done))
    mean = "  n/a" if row["train_success"] is None else f"{row['train_success']:.3f}"
    per_task = " ".join(
        f"{t.removesuffix('-v3')}={r:.2f}" if e else f"{t.removesuffix('-v3')}=n/a"
        for (t, r), e in zip(row["train_success_per_task"].items(), episodes, strict=True)
    )
    resets = ", ".join(f"{t.removesuffix('-v3')}={n}" for t, n in row["physics_resets"].items())
    print(
        f"{label}[{bar}] {row['wall_s']:6.0f}s  {row['env_steps'] / 1e6:8.1f}M steps  "
        f"update {row['updates']}  loss {row['loss']:.3f}  success {mean}"
        f"{f'  physics resets: {resets}' if resets else ''} | {per_task}",
        flush=True,
    )


def save_plot(plot: Callable[[list[dict], Path], None], runs: list[dict], path: Path) -> bool:
    """`plot(runs, path)` if matplotlib (optional: the `plots` extra) is there; the run's JSON is
    what counts, so without it the run still ends cleanly, saying so. True if it plotted."""
    try:
        plot(runs, path)
    except ImportError:
        print("matplotlib not installed (pip install 'mwjax[plots]'): no PNG", flush=True)
        return False
    return True


def _plot(runs: list[dict], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2, figsize=(11, 4))
    for run in runs:
        points = [r for r in run["curve"] if r["train_success"] is not None]
        label = f"seed {run['config']['seed']} (eval {run['eval_success']:.2f})"
        axes[0].plot(
            [r["env_steps"] / 1e6 for r in points], [r["train_success"] for r in points], label=label
        )
        axes[1].plot([r["wall_s"] for r in points], [r["train_success"] for r in points], label=label)
    axes[0].set_xlabel("env steps (millions)")
    axes[1].set_xlabel("wall clock (s, compile included)")
    for ax in axes:
        ax.set_ylabel("mean success, training episodes")
        ax.set_ylim(0, 1)
        ax.grid(alpha=0.3)
        ax.legend()
    fig.suptitle(
        f"{runs[0]['config']['task_set']} multi-task PPO ({runs[0]['config']['reward_version']} rewards)"
    )
    fig.tight_layout()
    fig.savefig(path, dpi=120)


def task_curves(runs: list[dict]) -> dict[str, list[tuple[int, list[float], list[float]]]]:
    """Each task's training success over env steps (millions), one series per run (seed, steps,
    success), from the curve points where every task had finished an episode: what the per-task
    PNG draws."""
    curves: dict[str, list[tuple[int, list[float], list[float]]]] = {}
    for run in runs:
        points = [row for row in run["curve"] if row["train_success"] is not None]
        steps = [row["env_steps"] / 1e6 for row in points]
        for task in points[0]["train_success_per_task"] if points else ():
            success = [row["train_success_per_task"][task] for row in points]
            curves.setdefault(task, []).append((run["config"]["seed"], steps, success))
    return curves


def _plot_tasks(runs: list[dict], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    curves = task_curves(runs)
    if not curves:
        return
    cols = min(len(curves), 5 if len(curves) <= 10 else 10)
    rows = math.ceil(len(curves) / cols)
    fig, axes = plt.subplots(
        rows, cols, figsize=(2.3 * cols, 1.9 * rows + 0.6), sharex=True, sharey=True, squeeze=False
    )
    for ax, (task, series) in zip(axes.flat, curves.items(), strict=False):  # spare panels stay empty
        for index, (seed, steps, success) in enumerate(series):
            ax.plot(steps, success, color=f"C{index}", linewidth=1, label=f"seed {seed}")
        evals = [
            run["eval_success_per_task"][task] for run in runs if task in run.get("eval_success_per_task", {})
        ]
        title = task.removesuffix("-v3") + (f" (eval {np.mean(evals):.2f})" if evals else "")
        ax.set_title(title, fontsize=8)
        ax.set_ylim(0, 1.02)
        ax.grid(alpha=0.3)
        ax.tick_params(labelsize=7)
    for ax in axes.flat[len(curves) :]:
        ax.axis("off")
    fig.supxlabel("env steps (millions)", fontsize=9)
    fig.supylabel("success, training episodes", fontsize=9)
    handles, labels = axes.flat[0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="upper right", fontsize=7, ncols=min(len(labels), 5))
    name = runs[0].get("name") or runs[0]["config"]["task_set"]
    fig.suptitle(f"{name}: training success per task", fontsize=10, x=0.02, ha="left")
    fig.tight_layout()
    fig.savefig(path, dpi=110)


def _commit() -> str:
    """The repository's HEAD (or $MWJAX_COMMIT), recorded with the results."""
    if os.environ.get("MWJAX_COMMIT"):
        return os.environ["MWJAX_COMMIT"]
    try:
        return subprocess.run(
            ["git", "rev-parse", "HEAD"], capture_output=True, text=True, check=True
        ).stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        return "unknown"


def task_set(text: str) -> str | tuple[str, ...]:
    """`--set` as `Config.task_set` takes it: `mwjax.benchmarks.parse_tasks`, a list of tasks as
    a tuple."""
    tasks = parse_tasks(text)
    return tasks if isinstance(tasks, str) else tuple(tasks)


def _gpus() -> list[str]:
    """The GPUs a run of this script would use: none when JAX is kept to the CPU."""
    return [] if os.environ.get("JAX_PLATFORMS") == "cpu" else distributed.visible_gpus()


def start_kernels(tasks: Any) -> Any:
    """On GPUs, first: Warp's kernel modules for every scene of `tasks` (a set name, task list or
    `Benchmark`), built side by side in processes (`mwjax.kernels.start_build`) instead of one after
    another inside the first chunk, a minute on a fresh machine; done at once when Warp's cache
    has them. Returns the build under way (None on the CPU): `_chunks` compiles the first chunk's
    program (XLA) while it runs, and the processes this run starts (one per GPU, `--parallel`
    seeds) start once it is done (`wait()`) and find the modules in Warp's cache."""
    if not _gpus() or distributed.launched():
        return None
    from mwjax import kernels

    return kernels.start_build(tasks)


def one_process_per_gpu(devices: str) -> int | None:
    """On GPUs, `--devices N` (N > 1, or `all`) reruns this script as one process per GPU
    (`python -m mwjax.distributed`) and returns the run's exit code: in one process, an update's
    all-reduces between Warp's calls hang on 4 GPUs (docs/multi-gpu.md). None: train here (one
    device, host devices, or already one of the processes)."""
    if devices == "1" or distributed.launched():
        return None
    gpus = _gpus()
    n = len(gpus) if devices == "all" else int(devices)
    if len(gpus) < 2 or n < 2:
        return None
    print(
        f"--devices {devices}: one process per GPU (python -m mwjax.distributed --processes {n})", flush=True
    )
    return distributed.launch([__file__, *sys.argv[1:]], n)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    defaults = Config()
    parser.add_argument("--set", default=defaults.task_set, help="a set name, or tasks separated by commas")
    parser.add_argument("--envs-per-task", type=int, default=defaults.envs_per_task)
    parser.add_argument("--unroll", type=int, default=defaults.unroll)
    parser.add_argument("--minibatches", type=int, default=defaults.minibatches)
    parser.add_argument("--epochs", type=int, default=defaults.epochs)
    parser.add_argument("--lr", type=float, default=defaults.learning_rate)
    parser.add_argument("--entropy-coef", type=float, default=defaults.entropy_coef)
    parser.add_argument("--reward-version", default=defaults.reward_version)
    parser.add_argument(
        "--architecture",
        choices=["shared", "multi-head", "per-task"],
        default=defaults.architecture,
        help="the networks' layers each task has to itself: none, the output layer, all",
    )
    parser.add_argument("--init-log-std", type=float, default=defaults.init_log_std)
    parser.add_argument(
        "--normalization",
        choices=["per-task", "shared"],
        default=defaults.normalization,
        help="reward scale and advantages normalized over each task's samples, or over all tasks' together",
    )
    parser.add_argument(
        "--staggered-starts",
        action=argparse.BooleanOptionalAction,
        default=defaults.staggered_starts,
        help="cut each env's first episode at a random multiple of --unroll steps (runs 1-6: off)",
    )
    add_run_arguments(parser, 8.4, "wall clock per seed (--vmap-seeds: for all), compile included")
    parser.add_argument(
        "--vmap-seeds",
        action="store_true",
        help="train all --seeds at once in one program on one device (jax.vmap over seeds; one env, "
        "so one set of goal variants)",
    )
    parser.add_argument("--eval-episodes", type=int, default=50, help="per task, one per goal variant")
    parser.add_argument(
        "--time-learner", action="store_true", help="after the evaluation, time the learner alone"
    )
    parser.add_argument(
        "--devices",
        default="1",
        help="devices to train on, data parallel: a count or 'all' (with python -m mwjax.distributed, "
        "every process's GPU)",
    )
    parser.add_argument(
        "--video",
        type=Path,
        default=None,
        help="a folder: one episode of the trained policy per task as <task>.mp4 (the video extra), "
        "from the corner camera; with several seeds, one sub-folder per seed",
    )
    parser.add_argument("--video-size", type=int, default=128, help="video frames' width and height")
    parser.add_argument(
        "--checkpoint",
        default=None,
        help="stem to save to after every chunk and resume from (STEM-seed<k>.npz/.json; one device; "
        "--vmap-seeds: STEM-seeds<k>-<l>-....npz/.json)",
    )
    add_combine_argument(parser)
    args = parser.parse_args()
    if combined(parser, args, lambda runs, device, origin: write_results(runs, args, device, origin)):
        return
    if args.checkpoint is not None and args.devices != "1":
        parser.error("--checkpoint is for one device: leave --devices at 1")
    if args.vmap_seeds:
        clash = [
            flag
            for flag, on in [
                ("--parallel", args.parallel > 1),
                ("--devices", args.devices != "1"),
                ("--video", args.video is not None),
                ("--time-learner", args.time_learner),
            ]
            if on
        ]
        if clash:
            parser.error(
                f"--vmap-seeds trains every seed in one program on one device: drop {', '.join(clash)}"
            )
    try:
        # The env's arguments first: on the CPU nothing else reads them before the first seed.
        tasks = task_set(args.set)
        EnvConfig(tasks, envs_per_task=args.envs_per_task, reward_version=args.reward_version)
        benchmark(tasks)
        kernels = start_kernels(tasks)
    except ValueError as error:
        parser.error(str(error))
    if kernels is not None and (args.devices != "1" or (args.parallel > 1 and len(args.seeds) > 1)):
        kernels.wait()  # before the processes this run starts, which find the modules in Warp's cache
    try:
        code = one_process_per_gpu(args.devices)
    except ValueError as error:
        parser.error(str(error))
    if code is not None:
        sys.exit(code)
    if args.parallel > 1 and len(args.seeds) > 1:
        if args.devices != "1":
            parser.error("--parallel trains each seed on one device: leave --devices at 1")
        video = (
            (lambda seed: ["--video", str(args.video / f"seed{seed}")]) if args.video else (lambda seed: [])
        )
        try:
            code = seeds_in_parallel(
                args,
                __file__,
                lambda runs, device: write_results(runs, args, device),
                lambda run: f"evaluation success {run['eval_success']:.3f}",
                video,
            )
        except ValueError as error:
            parser.error(str(error))
        sys.exit(code)
    distributed.initialize()  # one process per GPU, when started by `python -m mwjax.distributed`

    def config_of(seed: int) -> Config:
        return Config(
            task_set=task_set(args.set),
            envs_per_task=args.envs_per_task,
            unroll=args.unroll,
            minibatches=args.minibatches,
            epochs=args.epochs,
            learning_rate=args.lr,
            entropy_coef=args.entropy_coef,
            architecture=args.architecture,
            init_log_std=args.init_log_std,
            staggered_starts=args.staggered_starts,
            normalization=args.normalization,
            reward_version=args.reward_version,
            seed=seed,
            devices=jax.device_count() if args.devices == "all" else int(args.devices),
        )

    if args.vmap_seeds:
        runs = train_seeds(
            config_of(args.seeds[0]),
            args.seeds,
            args.minutes,
            args.log_every,
            args.updates,
            args.eval_episodes,
            kernels,
            None if args.checkpoint is None else f"{args.checkpoint}-seeds{'-'.join(map(str, args.seeds))}",
        )
        for run in runs:
            run.pop("params")
            print(
                f"seed {run['config']['seed']}: evaluation success {run['eval_success']:.3f} "
                f"{run['eval_success_per_task']}",
                flush=True,
            )
        device = jax.devices()[0]
        write_results(runs, args, getattr(device, "device_kind", str(device)))
        return
    runs = []
    for seed in args.seeds:
        config = config_of(seed)
        video = None
        if args.video is not None:
            video = args.video / f"seed{seed}" if len(args.seeds) > 1 else args.video
        run = train(
            config,
            args.minutes,
            args.log_every,
            args.updates,
            args.eval_episodes,
            args.time_learner,
            video,
            args.video_size,
            None if args.checkpoint is None else f"{args.checkpoint}-seed{seed}",
            kernels,
        )
        run.pop("params")
        print(
            f"seed {seed}: evaluation success {run['eval_success']:.3f} "
            f"({run['eval_s']:.0f}s) {run['eval_success_per_task']}",
            flush=True,
        )
        runs.append(run)
    if distributed.is_main():  # every process of a distributed run has the same results
        device = jax.devices()[0]
        write_results(runs, args, getattr(device, "device_kind", str(device)))


def seeds_in_parallel(
    args: argparse.Namespace,
    script: str,
    write: Callable[[list[dict], str], str],
    describe: Callable[[dict], str],
    extra: Callable[[int], list[str]] = lambda seed: [],
) -> int:
    """`--parallel N` of a training script (this one, `train_ml_rl2.py`): each seed trained by
    `script` in a process of its own, N at a time, each on a GPU of its own
    (`mwjax.distributed.run_independent`), with `extra(seed)` options; then `write(runs,
    device)` writes one summary of them all, as a sequential run does, and returns its stem.
    `describe(run)` is a seed's line. Returns 0, or 1 if a seed's run failed."""
    cpu = not _gpus()
    with tempfile.TemporaryDirectory(prefix="mwjax-seeds-") as tmp:
        commands, logs = [], []
        for seed in args.seeds:
            # The last occurrence of an option wins: each child trains its one seed.
            own = ["--seeds", str(seed), "--parallel", "1", "--out", f"{tmp}/seed{seed}", *extra(seed)]
            commands.append([script, *sys.argv[1:], *own])
            logs.append(Path(tmp) / f"seed{seed}.log")
        codes = distributed.run_independent(commands, logs, args.parallel, cpu=cpu)
        done = [seed for seed, code in zip(args.seeds, codes, strict=True) if code == 0]
        children = [json.loads(Path(f"{tmp}/seed{seed}.json").read_text()) for seed in done]
        if children:
            runs = [child["runs"][0] for child in children]
            for seed, run in zip(done, runs, strict=True):
                print(f"seed {seed}: {describe(run)}", flush=True)
            stem = write(runs, children[0]["device"])
            for seed in args.seeds:  # each seed's whole output beside the summary
                log = Path(f"{tmp}/seed{seed}.log")
                if log.exists():  # not if the run was stopped before this seed started
                    log.replace(f"{stem}-seed{seed}.log")
        failed = [seed for seed in args.seeds if seed not in done]
        if failed and not children:  # no summary: the logs go with the temporary directory
            for seed in failed:
                log = Path(f"{tmp}/seed{seed}.log")
                lines = log.read_text(errors="replace").splitlines() if log.exists() else ["(never started)"]
                tail = lines[-20:]
                print(f"seed {seed} failed; its log ends:", *tail, sep="\n", file=sys.stderr, flush=True)
    if failed:
        where = f" (logs: {stem}-seed<k>.log)" if children else ""
        print(f"seeds {failed} failed{where}", flush=True)
    return 1 if failed else 0


def write_results(runs: list[dict], args: argparse.Namespace, device: str, origin: dict | None = None) -> str:
    """The runs' JSON (with the IQM and its CI over seeds) and learning-curve PNG; returns their
    path without the suffix. `origin`: what `combine_runs` found, for runs of earlier invocations."""
    default = f"train-{args.set}-ppo-{device}-{_today()}".replace(" ", "_")
    return write_summary(runs, device, args.out or str(RESULTS / default), _plot, "eval_success", origin)


def write_summary(
    runs: list[dict], device: str, stem: str, plot: Callable, score: str, origin: dict | None = None
) -> str:
    """A training script's result, `stem`.json and .png: its runs (one per seed), each run's
    `score`, and over several seeds the IQM of the per-task `score` with its 95% stratified-
    bootstrap CI (`mwjax.stats`; tasks are the strata, seeds are resampled). `origin` (from
    `combine_runs`) records the commit and commands of runs trained by earlier invocations."""
    summary: dict[str, Any] = {
        "device": device,
        "commit": origin["commit"] if origin else _commit(),
        "date": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds"),
        "command": shlex.join(["python", *sys.argv]),
        **({"combined_from": origin["sources"]} if origin else {}),
        score: [r[score] for r in runs],
        "runs": runs,
    }
    if len(runs) > 1:
        from mwjax.stats import iqm, stratified_bootstrap_ci

        scores = np.array([list(r[f"{score}_per_task"].values()) for r in runs])
        estimate = stratified_bootstrap_ci(scores)
        summary["iqm"] = iqm(scores)
        summary["iqm_ci95"] = [estimate.low, estimate.high]
        print(
            f"{len(runs)} seeds: {score} IQM {summary['iqm']:.3f} "
            f"(95% CI {estimate.low:.3f}-{estimate.high:.3f})",
            flush=True,
        )
    Path(f"{stem}.json").write_text(json.dumps(summary, indent=2))
    plotted = save_plot(plot, runs, Path(f"{stem}.png")) and save_plot(
        _plot_tasks, runs, Path(f"{stem}-tasks.png")
    )
    print(f"-> {stem}.json" + (f", {stem}.png, {stem}-tasks.png" if plotted else ""))
    return stem


def combine_runs(paths: list[Path], across_commits: bool = False) -> tuple[list[dict], str, dict]:
    """The runs saved by earlier invocations of a training script (`--out` JSONs, e.g. one seed
    per device call), gathered for one summary: (runs, device, origin). Refuses runs that differ
    in anything but their seed, a seed twice, and runs from other devices or, unless
    `across_commits` (for commits known not to change training), other commits: their IQM would
    mix recipes. The origin's commit is then every commit, joined by "+"."""
    files = [(path, json.loads(Path(path).read_text())) for path in paths]
    runs = [run for _, data in files for run in data["runs"]]
    if not runs:
        raise ValueError("no runs in " + ", ".join(map(str, paths)))

    def recipe(run: dict) -> dict:
        return {k: v for k, v in run["config"].items() if k != "seed"}

    first = recipe(runs[0])
    for run in runs[1:]:
        own = recipe(run)
        differ = sorted(k for k in own.keys() | first.keys() if own.get(k) != first.get(k))
        if differ:
            raise ValueError(f"the runs differ in {', '.join(differ)}: combine runs of one recipe only")
    seeds = [run["config"]["seed"] for run in runs]
    if len(set(seeds)) < len(seeds):
        raise ValueError(f"a seed appears twice: {seeds}")
    for key in ("device",) if across_commits else ("device", "commit"):
        values = sorted({data[key] for _, data in files})
        if len(values) > 1:
            hint = " (--across-commits if they train alike)" if key == "commit" else ""
            raise ValueError(f"the runs come from different {key}s: {', '.join(values)}{hint}")
    sources = [
        {"path": str(path), "command": data["command"], "date": data["date"], "commit": data["commit"]}
        for path, data in files
    ]
    commits = "+".join(dict.fromkeys(data["commit"] for _, data in files))
    return runs, files[0][1]["device"], {"commit": commits, "sources": sources}


def add_run_arguments(parser: argparse.ArgumentParser, minutes: float, minutes_help: str) -> None:
    """A training script's seeds, how many train at once, its budget, chunk size and result stem."""
    parser.add_argument("--seeds", type=int, nargs="+", default=[0])
    parser.add_argument(
        "--parallel",
        type=int,
        default=1,
        help="seeds trained at once, each in its own process on a GPU of its own (1: one after another)",
    )
    parser.add_argument("--minutes", type=float, default=minutes, help=minutes_help)
    parser.add_argument("--updates", type=int, default=None, help="stop after this many updates instead")
    parser.add_argument("--log-every", type=int, default=10, help="updates per jitted chunk")
    parser.add_argument(
        "--out", default=None, help="result stem (default: benchmarks/results/train/train-...)"
    )


def add_combine_argument(parser: argparse.ArgumentParser) -> None:
    """A training script's `--combine JSON...` (see `combined`)."""
    parser.add_argument(
        "--combine",
        type=Path,
        nargs="+",
        metavar="JSON",
        help="train nothing: write one summary (IQM and CI over seeds, curves) of runs saved by "
        "earlier invocations of this script, e.g. one seed per device call",
    )
    parser.add_argument(
        "--across-commits",
        action="store_true",
        help="with --combine: accept runs of different commits (say why: only ones whose changes "
        "leave training alone); the summary records every commit",
    )


def combined(
    parser: argparse.ArgumentParser, args: argparse.Namespace, write: Callable[[list[dict], str, dict], str]
) -> bool:
    """With `--combine`: `write(runs, device, origin)` for the runs of the given JSONs
    (`combine_runs`) and True, the script then trains nothing; a mismatch ends in the usage error.
    Without it, False."""
    if not args.combine:
        return False
    try:
        runs, device, origin = combine_runs(args.combine, args.across_commits)
    except (OSError, ValueError, KeyError) as error:
        parser.error(f"--combine: {error}")
    write(runs, device, origin)
    return True


def _today() -> str:
    return datetime.datetime.now(datetime.timezone.utc).date().isoformat()


if __name__ == "__main__":
    main()
