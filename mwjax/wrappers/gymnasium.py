"""Gymnasium adapters over the functional core: a `VectorEnv` for the whole batch and a single
`Env` for MT1, registered under the reference's ids with an `mwjax/` prefix.

The vector env speaks JAX arrays (on device); `make_vector` wraps it in `NumpyVectorEnv` (the
default), in Gymnasium's `JaxToTorch`, or returns it bare (`array_type="jax"`).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import gymnasium as gym
import jax
import jax.numpy as jnp
import numpy as np
from gymnasium.vector import AutoresetMode

from mwjax import benchmarks
from mwjax.env import Env, State, make
from mwjax.sharding import ShardedEnv

Array = jax.Array
_AUTORESET = {AutoresetMode.SAME_STEP: "same_step", AutoresetMode.NEXT_STEP: "next_step"}
_TASK_SELECT = {"random": "on_reset", "pseudorandom": "on_request"}


class MwjaxVectorEnv(gym.vector.VectorEnv):
    """A Gymnasium `VectorEnv` over an `mwjax.Env` (one jitted call per step for all envs).

    Observations, rewards and flags are JAX arrays. `info` holds the core's per-step values
    (`success`, `near_object`, ... each with its `_key` mask); with SAME_STEP autoreset an
    episode's last observation and info are under `final_obs` / `final_info` (masks
    `_final_obs` / `_final_info`), with NEXT_STEP they are the step's own. `final_info` and, for
    NEXT_STEP, `info` carry `episode: {"r": return, "l": length}` where an episode ended.
    """

    def __init__(self, env: Env | ShardedEnv, use_one_hot: bool = False) -> None:
        if env.autoreset not in _AUTORESET.values():
            raise ValueError("the Gymnasium adapter needs autoreset 'same_step' or 'next_step'")
        self.env = env
        self.num_envs = env.num_envs
        self.use_one_hot = use_one_hot
        self.task_names = env.task_names
        self.metadata = {
            "autoreset_mode": next(m for m, v in _AUTORESET.items() if v == env.autoreset),
            "render_modes": [],
        }
        low, high = env.observation_bounds()
        n_tasks = len(env.task_list)
        self._one_hot = jnp.asarray(env.task_one_hot())
        if use_one_hot:
            low = np.concatenate([low, np.zeros(n_tasks, np.float32)])
            high = np.concatenate([high, np.ones(n_tasks, np.float32)])
        self.single_observation_space = gym.spaces.Box(low, high, dtype=np.float32)
        self.single_action_space = gym.spaces.Box(-1.0, 1.0, (4,), dtype=np.float32)
        self.observation_space = gym.vector.utils.batch_space(self.single_observation_space, self.num_envs)
        self.action_space = gym.vector.utils.batch_space(self.single_action_space, self.num_envs)
        self._reset = jax.jit(env.reset)
        # The old state is donated: each step's state reuses its buffers, so on a GPU Warp sees
        # the same addresses every step and replays one captured CUDA graph instead of capturing
        # (and keeping alive) a new one per buffer set. `state` is always the current one.
        self._step = jax.jit(env.step, donate_argnums=0)
        self._sample_goals = jax.jit(env.sample_goals)
        self._key = jax.random.key(0)
        self._state: State | None = None

    @property
    def state(self) -> State:
        """The core state (for code that wants to leave the adapter)."""
        if self._state is None:
            raise RuntimeError("call reset() first")
        return self._state

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None) -> tuple[Array, dict]:
        if options:
            raise ValueError(f"mwjax's vector env takes no reset options, got {sorted(options)}")
        if seed is not None:
            self._key = jax.random.key(seed)
            self.action_space.seed(seed)
        self._key, key = jax.random.split(self._key)
        self._state = self._reset(key)
        return self._obs(self._state.obs), {}

    def sample_tasks(self) -> tuple[Array, dict]:
        """Every env moves on to its next goal variant and restarts (the reference's ML `sample_tasks`)."""
        self._state = self._sample_goals(self.state)
        return self._obs(self._state.obs), {}

    def step(self, actions: Any) -> tuple[Array, Array, Array, Array, dict]:
        actions = jnp.asarray(actions, jnp.float32)
        if actions.shape != (self.num_envs, 4):
            raise ValueError(f"actions must have shape ({self.num_envs}, 4), got {actions.shape}")
        if not bool(jnp.all(jnp.isfinite(actions))):
            raise ValueError("actions contain NaN or inf")
        self._state = state = self._step(self.state, actions)
        done = state.terminated | state.truncated
        values = {
            k: v for k, v in state.info.items() if k not in ("final_obs", "episode_return", "episode_length")
        }
        episode = {"r": state.info["episode_return"], "l": state.info["episode_length"]}
        if self.env.autoreset == "same_step":
            final_info = _masked(values, done)
            final_info["episode"] = _masked(episode, done)
            final_info["_episode"] = done
            info = _masked(values, ~done)
            info.update(
                final_obs=self._obs(state.info["final_obs"]),
                _final_obs=done,
                final_info=final_info,
                _final_info=done,
            )
        else:
            info = _masked(values, jnp.ones_like(done))
            info.update(episode=_masked(episode, done), _episode=done)
        return self._obs(state.obs), state.reward, state.terminated, state.truncated, info

    def _obs(self, obs: Array) -> Array:
        return jnp.concatenate([obs, self._one_hot], axis=-1) if self.use_one_hot else obs


def _masked(values: dict[str, Array], mask: Array) -> dict[str, Array]:
    out: dict[str, Array] = {}
    for key, value in values.items():
        out[key] = value
        out["_" + key] = mask
    return out


class MwjaxEnv(gym.Env):
    """One env of one task (`gym.make("mwjax/MT1", env_name=...)`), NumPy in and out, like the
    reference's MT1 env: a random goal variant per reset, truncation at `max_episode_steps`."""

    metadata = {"render_modes": []}

    def __init__(
        self,
        env_name: str,
        seed: int | None = None,
        reward_function_version: str = "v2",
        max_episode_steps: int = 500,
        terminate_on_success: bool = False,
        use_one_hot: bool = False,
        num_tasks: int = 1,
        env_id: int = 0,
    ) -> None:
        self.env = Env(
            "MT1",
            envs_per_task=1,
            seed=0 if seed is None else seed,
            task=env_name,
            reward_version=reward_function_version,
            max_episode_steps=max_episode_steps,
            terminate_on_success=terminate_on_success,
            autoreset="disabled",
        )
        low, high = self.env.observation_bounds()
        if use_one_hot:
            if not 0 <= env_id < num_tasks:
                raise ValueError(f"env_id must lie in [0, num_tasks={num_tasks}), got {env_id}")
            low = np.concatenate([low, np.zeros(num_tasks, np.float32)])
            high = np.concatenate([high, np.ones(num_tasks, np.float32)])
        self._one_hot = (
            np.eye(num_tasks, dtype=np.float32)[env_id] if use_one_hot else np.zeros(0, np.float32)
        )
        self.observation_space = gym.spaces.Box(low, high, dtype=np.float32)
        self.action_space = gym.spaces.Box(-1.0, 1.0, (4,), dtype=np.float32)
        self.task_name = env_name
        self._reset = jax.jit(self.env.reset)
        self._step = jax.jit(self.env.step, donate_argnums=0)  # as in MwjaxVectorEnv
        self._key = jax.random.key(0 if seed is None else seed)
        self._state: State | None = None

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[np.ndarray, dict]:
        super().reset(seed=seed)
        if seed is not None:
            self._key = jax.random.key(seed)
        self._key, key = jax.random.split(self._key)
        self._state = self._reset(key)
        return self._obs(), {}

    def step(self, action: Any) -> tuple[np.ndarray, float, bool, bool, dict]:
        if self._state is None:
            raise RuntimeError("call reset() first")
        action = np.asarray(action, np.float32)
        if action.shape != (4,):
            raise ValueError(f"action must have shape (4,), got {action.shape}")
        if not np.all(np.isfinite(action)):
            raise ValueError("action contains NaN or inf")
        self._state = state = self._step(self._state, jnp.asarray(action[None]))
        info = {k: np.asarray(v[0]).item() for k, v in state.info.items() if k != "final_obs"}
        return self._obs(), float(state.reward[0]), bool(state.terminated[0]), bool(state.truncated[0]), info

    def _obs(self) -> np.ndarray:
        assert self._state is not None
        return np.concatenate([np.asarray(self._state.obs[0]), self._one_hot])


def make_vector(
    benchmark: str | Sequence[str] | benchmarks.Benchmark,
    split: str = "train",
    task: str | None = None,
    seed: int | None = None,
    num_envs: int | None = None,
    envs_per_task: int | None = None,
    meta_batch_size: int | None = None,
    total_tasks_per_cls: int | None = None,
    reward_function_version: str = "v2",
    use_one_hot: bool = False,
    terminate_on_success: bool | None = None,
    max_episode_steps: int = 500,
    autoreset_mode: AutoresetMode | str = AutoresetMode.SAME_STEP,
    task_select: str | None = None,
    array_type: str = "numpy",
    vector_strategy: str | None = None,
    devices: Sequence[jax.Device] | None = None,
) -> gym.vector.VectorEnv:
    """The Gymnasium vector env of a task set split, with the reference's kwargs.

    Batch size: MT sets take `envs_per_task` (default 1, the reference's one env per task) or
    `num_envs` (a multiple of the task count); ML sets take `meta_batch_size` (or `num_envs`),
    default 20 where 20 is a multiple of the split's task count, else one env per task.
    `vector_strategy` is accepted for compatibility and ignored: the whole batch is one device call.
    `devices` splits the batch over them (`mwjax.make`'s): rows are then laid out device by device
    (`env.row_order`; `task_names` and the one-hot ids follow).
    """
    del vector_strategy
    bench = benchmarks.benchmark(benchmark, task)
    n_tasks = len(bench.tasks(split))
    if bench.meta_learning:
        if envs_per_task is not None:
            raise ValueError("ML sets take meta_batch_size (or num_envs), not envs_per_task")
        if meta_batch_size is not None and num_envs not in (None, 1, meta_batch_size):
            raise ValueError(f"num_envs={num_envs} and meta_batch_size={meta_batch_size} disagree")
        total = meta_batch_size or (num_envs if num_envs not in (None, 1) else None)
        if total is None:
            total = 20 if 20 % n_tasks == 0 else n_tasks
    else:
        if meta_batch_size is not None:
            raise ValueError("meta_batch_size is for ML sets; MT sets take num_envs or envs_per_task")
        if envs_per_task is not None and num_envs not in (None, 1):
            raise ValueError("give envs_per_task or num_envs, not both")
        total = n_tasks * envs_per_task if envs_per_task is not None else (num_envs or 1)
        if total == 1:
            total = n_tasks
    if not isinstance(total, int) or total < n_tasks or total % n_tasks:
        raise ValueError(f"the batch ({total}) must be a positive multiple of the split's {n_tasks} tasks")
    mode = AutoresetMode(autoreset_mode) if isinstance(autoreset_mode, str) else autoreset_mode
    if mode not in _AUTORESET:
        raise ValueError(f"autoreset_mode must be SAME_STEP or NEXT_STEP, got {autoreset_mode!r}")
    if task_select is not None and task_select not in _TASK_SELECT:
        raise ValueError(f"task_select must be 'random' or 'pseudorandom', got {task_select!r}")
    if terminate_on_success is None:
        # The reference's ML test envs terminate on success, its train and MT envs do not.
        terminate_on_success = bench.meta_learning and split == "test"
    env = make(
        bench,
        envs_per_task=total // n_tasks,
        devices=devices,
        seed=0 if seed is None else seed,
        split=split,
        reward_version=reward_function_version,
        max_episode_steps=max_episode_steps,
        autoreset=_AUTORESET[mode],
        terminate_on_success=terminate_on_success,
        goal_sampling=None if task_select is None else _TASK_SELECT[task_select],
        variants_per_task=total_tasks_per_cls,
    )
    vector = MwjaxVectorEnv(env, use_one_hot=use_one_hot)
    if array_type == "jax":
        return vector
    if array_type == "numpy":
        return NumpyVectorEnv(vector)
    if array_type == "torch":
        return gym.wrappers.vector.JaxToTorch(vector)
    raise ValueError(f"array_type must be 'numpy', 'jax' or 'torch', got {array_type!r}")


class NumpyVectorEnv(gym.vector.VectorWrapper):
    """NumPy actions in, NumPy results out, with one device-to-host copy of each step's outputs.
    Gymnasium's `JaxToNumpy` converts through DLPack, which fails on the GPU for arrays that
    MJX-Warp's FFI calls produce ("JaxCallableGraphMode.WARP is not supported for JAX CPU FFI
    calls", H200, 2026-11-21); `jax.device_get` copies them fine."""

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None) -> tuple[Any, dict]:
        return jax.device_get(self.env.reset(seed=seed, options=options))

    def step(self, actions: Any) -> tuple[Any, Any, Any, Any, dict]:
        return jax.device_get(self.env.step(jnp.asarray(actions)))

    def sample_tasks(self) -> tuple[Any, dict]:
        return jax.device_get(self.env.sample_tasks())


def register_envs() -> None:
    """Registers the `mwjax/...` ids, mirroring the reference's `Meta-World/...` ones."""
    if "mwjax/MT10" in gym.registry:
        return

    def vector(benchmark: str, split: str = "train") -> Any:
        return lambda **kwargs: make_vector(benchmark, split=split, **kwargs)

    gym.register(
        "mwjax/MT1",
        entry_point=MwjaxEnv,
        vector_entry_point=lambda env_name, **kwargs: make_vector("MT1", task=env_name, **kwargs),
    )
    for name in ("MT10", "MT25", "MT50"):
        gym.register(f"mwjax/{name}", vector_entry_point=vector(name))
    for split in ("train", "test"):
        gym.register(
            f"mwjax/ML1-{split}",
            vector_entry_point=lambda env_name, split=split, **kwargs: make_vector(
                "ML1", task=env_name, split=split, **kwargs
            ),
        )
        for name in ("ML10", "ML25", "ML45"):
            gym.register(f"mwjax/{name}-{split}", vector_entry_point=vector(name, split))
    gym.register(
        "mwjax/custom-mt-envs",
        vector_entry_point=lambda envs_list, **kwargs: make_vector(benchmarks.custom_mt(envs_list), **kwargs),
    )
    gym.register(
        "mwjax/custom-ml-envs",
        vector_entry_point=lambda train_envs, test_envs, split="train", **kwargs: make_vector(
            benchmarks.custom_ml(train_envs, test_envs), split=split, **kwargs
        ),
    )
