"""Meta-World+'s evaluation protocol as batched device rollouts.

- `evaluator(env, policy)` is the functional core: a jittable `(params, key) -> EvalResult` that
  runs, for every task of `env`'s set, one episode per goal variant (episode j on variant
  j mod 50), all in parallel in one `lax.scan`. An episode succeeds if the task reports success
  at any step within the horizon; it ends there (its return stops accumulating), as with the
  reference's `terminate_on_success` evaluation.
- `evaluation(agent, envs, num_episodes)` and `metalearning_evaluation(...)` take the reference's
  agent objects (`eval_action`, `reset`, and for meta-learning `init`, `adapt_action`, `step`,
  `adapt`) and an mwjax Gymnasium vector env, and return the reference's tuples.
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from typing import Any, NamedTuple, Protocol

import jax
import jax.numpy as jnp
import numpy as np

from mwjax.env import Env, State
from mwjax.physics import DROPPED
from mwjax.sharding import ShardedEnv

Array = jax.Array
Policy = Callable[[Any, Array, Array], Array]


class EvalResult(NamedTuple):
    success_rate: Array  # (tasks,)
    success: Array  # (tasks, episodes) bool
    returns: Array  # (tasks, episodes) undiscounted, up to and including the success step
    lengths: Array  # (tasks, episodes) steps until success or the horizon
    # (tasks, episodes) bool: Warp dropped a contact, constraint row or collider pair during the
    # episode (`info["physics_overflow"]`), so it left the reference's physics.
    dropped: Array


class Agent(Protocol):
    def eval_action(self, observations: np.ndarray) -> np.ndarray: ...

    def reset(self, env_mask: np.ndarray) -> None: ...


class MetaLearningAgent(Agent, Protocol):
    def init(self) -> None: ...

    def adapt_action(self, observations: np.ndarray) -> tuple[np.ndarray, dict[str, np.ndarray]]: ...

    def step(self, timestep: Timestep) -> None: ...

    def adapt(self) -> None: ...


class Timestep(NamedTuple):
    observation: np.ndarray
    action: np.ndarray
    reward: np.ndarray
    terminated: np.ndarray
    truncated: np.ndarray
    aux_policy_outputs: dict[str, np.ndarray]


def evaluation_env(env: Env | ShardedEnv, num_episodes: int = 50) -> tuple[Env | ShardedEnv, np.ndarray]:
    """`env`'s tasks, goals and reward version with `num_episodes` envs per task, for evaluation,
    and the goal variant of each of its envs (episode j of a task on variant j mod 50). A sharded
    env's evaluation env has the next multiple of its device count instead (the episodes past
    `num_episodes` run but do not count, `by_task`), on the same devices."""
    if not isinstance(num_episodes, int) or num_episodes < 1:
        raise ValueError(f"num_episodes must be a positive int, got {num_episodes!r}")
    n_devices = len(env.devices) if isinstance(env, ShardedEnv) else 1
    per_task = -(-num_episodes // n_devices) * n_devices
    eval_env = env.replace(envs_per_task=per_task, autoreset="disabled", terminate_on_success=False)
    n_variants = next(iter(eval_env.goal_variants.values())).shape[0]
    variants = np.tile(np.arange(per_task) % n_variants, len(eval_env.task_list))
    if isinstance(eval_env, ShardedEnv):
        variants = variants[eval_env.row_order]
    return eval_env, variants


def by_task(eval_env: Env | ShardedEnv, values: Any, num_episodes: int) -> Any:
    """Per-env `values` of an `evaluation_env` (rows in its order) as `(tasks, num_episodes)`."""
    if isinstance(eval_env, ShardedEnv):
        values = values[np.argsort(eval_env.row_order)]
    return values.reshape(len(eval_env.task_list), eval_env.envs_per_task)[:, :num_episodes]


def evaluator(
    env: Env | ShardedEnv, policy: Policy, num_episodes: int = 50, one_hot: bool = False
) -> Callable[[Any, Array], EvalResult]:
    """A jittable `(params, key) -> EvalResult` for `policy(params, obs, key) -> actions` on
    `env`'s task set (see the module docstring). `one_hot` appends task ids to observations."""
    eval_env, variants = evaluation_env(env, num_episodes)
    task_ids = jnp.asarray(eval_env.task_one_hot())

    def observe(obs: Array) -> Array:
        return jnp.concatenate([obs, task_ids], axis=-1) if one_hot else obs

    def run(params: Any, key: Array) -> EvalResult:
        reset_key, act_key = jax.random.split(key)
        state = eval_env.reset_with_variants(variants, reset_key)
        zeros = jnp.zeros(eval_env.num_envs)

        def step(carry: tuple, k: Array) -> tuple[tuple, None]:
            state, running, returns, lengths, success, dropped = carry
            state = eval_env.step(state, policy(params, observe(state.obs), k))
            returns = returns + jnp.where(running, state.reward, 0.0)
            lengths = lengths + running
            success = success | (running & state.info["success"])
            dropped = dropped | (running & ((state.info["physics_overflow"] & int(DROPPED)) != 0))
            running = running & ~(state.info["success"] | state.truncated)
            return (state, running, returns, lengths, success, dropped), None

        false = zeros.astype(bool)
        init = (state, jnp.ones(eval_env.num_envs, bool), zeros, zeros.astype(jnp.int32), false, false)
        keys = jax.random.split(act_key, eval_env.max_episode_steps)
        (_, _, *per_env), _ = jax.lax.scan(step, init, keys)
        returns, lengths, success, dropped = (by_task(eval_env, x, num_episodes) for x in per_env)
        return EvalResult(success.mean(axis=1), success, returns, lengths, dropped)

    return run


def evaluation(
    agent: Agent, envs: Any, num_episodes: int = 50, seed: int = 0
) -> tuple[float, float, dict[str, float], dict[str, list[float]]]:
    """The reference's `metaworld.evaluation.evaluation`, batched: for each task of `envs` (an
    mwjax Gymnasium vector env, wrapped or not), one episode per goal variant, all at once.
    `agent.eval_action` receives NumPy observations of every episode, as `envs` shapes them.
    Returns (mean success rate, mean return, success rate per task, returns per task)."""
    core = _core(envs)
    eval_env, variants = evaluation_env(core.env, num_episodes)
    one_hot = eval_env.task_one_hot() if core.use_one_hot else None
    step = jax.jit(eval_env.step)
    state = jax.jit(eval_env.reset_with_variants)(jnp.asarray(variants), jax.random.key(seed))
    agent.reset(np.ones(eval_env.num_envs, bool))
    # Only the first `num_episodes` of each task count (a sharded env may run a few more).
    running = np.zeros(eval_env.num_envs, bool)
    running[by_task(eval_env, np.arange(eval_env.num_envs), num_episodes).ravel()] = True
    returns = np.zeros(eval_env.num_envs)
    success = np.zeros(eval_env.num_envs, bool)
    for _ in range(eval_env.max_episode_steps):
        obs = np.asarray(state.obs)
        actions = agent.eval_action(obs if one_hot is None else np.concatenate([obs, one_hot], axis=1))
        state = step(state, jnp.asarray(np.clip(actions, -1.0, 1.0), jnp.float32))
        solved, truncated = np.asarray(state.info["success"]), np.asarray(state.truncated)
        returns += np.where(running, np.asarray(state.reward), 0.0)
        success |= running & solved
        ended = running & (solved | truncated)
        agent.reset(ended)
        running &= ~ended
        if not running.any():
            break
    per_task_success = by_task(eval_env, success, num_episodes).mean(axis=1)
    per_task_returns = by_task(eval_env, returns, num_episodes)
    rates = {task: float(r) for task, r in zip(eval_env.task_list, per_task_success, strict=True)}
    episodic = {task: r.tolist() for task, r in zip(eval_env.task_list, per_task_returns, strict=True)}
    return float(np.mean(per_task_success)), float(np.mean(per_task_returns)), rates, episodic


def metalearning_evaluation(
    agent: MetaLearningAgent,
    envs: Any,
    num_evals: int = 10,
    adaptation_steps: int = 1,
    adaptation_episodes: int = 10,
    evaluation_episodes: int = 3,
    seed: int = 0,
) -> tuple[float, float, dict[str, float]]:
    """The reference's `metalearning_evaluation` on an mwjax ML vector env (all its envs step in
    one device call): `num_evals` times, every env moves on to its next goal variant, the agent
    adapts for `adaptation_steps` rounds of `adaptation_episodes` episodes per env (no termination
    on success), then is evaluated on those goals until every task has `evaluation_episodes`
    episodes (ending at success). Returns (mean success rate, mean return, success per task)."""
    core = _core(envs)
    adapt_env = core.env.replace(autoreset="same_step", terminate_on_success=False)

    # Adaptation and evaluation differ only in ending episodes at success: one step program takes
    # that switch as an argument, where two envs would each compile the set's step.
    @jax.jit
    def step(state: State, action: Array, terminate: Array) -> State:
        return adapt_env.replace(terminate_on_success=terminate).step(state, action)

    adapt_step = functools.partial(step, terminate=np.bool_(False))
    eval_step = functools.partial(step, terminate=np.bool_(True))
    sample, restart = jax.jit(adapt_env.sample_goals), jax.jit(adapt_env.restart)
    observe = core.observation
    tasks = list(dict.fromkeys(adapt_env.task_names))
    task_index = np.array([tasks.index(t) for t in adapt_env.task_names])
    # Episodes that end at the same step count in the unsharded env's row order.
    order = np.argsort(adapt_env.row_order) if isinstance(adapt_env, ShardedEnv) else None

    state = jax.jit(adapt_env.reset)(jax.random.key(seed))
    rates = np.zeros((num_evals, len(tasks)))
    total_success = total_return = 0.0
    for i in range(num_evals):
        if i:
            state = sample(state)
        agent.init()
        for _ in range(adaptation_steps):
            state = restart(state)
            obs = np.asarray(observe(state.obs))
            episodes = np.zeros(adapt_env.num_envs, np.int64)
            while not (episodes >= adaptation_episodes).all():
                actions, aux = agent.adapt_action(obs)
                state = adapt_step(state, jnp.asarray(np.clip(actions, -1.0, 1.0), jnp.float32))
                terminated, truncated = np.asarray(state.terminated), np.asarray(state.truncated)
                agent.step(Timestep(obs, actions, np.asarray(state.reward), terminated, truncated, aux))
                episodes += terminated | truncated
                obs = np.asarray(observe(state.obs))
            agent.adapt()
        state = restart(state)
        success, returns = _episodes_in_place(
            agent, eval_step, observe, state, task_index, evaluation_episodes, order
        )
        rates[i] = success
        total_success += float(np.mean(success))
        total_return += float(np.mean(returns))
    per_task = rates.mean(axis=0)
    return (
        total_success / num_evals,
        total_return / num_evals,
        dict(zip(tasks, per_task.tolist(), strict=True)),
    )


def _episodes_in_place(
    agent: Agent,
    step: Callable[[State, Array], State],
    observe: Callable[[Array], Array],
    state: State,
    task_index: np.ndarray,
    num_episodes: int,
    order: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """The reference's `evaluation` loop on the envs as they are: step until every task has
    `num_episodes` finished episodes; the first `num_episodes` of each task (in finishing order,
    ties by env index, or by position in `order`) count. Returns per-task success rates and mean
    returns."""
    order = np.arange(len(task_index)) if order is None else order
    n_tasks = int(task_index.max()) + 1
    successes, returns = np.zeros(n_tasks), [[] for _ in range(n_tasks)]
    obs = np.asarray(observe(state.obs))
    agent.reset(np.ones(len(task_index), bool))
    while min(len(r) for r in returns) < num_episodes:
        state = step(state, jnp.asarray(np.clip(agent.eval_action(obs), -1.0, 1.0), jnp.float32))
        done = np.asarray(state.terminated | state.truncated)
        agent.reset(done)
        episode_return = np.asarray(state.info["episode_return"])
        solved = np.asarray(state.info["success"])
        for i in order[done[order]]:
            t = task_index[i]
            returns[t].append(float(episode_return[i]))
            if len(returns[t]) <= num_episodes:
                successes[t] += float(solved[i])
        obs = np.asarray(observe(state.obs))
    return successes / num_episodes, np.array([np.mean(r[:num_episodes]) for r in returns])


def _core(envs: Any) -> Any:
    """The `MwjaxVectorEnv` under Gymnasium wrappers."""
    core = getattr(envs, "unwrapped", envs)
    if not hasattr(core, "env") or not isinstance(core.env, (Env, ShardedEnv)):
        raise TypeError(f"expected an mwjax Gymnasium vector env, got {type(envs).__name__}")
    return core
