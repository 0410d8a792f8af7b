"""The functional core: every task of a set in one batched state, one jitted `reset` and `step`.

The batch is laid out task by task (`envs_per_task` rows each), tasks that share a scene next to
each other so that the physics seam (`mwjax.physics`) can run one batch per scene. Task code runs
vmapped over each task's rows; nothing here knows what a task does. The concerns around the
batch live in their own modules: the config (`mwjax.config`), goal draws (`mwjax.goals`), the
arm's action and observation layout (`mwjax.sawyer`), and reset placement (`mwjax.placement`).
"""

from __future__ import annotations

import copy
import dataclasses
import functools
from collections.abc import Callable, Mapping, Sequence
from typing import TYPE_CHECKING, Any

import jax
import jax.numpy as jnp
import numpy as np

from mwjax import benchmarks, goals, placement
from mwjax.batching import cond_any
from mwjax.config import EnvConfig
from mwjax.contracts import Frame, Kinematics, Placement, StepInputs
from mwjax.observation import Observation
from mwjax.physics import Physics, PhysicsConfig, PhysicsState
from mwjax.placement import Settled, TaskRows, select_rows
from mwjax.sawyer import Sawyer, check_action, frame_obs
from mwjax.tasks import get_task
from mwjax.tasks.spec import TaskSpec

if TYPE_CHECKING:
    from mwjax.sharding import ShardedEnv

Array = jax.Array

# The float info terms every V2 kernel reports besides `success`.
_REWARD_INFO = ("near_object", "grasp_reward", "in_place_reward", "obj_to_target", "unscaled_reward")


@jax.tree_util.register_dataclass
@dataclasses.dataclass(frozen=True)
class State:
    """The whole batch. Per-env arrays have a leading axis of `env.num_envs`."""

    physics: tuple[PhysicsState, ...]
    obs: Array
    reward: Array
    terminated: Array
    truncated: Array
    info: dict[str, Array]
    steps: Array
    episode_return: Array
    target_pos: Array
    constants: dict[str, Array]
    # Each env's goal variants in the order it visits them, and where it is in that order.
    goal_order: Array
    goal_cursor: Array
    key: Array

    @property
    def variant(self) -> Array:
        """The goal variant (index into `env.goal_variants[task]`) of every env's episode."""
        return jnp.take_along_axis(self.goal_order, self.goal_cursor[:, None], axis=1)[:, 0]


def staggered(state: State, max_episode_steps: int, key: Array) -> State:
    """`state` with every env's episode counter at a random point of 0..max_episode_steps-1, so
    that a window of steps shorter than an episode sees resets at their long-run rate (the
    benchmarks' `--stagger`, the main job's throughput). The counters keep the sharding of the
    ones they replace, so a program compiled for a sharded state accepts them."""
    offsets = jax.random.randint(key, state.steps.shape, 0, max_episode_steps)
    offsets = jax.device_put(offsets.astype(state.steps.dtype), state.steps.sharding)
    return dataclasses.replace(state, steps=offsets)


def _placed_as_one(method: Callable[..., State]) -> Callable[..., State]:
    """Called eagerly (outside a trace), a method's state comes back partly committed to the
    device (the arrays the Warp calls make) and partly not; `jax.jit` compiles once per such mix,
    so a jitted `step` fed an eagerly reset state would compile twice (once more for its own,
    all-committed output). Eagerly, the whole state is put on that device; traced, unchanged."""

    @functools.wraps(method)
    def call(self: Env, *args: Any, **kwargs: Any) -> State:
        state = method(self, *args, **kwargs)
        if isinstance(state.obs, jax.core.Tracer):
            return state
        return jax.device_put(state, state.obs.sharding)

    return call


class Env:
    """A batched Meta-World task set. Build it with `mwjax.make` (or from an `EnvConfig`)."""

    # Config fields read only when `step` and `observe` are traced: `replace` changing these alone
    # shares the built physics, task rows and goals, which are most of `make`'s time.
    _TRACE_TIME_FIELDS = frozenset(
        {"reward_version", "max_episode_steps", "autoreset", "terminate_on_success"}
    )

    def __init__(self, config: EnvConfig) -> None:
        self._configure(config)
        bench = benchmarks.benchmark(config.tasks, config.task)
        variants = goals.set_variants(config, bench)
        n_variants = goals.variant_count(config, variants)
        self.benchmark = bench
        self.split = config.split
        self.partially_observable = (
            bench.meta_learning if config.partially_observable is None else config.partially_observable
        )
        self.goal_sampling = config.goal_sampling or ("on_request" if bench.meta_learning else "on_reset")
        self.envs_per_task = envs_per_task = config.envs_per_task

        groups = placement.scene_groups([get_task(name) for name in bench.tasks(config.split)])
        self.physics = Physics(
            [
                (
                    members[0].scene,
                    placement.mocap_bodies(members),
                    len(members) * envs_per_task,
                )
                for members in groups
            ],
            config.physics or PhysicsConfig(),
        )
        rows = placement.task_rows(self.physics, groups, envs_per_task)
        self._rows = tuple(placement.with_settled_variants(self.physics, rows, variants, n_variants))
        self.task_list = tuple(r.spec.name for r in rows)
        self.num_envs = len(rows) * envs_per_task
        self.task_names = tuple(name for name in self.task_list for _ in range(envs_per_task))
        self.task_ids = np.repeat(np.arange(len(rows)), envs_per_task)
        self.goal_variants = {name: variants[name][:n_variants] for name in self.task_list}
        self.goals = goals.GoalDraws.build(
            variants, self.task_list, self.task_ids, self.goal_sampling, envs_per_task, n_variants
        )
        self.sawyer = Sawyer.of([r.spec for r in rows], envs_per_task, self.partially_observable)
        # Each task's frame observation, jitted: traced once per batch shape, then reused by the
        # reset, the step and the step's autoreset (and lowered once per program).
        self._frame_obs = tuple(
            _jitted_frame_obs(r.spec, self.physics.groups[r.group].model) for r in self._rows
        )

    def _configure(self, config: EnvConfig) -> None:
        """The trace-time settings (`_TRACE_TIME_FIELDS`) from `config`."""
        self.config = config
        self.reward_version = config.reward_version
        self.max_episode_steps = config.max_episode_steps
        self.autoreset = config.autoreset
        self.terminate_on_success = config.terminate_on_success

    # ----------------------------------------------------------------------------------------
    # Public functional API

    @_placed_as_one
    def reset(self, key: Array) -> State:
        """A fresh episode in every env, each from its own key. With `goal_sampling="on_reset"`
        (MT sets) every env draws one of its task's goal variants; with `"on_request"` (ML sets)
        every env shuffles its own share of them and starts on the first."""
        keys = self._row_keys(key)
        order, keys = self.goals.shuffled_pools(keys)
        cursor = jnp.zeros(self.num_envs, jnp.int32)
        if self.goal_sampling == "on_reset":
            cursor, keys = self.goals.draw_cursor(keys)
        return self._start(order, cursor, keys)

    @_placed_as_one
    def reset_with_variants(self, variants: Array, key: Array | None = None) -> State:
        """A fresh episode in every env on the given goal variants (`(num_envs,)` indices into
        `env.goal_variants[task]`), e.g. one episode per variant for evaluation."""
        variants = jnp.asarray(variants, jnp.int32)
        if variants.shape != (self.num_envs,):
            raise ValueError(f"variants must have shape ({self.num_envs},), got {variants.shape}")
        if not isinstance(variants, jax.core.Tracer):
            n = self.goals.count
            concrete = np.asarray(variants)
            if not np.all((concrete >= 0) & (concrete < n)):
                raise ValueError(f"variants must lie in [0, {n})")
        keys = self._row_keys(jax.random.key(0) if key is None else key)
        order = jnp.broadcast_to(
            jnp.arange(self.goals.count, dtype=jnp.int32), (self.num_envs, self.goals.count)
        )
        return self._start(order, variants, keys)

    @_placed_as_one
    def sample_goals(self, state: State) -> State:
        """Every env moves on to its next goal variant and starts a fresh episode (the reference's
        `sample_tasks` of ML envs: each env cycles through its own share of the variants in a
        shuffled order, reshuffling when it has used them all). With `goal_sampling="on_reset"`
        every env draws a new variant, as at any reset."""
        if self.goal_sampling == "on_reset":
            cursor, keys = self.goals.draw_cursor(state.key)
            return self._start(state.goal_order, cursor, keys)
        cursor = state.goal_cursor + 1
        wrapped = cursor >= self.goals.pool_sizes
        reshuffled, keys = self.goals.shuffled_pools(state.key)
        order = select_rows(wrapped, reshuffled, state.goal_order)
        return self._start(order, jnp.where(wrapped, 0, cursor), keys)

    @_placed_as_one
    def reset_to(self, rand_vecs: Array, key: Array | None = None) -> State:
        """A fresh episode in every env with the given goal variants (`(num_envs, d)`, the
        reference's `rand_vec`, zero-padded to the widest task of the set)."""
        rand_vecs = jnp.asarray(rand_vecs, jnp.float32)
        if rand_vecs.shape != (self.num_envs, self.goals.width):
            raise ValueError(
                f"rand_vecs must have shape {(self.num_envs, self.goals.width)}, got {rand_vecs.shape}"
            )
        keys = self._row_keys(jax.random.key(0) if key is None else key)
        order, keys = self.goals.shuffled_pools(keys)
        cursor = jnp.zeros(self.num_envs, jnp.int32)
        all_rows = jnp.ones(self.num_envs, bool)
        return self._reset_rows(self.physics.make_data(), rand_vecs, None, order, cursor, keys, all_rows)

    def replace(self, **changes: Any) -> Env | ShardedEnv:
        """The same env with some config fields changed (a new, separately compiled env);
        `devices=` splits it over devices, as `make`'s. Changing only the reward version, episode
        length, autoreset or termination reuses this env's built physics and goals."""
        devices = changes.pop("devices", None)
        config = dataclasses.replace(self.config, **changes)
        if devices is None and changes.keys() <= self._TRACE_TIME_FIELDS:
            env = copy.copy(self)
            env._configure(config)
            return env
        if devices is None:
            return Env(config)
        from mwjax.sharding import ShardedEnv

        return ShardedEnv(devices, config)

    @_placed_as_one
    def restart(self, state: State, mask: Array | None = None) -> State:
        """Fresh episodes in the rows where `mask` (all by default), as an autoreset starts them:
        a new goal variant with `goal_sampling="on_reset"`, the same one with `"on_request"`."""
        mask = jnp.ones(self.num_envs, bool) if mask is None else jnp.asarray(mask, bool)
        return self._restart(state, mask)

    def observation_bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """The reference's observation box (hand box, gripper [-1, 1], unbounded objects, goal
        box or zeros when hidden), widened over the set's tasks, whose goal boxes differ."""
        return self.sawyer.observation_bounds()

    def task_one_hot(self) -> np.ndarray:
        """Each env's task id as a one-hot row, `(num_envs, tasks)`: the reference's `use_one_hot`."""
        return np.eye(len(self.task_list), dtype=np.float32)[self.task_ids]

    def task_rows(self, task: str) -> slice:
        """The rows of `task` in the env batch."""
        return self._task(task).rows

    def kinematics(self, state: State, task: str) -> Kinematics:
        """qpos, qvel and the body/site/geom poses of `task`'s rows (its scene's ids)."""
        rows = self._task(task)
        return Kinematics.of(state.physics[rows.group]).rows(rows.local_start, rows.local_start + rows.size)

    def settled_kinematics(self, task: str) -> Kinematics:
        """`task`'s recorded settled state, one env's: hand at its start, objects where the
        recorded reset left them (what resets place objects into, `mwjax.placement`)."""
        return self._task(task).settled.kin

    def with_physics_state(self, state: State, physics: Mapping[str, Mapping[str, Array]]) -> State:
        """`state` with the dynamic physics state of some tasks' rows replaced (e.g. by recorded
        reference states): `{task: {"qpos", "qvel", "mocap_pos", "mocap_quat"}}`, the mocap
        entries being the hand's. Kinematics are recomputed; use `observe` for obs and rewards."""
        datas = list(state.physics)
        for task, fields in physics.items():
            rows = self._task(task)
            local = rows.local_rows
            data = datas[rows.group]
            datas[rows.group] = data.replace(
                qpos=data.qpos.at[local].set(jnp.asarray(fields["qpos"], jnp.float32)),
                qvel=data.qvel.at[local].set(jnp.asarray(fields["qvel"], jnp.float32)),
                mocap_pos=data.mocap_pos.at[local, 0].set(jnp.asarray(fields["mocap_pos"], jnp.float32)),
                mocap_quat=data.mocap_quat.at[local, 0].set(jnp.asarray(fields["mocap_quat"], jnp.float32)),
            )
        return dataclasses.replace(state, physics=self.physics.kinematics(tuple(datas)))

    def observe(self, state: State, action: Array) -> State:
        """Observation, reward and success of the current physics state, as the reference computes
        them after a step with `action`; `state.obs`'s frame is taken as the previous one."""
        obs, reward, info, constants = self._observe_and_reward(
            self._kinematics(state.physics), state, action
        )
        info["invalid_action"] = state.info["invalid_action"]
        info["physics_overflow"] = state.info["physics_overflow"]
        info["physics_reset"] = state.info["physics_reset"]
        return dataclasses.replace(state, obs=obs, reward=reward, info=info, constants=constants)

    @_placed_as_one
    def step(self, state: State, action: Array) -> State:
        """One env step for the whole batch (5 physics steps), with rewards and autoreset.

        `action`: `(num_envs, 4)` floats in [-1, 1] (an array, or nested lists). Besides the task's
        reward terms and `success`, `state.info` holds per env: `episode_return` and
        `episode_length` (the episode's return and steps so far, including this step; at an
        autoreset, the finished episode's), `invalid_action` (this step's action had NaN or inf
        and was replaced by zeros), `physics_overflow` (Warp's `OverflowType` flags of this step),
        `physics_reset` (the physics diverged in this step and was reset to the model's defaults,
        as MuJoCo C's automatic reset does; `PhysicsInstabilityWarning`) and `final_obs` (the last
        observation of an episode that ended at this step)."""
        action = check_action(action, self.num_envs)
        valid = jnp.all(jnp.isfinite(action), axis=-1)
        action = jnp.where(valid[:, None], action, 0.0)

        datas = self.physics.step(self.apply_action(state.physics, action))
        kin = self._kinematics(datas)
        obs, reward, info, constants = self._observe_and_reward(kin, state, action)
        info["invalid_action"] = ~valid
        info["physics_overflow"] = self.physics.overflow(datas)
        info["physics_reset"] = self.physics.resets(datas)
        steps = state.steps + 1
        episode_return = state.episode_return + reward
        info["episode_return"] = episode_return
        info["episode_length"] = steps
        truncated = steps >= self.max_episode_steps
        # `terminate_on_success` may also be a traced bool (`replace` inside a jitted function):
        # one program then steps both ways (`mwjax.evaluation.metalearning_evaluation`).
        terminated = info["success"] & self.terminate_on_success
        stepped = dataclasses.replace(
            state,
            physics=datas,
            obs=obs,
            reward=reward,
            terminated=terminated,
            truncated=truncated,
            info=info,
            steps=steps,
            episode_return=episode_return,
            constants=constants,
        )
        done = terminated | truncated
        if self.autoreset == "same_step":
            return cond_any(done, self._autoreset, self._with_final, stepped)
        stepped = self._with_final(stepped, done)
        if self.autoreset == "disabled":
            return stepped
        # NEXT_STEP: an env whose episode ended at the previous call starts a new one instead.
        ended = state.terminated | state.truncated
        return cond_any(ended, self._restart, lambda s, _: s, stepped)

    def _row_keys(self, key: Array) -> Array:
        """One key per env, split from a reset's key (a sharded env's part on one device,
        `mwjax.sharding`, takes its rows of the whole batch's split instead)."""
        return jax.random.split(key, self.num_envs)

    def apply_action(self, datas: tuple[PhysicsState, ...], action: Array) -> tuple[PhysicsState, ...]:
        """The physics states with `action` written in (the hand's mocap target, the fingers'
        controls), as `step` does before stepping them (`mwjax.sawyer`)."""
        return self.sawyer.apply_action(self.physics.groups, datas, action)

    def _task(self, task: str) -> TaskRows:
        for rows in self._rows:
            if rows.spec.name == task:
                return rows
        raise ValueError(f"{task!r} is not in this env's tasks {self.task_list}")

    # ----------------------------------------------------------------------------------------
    # Reset

    def _start(self, order: Array, cursor: Array, keys: Array) -> State:
        variant, rand_vecs = self.goals.at(order, cursor)
        all_rows = jnp.ones(self.num_envs, bool)
        return self._reset_rows(self.physics.make_data(), rand_vecs, variant, order, cursor, keys, all_rows)

    def _reset_rows(
        self,
        datas: tuple[PhysicsState, ...],
        rand_vecs: Array,
        variant: Array | None,
        goal_order: Array,
        goal_cursor: Array,
        keys: Array,
        done: Array,
    ) -> State:
        """Fresh episodes in the rows where `done`; the other rows' physics is kept as is. Rows
        reset to goal variants `variant` (indices) when given, else to the vectors `rand_vecs`."""
        placements: list[Placement] = []
        settled: list[Settled] = []
        new_datas = list(datas)
        for g in range(len(self.physics.groups)):
            new_datas[g], group_placements, group_settled = placement.reset_group(
                self.physics, self._rows, g, datas[g], rand_vecs, variant, done
            )
            placements.extend(group_placements)
            settled.extend(group_settled)
        datas = self.physics.kinematics(tuple(new_datas))
        kin = self._kinematics(datas)

        curr_parts, target_parts, constant_parts = [], [], []
        parts = zip(self._rows, placements, settled, self._frame_obs, strict=True)
        for rows, placed, rows_settled, rows_obs in parts:
            frames = kin[rows.group].rows(rows.local_start, rows.local_start + rows.size)
            model = self.physics.groups[rows.group].model

            def one(
                k: Kinematics,
                p: Placement,
                s: Kinematics,
                rows: TaskRows = rows,
                model: Any = model,
                obs_fn: Callable[[Kinematics], Array] = rows_obs,
            ) -> tuple[Array, dict[str, Array]]:
                frame = Frame(model, k)
                return obs_fn(k), rows.spec.constants(frame, p, Frame(model, s))

            curr, constants = jax.vmap(one)(frames, placed, rows_settled.kin)
            curr_parts.append(curr)
            # A goal read off the placed scene (e.g. a site on a moved fixture) overrides `place`'s.
            target_parts.append(constants.pop("target_pos", placed.target_pos))
            constant_parts.append(constants)
        curr = jnp.concatenate(curr_parts)
        target = jnp.concatenate(target_parts).astype(jnp.float32)
        obs = self.sawyer.observation(curr, curr, target)
        zeros = jnp.zeros(self.num_envs, jnp.float32)
        info = {name: zeros for name in _REWARD_INFO}
        info["success"] = jnp.zeros(self.num_envs, bool)
        info["invalid_action"] = jnp.zeros(self.num_envs, bool)
        info["physics_overflow"] = jnp.zeros(self.num_envs, jnp.int32)
        info["physics_reset"] = jnp.zeros(self.num_envs, bool)
        info["episode_return"] = zeros
        info["episode_length"] = jnp.zeros(self.num_envs, jnp.int32)
        info["final_obs"] = obs
        return State(
            physics=datas,
            obs=obs,
            reward=zeros,
            terminated=jnp.zeros(self.num_envs, bool),
            truncated=jnp.zeros(self.num_envs, bool),
            info=info,
            steps=jnp.zeros(self.num_envs, jnp.int32),
            episode_return=zeros,
            target_pos=target,
            constants=_merge_constants(constant_parts, [r.size for r in self._rows]),
            goal_order=goal_order,
            goal_cursor=goal_cursor,
            key=keys,
        )

    def _fresh(self, state: State, done: Array) -> State:
        """New episodes in the `done` rows (a new goal variant if `goal_sampling="on_reset"`)."""
        cursor, keys = state.goal_cursor, state.key
        if self.goal_sampling == "on_reset":
            cursor, keys = self.goals.draw_cursor(keys)
        variant, rand_vecs = self.goals.at(state.goal_order, cursor)
        return self._reset_rows(state.physics, rand_vecs, variant, state.goal_order, cursor, keys, done)

    def _autoreset(self, state: State, done: Array) -> State:
        """SAME_STEP: the `done` rows carry the next episode's start, their step's reward, flags
        and info stay (they are the finished episode's final info), `final_obs` its last obs."""
        fresh = self._fresh(state, done)
        final = self._with_final(state, done)
        pick = functools.partial(select_rows, done)
        return dataclasses.replace(
            final,
            physics=fresh.physics,
            obs=pick(fresh.obs, state.obs),
            steps=jnp.where(done, 0, state.steps),
            episode_return=jnp.where(done, 0.0, state.episode_return),
            target_pos=pick(fresh.target_pos, state.target_pos),
            constants=jax.tree.map(pick, fresh.constants, state.constants),
            goal_cursor=pick(fresh.goal_cursor, state.goal_cursor),
            key=pick(fresh.key, state.key),
        )

    def _restart(self, state: State, ended: Array) -> State:
        """NEXT_STEP: the `ended` rows are replaced by a fresh episode's start, as `reset` returns it."""
        fresh = self._fresh(state, ended)
        pick = functools.partial(select_rows, ended)
        # The physics is per scene group (and `fresh` already has it); the rest is per env.
        rows = jax.tree.map(
            pick, dataclasses.replace(fresh, physics=()), dataclasses.replace(state, physics=())
        )
        return dataclasses.replace(rows, physics=fresh.physics)

    @staticmethod
    def _with_final(state: State, done: Array) -> State:
        """Autoreset keeps the finished episode's last observation in `info["final_obs"]`."""
        info = dict(state.info)
        info["final_obs"] = state.obs
        return dataclasses.replace(state, info=info)

    # ----------------------------------------------------------------------------------------
    # Step

    def _kinematics(self, datas: tuple[PhysicsState, ...]) -> tuple[Kinematics, ...]:
        return tuple(Kinematics.of(d) for d in datas)

    def _observe_and_reward(
        self, kin: tuple[Kinematics, ...], state: State, action: Array
    ) -> tuple[Array, Array, dict[str, Array], dict[str, Array]]:
        """Obs, reward and info after a step, and the constants with first-step latches applied."""
        curr_parts = []
        for rows, obs_fn in zip(self._rows, self._frame_obs, strict=True):
            frames = kin[rows.group].rows(rows.local_start, rows.local_start + rows.size)
            curr_parts.append(jax.vmap(obs_fn)(frames))
        curr = jnp.concatenate(curr_parts)
        obs = self.sawyer.clip(self.sawyer.observation(curr, Observation(state.obs).frame, state.target_pos))

        first_step = state.steps == 0
        rewards, infos, constant_parts = [], [], []
        for rows in self._rows:
            model = self.physics.groups[rows.group].model
            frames = kin[rows.group].rows(rows.local_start, rows.local_start + rows.size)
            sl = slice(rows.start, rows.start + rows.size)
            constants = {k: v[sl] for k, v in state.constants.items()}

            def one(
                k: Kinematics,
                o: Array,
                a: Array,
                t: Array,
                c: dict[str, Array],
                first: Array,
                m: Any = model,
                spec: TaskSpec = rows.spec,
            ) -> tuple[Array, dict[str, Array], dict[str, Array]]:
                step = StepInputs(frame=Frame(m, k), obs=Observation(o), action=a, target_pos=t, constants=c)
                if spec.latch is not None:
                    latched = {name: jnp.where(first, v, c[name]) for name, v in spec.latch(step).items()}
                    c = {**c, **latched}
                    step = dataclasses.replace(step, constants=c)
                reward_fn = spec.reward_v1 if self.reward_version == "v1" else spec.reward_v2
                return (*reward_fn(step), c)

            reward, info, constants = jax.vmap(one)(
                frames, obs[sl], action[sl], state.target_pos[sl], constants, first_step[sl]
            )
            rewards.append(reward)
            infos.append(info)
            constant_parts.append(constants)
        info = {k: jnp.concatenate([i[k] for i in infos]) for k in infos[0]}
        info["success"] = info["success"] > 0
        constants = {k: jnp.concatenate([c[k] for c in constant_parts]) for k in state.constants}
        return obs, jnp.concatenate(rewards).astype(jnp.float32), info, constants


def _jitted_frame_obs(spec: TaskSpec, model: Any) -> Callable[[Kinematics], Array]:
    """One env's frame observation (`frame_obs`) from its kinematics, jitted (a plain function:
    JAX would name a partial by printing what it holds)."""

    def frame_observation(k: Kinematics) -> Array:
        return frame_obs(spec, Frame(model, k))

    return jax.jit(frame_observation)


def _merge_constants(parts: list[dict[str, Array]], sizes: list[int]) -> dict[str, Array]:
    """Per-task constant dicts -> one dict over the batch, zeros where a task has no such key."""
    shapes: dict[str, tuple[int, ...]] = {}
    for part in parts:
        for key, value in part.items():
            shapes.setdefault(key, value.shape[1:])
    merged = {}
    for key, shape in shapes.items():
        merged[key] = jnp.concatenate(
            [
                part[key].astype(jnp.float32) if key in part else jnp.zeros((n, *shape), jnp.float32)
                for part, n in zip(parts, sizes, strict=True)
            ]
        )
    return merged


def make(
    tasks: str | Sequence[str],
    envs_per_task: int | None = None,
    seed: int = 0,
    reward_version: str = "v2",
    num_envs: int | None = None,
    devices: Sequence[jax.Device] | None = None,
    **kwargs: Any,
) -> Env | ShardedEnv:
    """`mwjax.make("MT10", envs_per_task=256, seed=42)`: a batched task set (see `Env`).

    `tasks` is a set name ("MT10", "ML45", "MT1"/"ML1" with `task=`, ...; see
    `mwjax.benchmarks.benchmark`), a list of task names or a `Benchmark`; `split` picks an ML
    set's "train" or "test" tasks. Give the batch either per task (`envs_per_task`, default 1) or
    in total (`num_envs`, a multiple of the task count). The other keywords are `EnvConfig`'s.
    `devices` (e.g. `jax.devices()`) splits
    the batch over them, an equal share of every task on each (`mwjax.sharding.ShardedEnv`).
    """
    if num_envs is not None:
        if envs_per_task is not None:
            raise ValueError("give envs_per_task or num_envs, not both")
        n_tasks = len(benchmarks.task_names(tasks, kwargs.get("split", "train"), kwargs.get("task")))
        if not isinstance(num_envs, int) or num_envs < n_tasks or num_envs % n_tasks:
            raise ValueError(f"num_envs={num_envs!r} is not a positive multiple of the {n_tasks} tasks")
        envs_per_task = num_envs // n_tasks
    envs_per_task = 1 if envs_per_task is None else envs_per_task
    config = EnvConfig(tasks, envs_per_task=envs_per_task, seed=seed, reward_version=reward_version, **kwargs)
    if devices is not None:
        from mwjax.sharding import ShardedEnv

        return ShardedEnv(devices, config)
    return Env(config)
