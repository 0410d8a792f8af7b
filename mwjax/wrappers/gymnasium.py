"""Gymnasium adapters over the functional core: a `VectorEnv` for the whole batch and single
`Env`s for MT1 and the reference's goal_observable / goal_hidden envs. The ids are registered by
`mwjax.wrappers.registration`, whose entry points call `registered_vector`, `vector_as_env`,
`MwjaxEnv` and `GoalEnv` here.

The vector env speaks JAX arrays (on device); `make_vector` wraps it in `NumpyVectorEnv` (the
default), in Gymnasium's `JaxToTorch`, or returns it bare (`array_type="jax"`).
"""

from __future__ import annotations

import dataclasses
import importlib.util
from collections.abc import Sequence
from typing import Any

import gymnasium as gym
import jax
import jax.numpy as jnp
import numpy as np
from gymnasium.vector import AutoresetMode

from mwjax import benchmarks, determinism, rendering, warp_graphs
from mwjax.config import MAX_EPISODE_STEPS, EnvConfig
from mwjax.env import Env, State, make
from mwjax.physics import PhysicsConfig, local_device, runs_scenes_together
from mwjax.sharding import ShardedEnv

Array = jax.Array
_AUTORESET = {AutoresetMode.SAME_STEP: "same_step", AutoresetMode.NEXT_STEP: "next_step"}
_TASK_SELECT = {"random": "on_reset", "pseudorandom": "on_request"}
_ARRAY_TYPES = ("numpy", "jax", "torch")
# Options of the reference's envs that mwjax does not implement, at their defaults there: a call
# may pass them at these values (code written for the reference does); any other value is refused.
_UNSUPPORTED = {
    "recurrent_info_in_obs": False,
    "normalize_reward_in_recurrent_info": True,
    "reward_normalization_method": None,
    "normalize_observations": False,
    "reward_alpha": 0.001,
}
# The rendering kwargs (the reference's, plus `render_envs` for a batch): `mwjax.rendering`.
_RENDER_OPTIONS = ("render_mode", "render_envs", "camera_name", "camera_id", "width", "height")
_INSTEAD = {
    "reward_normalization_method": "wrap the env in gymnasium.wrappers.vector.NormalizeReward",
    "reward_alpha": "wrap the env in gymnasium.wrappers.vector.NormalizeReward",
    "normalize_observations": "wrap the env in gymnasium.wrappers.vector.NormalizeObservation",
}


def _refuse_unsupported(options: dict[str, Any]) -> None:
    for name, value in options.items():
        if name not in _UNSUPPORTED:
            raise TypeError(f"got an unexpected keyword argument {name!r}")
        default = _UNSUPPORTED[name]
        if value != default:
            instead = f"; {_INSTEAD[name]}" if name in _INSTEAD else ""
            raise NotImplementedError(
                f"mwjax does not implement the reference's {name}={value!r} (only its default, "
                f"{default!r}){instead}"
            )


def _adapter_physics(physics: PhysicsConfig | None, devices: Sequence[jax.Device] | None) -> PhysicsConfig:
    """The adapter's physics: on one GPU, where Warp's graph mode is left to MJX, Warp's staged
    mode, with the scenes side by side unless the caller chose (`concurrent_scenes`, or
    `MWJAX_CONCURRENT_SCENES=0`). Stepped from Python, the adapter's calls get new buffers each
    time, so MJX's default mode captures a new CUDA graph at every call and never replays one; the
    staged mode captures each call once, against fixed staging buffers, and replays it (1.6x the
    env steps/s at 131,070 MT10 envs, with bounded memory); side by side, with the scenes'
    staged calls copying only the live state, 1.8x the scenes in turn at 131,070 MT10 envs and
    2.0x at 409,600 MT50 envs (first steps from reset; docs/performance.md). Not on the CPU
    (Warp has no graphs there), over several devices (one graph per traced call would serve them
    all) or in the deterministic mode (which launches kernels one by one to check their record
    buffers)."""
    config = physics or PhysicsConfig()
    if config.graph_mode is not None or determinism.enabled() or (devices is not None and len(devices) != 1):
        return config
    device = local_device() if devices is None else devices[0]
    if device.platform != "gpu":
        return config
    # Side by side or in turn as the jitted step's default picks on this GPU (the caller's
    # setting, else MWJAX_CONCURRENT_SCENES), which the staged mode would otherwise turn off.
    together = runs_scenes_together(dataclasses.replace(config, graph_mode=None), device.platform)
    return dataclasses.replace(config, graph_mode="warp_staged_ex", concurrent_scenes=together)


def _seed_key(seed: Any) -> Array:
    """The key of a `reset(seed=...)`: Gymnasium's seeds are non-negative ints."""
    if not isinstance(seed, (int, np.integer)) or isinstance(seed, bool) or seed < 0:
        raise ValueError(f"seed must be a non-negative int, got {seed!r}")
    return jax.random.key(int(seed))


def _check_actions_dtype(dtype: Any) -> None:
    if not np.issubdtype(dtype, np.floating):
        raise ValueError(f"actions must be floating point (the action space is float32), got dtype {dtype}")


class MwjaxVectorEnv(gym.vector.VectorEnv):
    """A Gymnasium `VectorEnv` over an `mwjax.Env` (one jitted call per step for all envs).

    Observations, rewards and flags are JAX arrays. `info` holds the core's per-step values
    (`success`, `near_object`, ... each with its `_key` mask); with SAME_STEP autoreset an
    episode's last observation and info are under `final_obs` / `final_info` (masks
    `_final_obs` / `_final_info`), with NEXT_STEP they are the step's own. `final_info` and, for
    NEXT_STEP, `info` carry `episode: {"r": return, "l": length}` where an episode ended.
    """

    def __init__(
        self,
        env: Env | ShardedEnv,
        use_one_hot: bool = False,
        num_tasks: int | None = None,
        render_mode: str | None = None,
        render_envs: Sequence[int] | str | None = None,
        camera_name: str | None = None,
        camera_id: int | None = None,
        width: int = rendering.DEFAULT_SIZE,
        height: int = rendering.DEFAULT_SIZE,
    ) -> None:
        """`num_tasks` widens the one-hot task ids (the reference's `num_tasks`; default: the
        set's task count). `render_mode` "rgb_array" / "depth_array" makes `render()` return a
        tuple of NumPy images of the `render_envs` (default: the first env of each task; "all":
        every env, which Gymnasium's vector `RecordVideo` needs), with the reference's
        `camera_name` / `camera_id` / `width` / `height` (`mwjax.rendering`)."""
        if env.autoreset not in _AUTORESET.values():
            raise ValueError("the Gymnasium adapter needs autoreset 'same_step' or 'next_step'")
        self.env = env
        self.num_envs = env.num_envs
        self.use_one_hot = use_one_hot
        self.task_names = env.task_names
        self.metadata = {
            "autoreset_mode": next(m for m, v in _AUTORESET.items() if v == env.autoreset),
            "render_modes": list(rendering.RENDER_MODES),
            "render_fps": rendering.RENDER_FPS,
        }
        if render_mode is None:
            render_envs = ()
        elif render_envs is None:
            render_envs = [np.arange(env.num_envs)[env.task_rows(task)][0] for task in env.task_list]
        elif isinstance(render_envs, str):
            if render_envs != "all":
                raise ValueError(f"render_envs must be a list of env indices or 'all', got {render_envs!r}")
            render_envs = range(env.num_envs)
        self.render_mode = render_mode
        self._frames = rendering.GymFrames(
            env, render_mode, render_envs, camera_name, camera_id, width, height
        )
        low, high = env.observation_bounds()
        n_tasks = _one_hot_width(num_tasks, len(env.task_list))
        one_hot = env.task_one_hot()
        self._one_hot = jnp.asarray(np.pad(one_hot, ((0, 0), (0, n_tasks - one_hot.shape[1]))))
        if use_one_hot:
            low = np.concatenate([low, np.zeros(n_tasks, np.float32)])
            high = np.concatenate([high, np.ones(n_tasks, np.float32)])
        self.single_observation_space = gym.spaces.Box(low, high, dtype=np.float32)
        self.single_action_space = gym.spaces.Box(-1.0, 1.0, (4,), dtype=np.float32)
        self.observation_space = gym.vector.utils.batch_space(self.single_observation_space, self.num_envs)
        self.action_space = gym.vector.utils.batch_space(self.single_action_space, self.num_envs)
        # Called step by step from Python, these programs get new temporary buffers at every
        # call, so in Warp's "warp" graph mode (a caller's choice; `_adapter_physics`) they
        # capture their calls' CUDA graphs anew each time; keeping one graph per call site
        # (`mwjax.warp_graphs`) instead of Warp's up to 32, each with its collider scratch, is
        # what lets 100k+ envs fit there. The staged mode replays one graph per call and needs
        # no bound. The old state is donated (`state` is always the current one).
        self._reset = warp_graphs.stepped_from_python(jax.jit(env.reset))
        self._step = warp_graphs.stepped_from_python(jax.jit(env.step, donate_argnums=0))
        self._sample_goals = warp_graphs.stepped_from_python(jax.jit(env.sample_goals))
        self._key = jax.random.key(0)
        self._state: State | None = None

    @property
    def state(self) -> State:
        """The core state (for code that wants to leave the adapter)."""
        if self._state is None:
            raise RuntimeError("call reset() first")
        return self._state

    @state.setter
    def state(self, state: State) -> None:
        """Continue from `state`, a core state of this env's batch (a saved one, or one changed
        with `mwjax.env.staggered`, say). The next step donates it, as it does the adapter's own."""
        if not isinstance(state, State) or state.obs.shape[:1] != (self.num_envs,):
            raise ValueError(f"state must be a mwjax State of this env's {self.num_envs} envs")
        self._state = state

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None) -> tuple[Array, dict]:
        if options:
            raise ValueError(f"mwjax's vector env takes no reset options, got {sorted(options)}")
        if seed is not None:
            self._key = _seed_key(seed)
            self.action_space.seed(seed)
        self._key, key = jax.random.split(self._key)
        self._state = self._reset(key)
        return self.observation(self._state.obs), {}

    def sample_tasks(self) -> tuple[Array, dict]:
        """Every env moves on to its next goal variant and restarts (the reference's ML `sample_tasks`)."""
        self._state = self._sample_goals(self.state)
        return self.observation(self._state.obs), {}

    def step(self, actions: Any) -> tuple[Array, Array, Array, Array, dict]:
        # Host actions are checked on the host; device arrays on the device, which waits for
        # the steps already queued there.
        xp = jnp if isinstance(actions, jax.Array) else np
        actions = xp.asarray(actions)
        _check_actions_dtype(actions.dtype)
        actions = actions.astype(np.float32)
        if actions.shape != (self.num_envs, 4):
            raise ValueError(f"actions must have shape ({self.num_envs}, 4), got {actions.shape}")
        if not bool(xp.all(xp.isfinite(actions))):
            raise ValueError("actions contain NaN or inf")
        self._state = state = self._step(self.state, jnp.asarray(actions))
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
                final_obs=self.observation(state.info["final_obs"]),
                _final_obs=done,
                final_info=final_info,
                _final_info=done,
            )
        else:
            info = _masked(values, jnp.ones_like(done))
            info.update(episode=_masked(episode, done), _episode=done)
        return self.observation(state.obs), state.reward, state.terminated, state.truncated, info

    def render(self) -> tuple[np.ndarray, ...] | None:
        frames = self._frames(self._state)
        return None if frames is None else tuple(frames)

    def observation(self, obs: Array) -> Array:
        """This env's observations of core observations `(num_envs, 39)` (e.g. `state.obs`): with
        `use_one_hot`, each env's task one-hot appended."""
        return jnp.concatenate([obs, self._one_hot], axis=-1) if self.use_one_hot else obs


@jax.jit
def _take_rows(values: Array, rows: Array) -> Array:
    return values[rows]


def _with_rows_of(device: Array, host: np.ndarray, rows: np.ndarray) -> np.ndarray:
    """A copy of `host` with `rows` copied from `device`. The row indices are padded to a power
    of two, so that the gather compiles for a few sizes, not for every number of rows."""
    out = host.copy()
    if rows.size:
        padded = np.pad(rows, (0, (1 << (rows.size - 1).bit_length()) - rows.size), mode="edge")
        out[rows] = np.asarray(_take_rows(device, jnp.asarray(padded)))[: rows.size]
    return out


def _masked(values: dict[str, Array], mask: Array) -> dict[str, Array]:
    out: dict[str, Array] = {}
    for key, value in values.items():
        out[key] = value
        out["_" + key] = mask
    return out


class _SingleEnv(gym.Env):
    """One env of one task over a one-env core, NumPy in and out. `info` holds the core's
    per-step values for the env (`success`, ..., `episode_return`, `episode_length`,
    `invalid_action`, `physics_overflow`, `physics_reset`)."""

    metadata = {"render_modes": list(rendering.RENDER_MODES), "render_fps": rendering.RENDER_FPS}

    def _setup(self, core: Env, key: Array, one_hot: np.ndarray, **render: Any) -> None:
        """`render`: `render_mode`, `camera_name`, `camera_id`, `width`, `height` (`mwjax.rendering`)."""
        low, high = core.observation_bounds()
        self.env = core
        self.task_name = core.task_list[0]
        self.observation_space = gym.spaces.Box(
            np.concatenate([low, np.zeros_like(one_hot)]),
            np.concatenate([high, np.ones_like(one_hot)]),
            dtype=np.float32,
        )
        self.action_space = gym.spaces.Box(-1.0, 1.0, (4,), dtype=np.float32)
        self._one_hot = one_hot
        self._reset = warp_graphs.stepped_from_python(jax.jit(core.reset))  # as in MwjaxVectorEnv
        self._step = warp_graphs.stepped_from_python(jax.jit(core.step, donate_argnums=0))
        self._key = key
        self._state: State | None = None
        self.render_mode = render.get("render_mode")
        self._frames = rendering.GymFrames(
            core,
            self.render_mode,
            [0],
            render.get("camera_name"),
            render.get("camera_id"),
            render.get("width", rendering.DEFAULT_SIZE),
            render.get("height", rendering.DEFAULT_SIZE),
        )

    def render(self) -> np.ndarray | None:
        """The reference's `render()`: an `(H, W, 3)` uint8 image, or `(H, W)` depth buffer."""
        frames = self._frames(self._state)
        return None if frames is None else frames[0]

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[np.ndarray, dict]:
        super().reset(seed=seed)
        if seed is not None:
            self._key = _seed_key(seed)
        self._key, key = jax.random.split(self._key)
        self._state = self._reset(key)
        return self._obs(), {}

    def step(self, action: Any) -> tuple[np.ndarray, float, bool, bool, dict]:
        if self._state is None:
            raise RuntimeError("call reset() first")
        action = np.asarray(action)
        _check_actions_dtype(action.dtype)
        action = action.astype(np.float32)
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


class MwjaxEnv(_SingleEnv):
    """One env of one task (`gym.make("mwjax/MT1", env_name=...)`), like the reference's MT1 env:
    a random goal variant per reset, truncation at `max_episode_steps`."""

    def __init__(
        self,
        env_name: str,
        seed: int | None = None,
        reward_function_version: str = "v2",
        max_episode_steps: int | None = MAX_EPISODE_STEPS,
        terminate_on_success: bool = False,
        use_one_hot: bool = False,
        num_tasks: int | None = None,
        env_id: int | None = None,
        task_select: str = "random",
        vector_strategy: str | None = None,
        autoreset_mode: Any = None,
        num_envs: int | None = None,
        num_goals: int | None = None,
        **reference_options: Any,
    ) -> None:
        """The reference's MT1 kwargs. `vector_strategy`, `autoreset_mode` and `num_envs` mean
        nothing for one env and are ignored, as there."""
        del vector_strategy, autoreset_mode, num_envs
        render = {k: reference_options.pop(k) for k in _RENDER_OPTIONS if k in reference_options}
        if "render_envs" in render:
            raise TypeError("render_envs is for a vector env; one env renders itself")
        _refuse_unsupported(reference_options)
        if task_select != "random":
            raise NotImplementedError(
                f"the single MT1 env draws a goal variant at every reset (task_select='random'); for "
                f"task_select={task_select!r} use gym.make_vec('mwjax/MT1', env_name=..., task_select=...)"
            )
        num_tasks = 1 if num_tasks is None else num_tasks
        env_id = 0 if env_id is None else env_id
        if use_one_hot and not (isinstance(env_id, int) and 0 <= env_id < num_tasks):
            raise ValueError(f"env_id must lie in [0, num_tasks={num_tasks}), got {env_id}")
        seed_value = 0 if seed is None else seed
        goals = _sampled_goals(benchmarks.benchmark("MT1", env_name), "train", seed_value, num_goals)
        core = Env(
            EnvConfig(
                "MT1",
                envs_per_task=1,
                seed=seed_value,
                task=env_name,
                reward_version=reward_function_version,
                max_episode_steps=MAX_EPISODE_STEPS if max_episode_steps is None else max_episode_steps,
                terminate_on_success=terminate_on_success,
                autoreset="disabled",
                goal_variants=goals,
                physics=_adapter_physics(None, None),
            )
        )
        one_hot = np.eye(num_tasks, dtype=np.float32)[env_id] if use_one_hot else np.zeros(0, np.float32)
        self._setup(core, jax.random.key(seed_value), one_hot, **render)


class GoalEnv(_SingleEnv):
    """`gym.make("mwjax/goal_observable" | "mwjax/goal_hidden", env_name=..., seed=...)`: one env
    of one task on one goal, like the reference's `ALL_V3_ENVIRONMENTS_GOAL_OBSERVABLE` /
    `_GOAL_HIDDEN` classes. Their constructor seeds numpy's global RNG with `seed` and resets
    once, which draws the goal (`rand_vec`) and freezes it: every reset starts that same goal.
    The goal is drawn here the same way (`benchmarks.sample_goal_variants`, one variant), so a
    seed gives the reference's goal; `seed=None` draws a fresh one. goal_hidden zeroes the goal
    in observations (and its observation space), as the reference's `partially_observable`.
    Episodes are truncated at 500 steps, the reference env's own `max_path_length`."""

    def __init__(self, hidden: bool, env_name: str, seed: int | None = None) -> None:
        task = env_name.removesuffix("-goal-hidden" if hidden else "-goal-observable")
        if seed is None:
            seed = int(np.random.SeedSequence().generate_state(1)[0])
        rand_vec = benchmarks.sample_goal_variants([task], seed, n_goals=1)
        core = Env(
            EnvConfig(
                "MT1",
                envs_per_task=1,
                seed=seed,
                task=task,
                partially_observable=hidden,
                autoreset="disabled",
                goal_variants=rand_vec,
                physics=_adapter_physics(None, None),
            )
        )
        self.goal = rand_vec[task][0]
        self._setup(core, jax.random.key(seed), np.zeros(0, np.float32))


def _one_hot_width(num_tasks: int | None, n_tasks: int) -> int:
    if num_tasks is None:
        return n_tasks
    if not isinstance(num_tasks, int) or isinstance(num_tasks, bool) or num_tasks < n_tasks:
        raise ValueError(
            f"num_tasks (one-hot size) must be an int >= {n_tasks} (the tasks), got {num_tasks!r}"
        )
    return num_tasks


def _positive_int(name: str, value: Any) -> int:
    if not isinstance(value, int) or isinstance(value, bool) or value < 1:
        raise ValueError(f"{name} must be a positive int, got {value!r}")
    return value


def _sampled_goals(
    bench: benchmarks.Benchmark, split: str, seed: int, num_goals: int | None
) -> dict[str, np.ndarray] | None:
    """The reference's `num_goals` (goal variants sampled per task, 50 by default; it changes the
    draw sequence, so the variants are sampled again with that count), or None for the default."""
    if num_goals is None:
        return None
    if bench.meta_learning:
        raise ValueError("num_goals is for MT sets (the reference's ML envs do not take it)")
    return benchmarks.sample_goal_variants(bench.tasks(split), seed, _positive_int("num_goals", num_goals))


def _batch_size(
    bench: benchmarks.Benchmark,
    n_tasks: int,
    num_envs: int | None,
    envs_per_task: int | None,
    meta_batch_size: int | None,
) -> int:
    """The whole batch. `num_envs` is the total (a multiple of the task count); 1 or None mean
    the default, because `gym.make_vec` passes `num_envs=1` when the caller gives none."""
    if num_envs is not None:
        _positive_int("num_envs (the total batch, a multiple of the task count)", num_envs)
    given = None if num_envs in (None, 1) else num_envs
    if bench.meta_learning:
        if envs_per_task is not None:
            raise ValueError("ML sets take meta_batch_size (or num_envs), not envs_per_task")
        if meta_batch_size is not None:
            _positive_int("meta_batch_size", meta_batch_size)
            if given not in (None, meta_batch_size):
                raise ValueError(f"num_envs={num_envs} and meta_batch_size={meta_batch_size} disagree")
        total = meta_batch_size or given
        if total is None:
            total = 20 if 20 % n_tasks == 0 else n_tasks
    else:
        if meta_batch_size is not None:
            raise ValueError("meta_batch_size is for ML sets; MT sets take num_envs or envs_per_task")
        if envs_per_task is not None:
            _positive_int("envs_per_task", envs_per_task)
            if given is not None:
                raise ValueError("give envs_per_task or num_envs, not both")
            return n_tasks * envs_per_task
        total = given or n_tasks
    if total % n_tasks:
        raise ValueError(f"the batch ({total}) must be a positive multiple of the split's {n_tasks} tasks")
    return total


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
    max_episode_steps: int | None = MAX_EPISODE_STEPS,
    autoreset_mode: AutoresetMode | str = AutoresetMode.SAME_STEP,
    task_select: str | None = None,
    array_type: str = "numpy",
    vector_strategy: str | None = None,
    num_goals: int | None = None,
    num_tasks: int | None = None,
    env_id: int | None = None,
    devices: Sequence[jax.Device] | None = None,
    physics: PhysicsConfig | None = None,
    **reference_options: Any,
) -> gym.vector.VectorEnv:
    """The Gymnasium vector env of a task set split, with the reference's kwargs.

    Batch size: MT sets take `envs_per_task` (default 1, the reference's one env per task) or
    `num_envs`, the total batch (a positive multiple of the task count; 1, what
    `gym.make_vec` passes by default, means one env per task); ML sets take `meta_batch_size` (or
    `num_envs`), default 20 where 20 is a multiple of the split's task count, else one env per
    task. `vector_strategy` ("sync" or "async") is accepted for compatibility and ignored: the
    whole batch is one device call. `num_goals` (MT sets) and `num_tasks` (the one-hot width) are
    the reference's, and so are its rendering kwargs (plus `render_envs`: which envs `render()`
    shows; `MwjaxVectorEnv`); its normalization and recurrent-info options are accepted at their
    defaults only. `max_episode_steps=None` means the reference's 500. `array_type="torch"` needs
    PyTorch (the `torch` extra). `devices` splits the batch over them (`mwjax.make`'s): rows are
    then laid out device by device (`env.row_order`; `task_names` and the one-hot ids follow).
    `physics` is `mwjax.make`'s (buffer sizes, solver iterations, Warp's graph mode); on one GPU
    the adapter's graph mode, unless given, is Warp's staged mode (`_adapter_physics`).
    """
    if vector_strategy not in (None, "sync", "async"):
        raise ValueError(f"vector_strategy must be 'sync' or 'async', got {vector_strategy!r}")
    if devices is not None and any(d.process_index != jax.process_index() for d in devices):
        raise ValueError(
            "the Gymnasium adapter returns host arrays of its whole batch, so its devices must be "
            "this process's: in a run of several processes (mwjax.distributed) give each process "
            "its own envs with devices=jax.local_devices() (or none)"
        )
    if env_id is not None:
        raise ValueError("env_id is for one env (gym.make of mwjax/MT1); a set gives each env its task's id")
    render = {k: reference_options.pop(k) for k in _RENDER_OPTIONS if k in reference_options}
    _refuse_unsupported(reference_options)
    if array_type not in _ARRAY_TYPES:
        raise ValueError(f"array_type must be one of {_ARRAY_TYPES}, got {array_type!r}")
    if array_type == "torch" and importlib.util.find_spec("torch") is None:
        raise ModuleNotFoundError(
            'array_type="torch" needs PyTorch, which mwjax does not install by default: '
            'pip install "mwjax[torch]" (or any torch build for your machine)'
        )
    bench = benchmarks.benchmark(benchmark, task)
    n_tasks = len(bench.tasks(split))
    total = _batch_size(bench, n_tasks, num_envs, envs_per_task, meta_batch_size)
    mode = AutoresetMode(autoreset_mode) if isinstance(autoreset_mode, str) else autoreset_mode
    if mode not in _AUTORESET:
        raise ValueError(f"autoreset_mode must be SAME_STEP or NEXT_STEP, got {autoreset_mode!r}")
    if task_select is not None and task_select not in _TASK_SELECT:
        raise ValueError(f"task_select must be 'random' or 'pseudorandom', got {task_select!r}")
    if terminate_on_success is None:
        # The reference's ML test envs terminate on success, its train and MT envs do not.
        terminate_on_success = bench.meta_learning and split == "test"
    seed = 0 if seed is None else seed
    env = make(
        bench,
        envs_per_task=total // n_tasks,
        devices=devices,
        physics=_adapter_physics(physics, devices),
        seed=seed,
        split=split,
        reward_version=reward_function_version,
        max_episode_steps=MAX_EPISODE_STEPS if max_episode_steps is None else max_episode_steps,
        autoreset=_AUTORESET[mode],
        terminate_on_success=terminate_on_success,
        goal_sampling=None if task_select is None else _TASK_SELECT[task_select],
        variants_per_task=total_tasks_per_cls,
        goal_variants=_sampled_goals(bench, split, seed, num_goals),
    )
    vector = MwjaxVectorEnv(env, use_one_hot=use_one_hot, num_tasks=num_tasks, **render)
    if array_type == "jax":
        return vector
    if array_type == "numpy":
        return NumpyVectorEnv(vector)
    return gym.wrappers.vector.JaxToTorch(vector)


def registered_vector(
    set_name: str,
    split: str = "train",
    *,
    env_name: str | None = None,
    envs_list: Sequence[str] | None = None,
    env_names: Sequence[str] | None = None,
    train_envs: Sequence[str] | None = None,
    test_envs: Sequence[str] | None = None,
    **kwargs: Any,
) -> gym.vector.VectorEnv:
    """The vector entry point of every registered set id. `set_name` (and an ML id's `split`) come
    from the registration; the task-naming kwargs are the reference's: `env_name` for MT1/ML1,
    `envs_list` (or the paper's `env_names`) for a custom MT set, `train_envs` and `test_envs`
    for a custom ML set. The rest goes to `make_vector`."""
    naming = {
        "env_name": env_name,
        "envs_list": envs_list,
        "env_names": env_names,
        "train_envs": train_envs,
        "test_envs": test_envs,
    }
    wanted = {
        "MT1": {"env_name"},
        "ML1": {"env_name"},
        "custom-mt": {"envs_list", "env_names"},
        "custom-ml": {"train_envs", "test_envs"},
    }.get(set_name, set())
    given = {name for name, value in naming.items() if value is not None}
    if given - wanted:
        raise TypeError(f"{set_name} does not take {', '.join(sorted(given - wanted))}")
    if set_name in ("MT1", "ML1"):
        if env_name is None:
            raise TypeError(f"{set_name} needs env_name=<task name>")
        return make_vector(set_name, split=split, task=env_name, **kwargs)
    if set_name == "custom-mt":
        if len(given) != 1:
            raise TypeError("a custom MT set needs its tasks as envs_list=[...] (or env_names=[...])")
        return make_vector(benchmarks.custom_mt(envs_list or env_names or ()), split=split, **kwargs)
    if set_name == "custom-ml":
        if train_envs is None or test_envs is None:
            raise TypeError("a custom ML set needs train_envs=[...] and test_envs=[...]")
        return make_vector(benchmarks.custom_ml(train_envs, test_envs), split=split, **kwargs)
    return make_vector(set_name, split=split, **kwargs)


class VectorAsEnv(gym.vector.VectorWrapper, gym.Env):
    """What `gym.make` gives for a task set: the vector env, unchanged, also typed as a
    `gymnasium.Env`. The Meta-World+ paper writes `gym.make("Meta-World/MT10",
    vector_strategy="sync", seed=42)`, and `gym.make` refuses anything that is not a
    `gymnasium.Env`. Its API is the vector env's (batched actions, `num_envs`, `single_*_space`);
    `gym.make`'s own `max_episode_steps` adds a single-env `TimeLimit`, so give the episode length
    to `gym.make_vec` instead."""


def vector_as_env(*bound: Any, **kwargs: Any) -> VectorAsEnv:
    """The `gym.make` entry point of every registered set id (see `registered_vector`)."""
    return VectorAsEnv(registered_vector(*bound, **kwargs))


class NumpyVectorEnv(gym.vector.VectorWrapper):
    """NumPy actions in, NumPy results out, with one device-to-host copy of each step's outputs
    (and one of the finished envs' `final_obs` rows).
    Gymnasium's `JaxToNumpy` converts through DLPack, which fails on the GPU for arrays that
    MJX-Warp's FFI calls produce ("JaxCallableGraphMode.WARP is not supported for JAX CPU FFI
    calls", H200, 2026-11-21); `jax.device_get` copies them fine.

    `info["final_obs"]` differs from the step's observation only in the envs whose episode ended
    (elsewhere both are the current observation, `Env._with_final`), so only those rows of it
    are copied and the rest is the observation's host copy: some 40% less to copy per step."""

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None) -> tuple[Any, dict]:
        return jax.device_get(self.env.reset(seed=seed, options=options))

    def step(self, actions: Any) -> tuple[Any, Any, Any, Any, dict]:
        obs, reward, terminated, truncated, info = self.env.step(actions)
        final_obs = info.pop("final_obs", None)
        obs, reward, terminated, truncated, info = jax.device_get((obs, reward, terminated, truncated, info))
        if final_obs is not None:
            info["final_obs"] = _with_rows_of(final_obs, obs, np.flatnonzero(info["_final_obs"]))
        return obs, reward, terminated, truncated, info

    def sample_tasks(self) -> tuple[Any, dict]:
        return jax.device_get(self.env.sample_tasks())
