"""The functional core: every task of a set in one batched state, one jitted `reset` and `step`.

The batch is laid out task by task (`envs_per_task` rows each), tasks that share a scene next to
each other so that the physics seam (`mwjax.physics`) can run one batch per scene. Task code runs
vmapped over each task's rows; nothing here knows what a task does.
"""

from __future__ import annotations

import dataclasses
import functools
from collections.abc import Mapping, Sequence
from importlib import resources
from typing import TYPE_CHECKING, Any, NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from mwjax import benchmarks
from mwjax.contracts import Frame, Kinematics, Placement, StepInputs
from mwjax.observation import OBJECTS_SIZE, Observation
from mwjax.physics import Physics, PhysicsConfig, PhysicsState
from mwjax.tasks import get_task
from mwjax.tasks.spec import TaskSpec

if TYPE_CHECKING:
    from mwjax.sharding import ShardedEnv

Array = jax.Array

MAX_EPISODE_STEPS = 500
_HAND_SPACE_LOW = np.array([-0.525, 0.348, -0.0525], np.float32)
_HAND_SPACE_HIGH = np.array([0.525, 1.025, 0.7], np.float32)
_HAND_QUAT = np.array([1.0, 0.0, 1.0, 0.0], np.float32)
_ACTION_SCALE = 1.0 / 100
# SawyerXYZEnv._reset_hand: 50 env steps of physics driving the hand to `hand_init_pos`.
_SETTLE_ENV_STEPS = 50
# The float info terms every V2 kernel reports besides `success`.
_REWARD_INFO = ("near_object", "grasp_reward", "in_place_reward", "obj_to_target", "unscaled_reward")
AUTORESET_MODES = ("same_step", "next_step", "disabled")
GOAL_SAMPLING = ("on_reset", "on_request")


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


class Settled(NamedTuple):
    """The state a reset places objects into: the reference's data right after `_reset_hand`
    (poses as its last `mj_step` left them), one env or a batch."""

    kin: Kinematics
    qacc_warmstart: Array


@dataclasses.dataclass(frozen=True, eq=False)
class _TaskRows:
    spec: TaskSpec
    group: int
    start: int  # first row in the env batch
    local_start: int  # first row in its physics group
    size: int
    # The recorded settled state (the same for every goal unless `spec.settle_per_goal`).
    settled: Settled
    # The hand's part of it, the same in every task: mocap_pos, mocap_quat, ctrl.
    settled_data: dict[str, np.ndarray]
    # With `spec.settle_per_goal`: the settled state of each of the env's goal variants.
    settled_per_variant: Settled | None = None


def _load_settled(name: str) -> tuple[Settled, dict[str, np.ndarray]]:
    path = resources.files("mwjax.tasks") / "settled_states.npz"
    with resources.as_file(path) as file, np.load(file) as archive:
        fields = {
            key.split("/", 1)[1]: archive[key].astype(np.float32)
            for key in archive.files
            if key.startswith(name + "/")
        }
    if not fields:
        raise ValueError(f"no settled state recorded for {name!r}")
    kin = Kinematics(*(jnp.asarray(fields[f]) for f in Kinematics._fields))
    return Settled(kin, jnp.asarray(fields["qacc_warmstart"])), fields


# Settled states per goal variant, by (scene, its mocap bodies, physics config, task, variants):
# every env of a process with the same tasks and goals shares them.
_SETTLED_PER_VARIANT: dict[tuple[Any, ...], Settled] = {}


class Env:
    """A batched Meta-World task set. Build it with `mwjax.make`."""

    def __init__(
        self,
        tasks: str | Sequence[str] | benchmarks.Benchmark,
        envs_per_task: int,
        seed: int = 0,
        reward_version: str = "v2",
        split: str = "train",
        task: str | None = None,
        partially_observable: bool | None = None,
        max_episode_steps: int = MAX_EPISODE_STEPS,
        autoreset: str = "same_step",
        terminate_on_success: bool = False,
        goal_sampling: str | None = None,
        variants_per_task: int | None = None,
        physics: PhysicsConfig | None = None,
        goal_variants: Mapping[str, Any] | None = None,
    ) -> None:
        if reward_version not in ("v1", "v2"):
            raise ValueError(f"reward_version must be 'v1' or 'v2', got {reward_version!r}")
        if not isinstance(envs_per_task, int) or envs_per_task < 1:
            raise ValueError(f"envs_per_task must be a positive int, got {envs_per_task!r}")
        if not isinstance(max_episode_steps, int) or max_episode_steps < 1:
            raise ValueError(f"max_episode_steps must be a positive int, got {max_episode_steps!r}")
        if autoreset not in AUTORESET_MODES:
            raise ValueError(f"autoreset must be one of {AUTORESET_MODES}, got {autoreset!r}")
        self.config: dict[str, Any] = {
            "tasks": tasks,
            "envs_per_task": envs_per_task,
            "seed": seed,
            "reward_version": reward_version,
            "split": split,
            "task": task,
            "partially_observable": partially_observable,
            "max_episode_steps": max_episode_steps,
            "autoreset": autoreset,
            "terminate_on_success": terminate_on_success,
            "goal_sampling": goal_sampling,
            "variants_per_task": variants_per_task,
            "physics": physics,
            "goal_variants": goal_variants,
        }
        bench = benchmarks.benchmark(tasks, task)
        names = bench.tasks(split)
        if goal_variants is None:
            variants = benchmarks.goal_variants(bench, seed, split)
        else:
            variants = _given_variants(goal_variants, names)
        if goal_sampling is None:
            goal_sampling = "on_request" if bench.meta_learning else "on_reset"
        if goal_sampling not in GOAL_SAMPLING:
            raise ValueError(f"goal_sampling must be one of {GOAL_SAMPLING}, got {goal_sampling!r}")
        available = len(next(iter(variants.values())))
        n_variants = available if variants_per_task is None else variants_per_task
        if not isinstance(n_variants, int) or not 1 <= n_variants <= available:
            raise ValueError(f"variants_per_task must be an int in [1, {available}], got {n_variants!r}")
        self.benchmark = bench
        self.split = split
        self.reward_version = reward_version
        self.partially_observable = (
            bench.meta_learning if partially_observable is None else partially_observable
        )
        self.max_episode_steps = max_episode_steps
        self.autoreset = autoreset
        self.terminate_on_success = terminate_on_success
        self.goal_sampling = goal_sampling
        self.envs_per_task = envs_per_task

        specs = [get_task(name) for name in names]
        scenes = list(dict.fromkeys(spec.scene for spec in specs))
        ordered = [spec for scene in scenes for spec in specs if spec.scene == scene]
        group_specs = [[s for s in ordered if s.scene == scene] for scene in scenes]
        self.physics = Physics(
            [
                (
                    scene,
                    tuple(sorted({b for s in members for b in s.moved_bodies})),
                    len(members) * envs_per_task,
                )
                for scene, members in zip(scenes, group_specs, strict=True)
            ],
            physics or PhysicsConfig(),
        )
        for members in group_specs:
            if len({s.reset_env_steps for s in members if s.reset_env_steps}) > 1:
                raise ValueError(f"tasks of scene {members[0].scene} step different counts at reset")
        rows: list[_TaskRows] = []
        for g, members in enumerate(group_specs):
            for k, spec in enumerate(members):
                settled, raw = _load_settled(spec.name)
                rows.append(
                    _TaskRows(
                        spec=spec,
                        group=g,
                        start=self.physics.groups[g].start + k * envs_per_task,
                        local_start=k * envs_per_task,
                        size=envs_per_task,
                        settled=settled,
                        settled_data=raw,
                    )
                )
        self._rows = tuple(self._with_settled_variants(rows, variants, n_variants))
        self.task_list = tuple(r.spec.name for r in rows)
        self.num_envs = len(rows) * envs_per_task
        self.task_names = tuple(name for name in self.task_list for _ in range(envs_per_task))
        self.task_ids = np.repeat(np.arange(len(rows)), envs_per_task)

        self.goal_variants = {name: variants[name][:n_variants] for name in self.task_list}
        width = max(v.shape[1] for v in variants.values())
        self._variants = jnp.asarray(
            np.stack(
                [np.pad(variants[n], ((0, 0), (0, width - variants[n].shape[1]))) for n in self.task_list]
            ),
            jnp.float32,
        )

        def per_env(values: Sequence[Any]) -> jnp.ndarray:
            return jnp.asarray(np.repeat(np.asarray(values, np.float32), envs_per_task, axis=0))

        self._mocap_low = per_env([r.spec.mocap_bounds[0] for r in rows])
        self._mocap_high = per_env([r.spec.mocap_bounds[1] for r in rows])
        self._goal_low = per_env([r.spec.goal_bounds[0] for r in rows])
        self._goal_high = per_env([r.spec.goal_bounds[1] for r in rows])
        self._goal_pools, self._goal_pool_sizes = _goal_pools(
            goal_sampling, envs_per_task, n_variants, len(rows)
        )

    # ----------------------------------------------------------------------------------------
    # Public functional API

    def reset(self, key: Array) -> State:
        """A fresh episode in every env, each from its own key. With `goal_sampling="on_reset"`
        (MT sets) every env draws one of its task's goal variants; with `"on_request"` (ML sets)
        every env shuffles its own share of them and starts on the first."""
        keys = self._row_keys(key)
        order, keys = self._shuffled_pools(keys)
        cursor = jnp.zeros(self.num_envs, jnp.int32)
        if self.goal_sampling == "on_reset":
            cursor, keys = self._draw_cursor(keys)
        return self._start(order, cursor, keys)

    def reset_with_variants(self, variants: Array, key: Array | None = None) -> State:
        """A fresh episode in every env on the given goal variants (`(num_envs,)` indices into
        `env.goal_variants[task]`), e.g. one episode per variant for evaluation."""
        variants = jnp.asarray(variants, jnp.int32)
        if variants.shape != (self.num_envs,):
            raise ValueError(f"variants must have shape ({self.num_envs},), got {variants.shape}")
        if not isinstance(variants, jax.core.Tracer):
            n = self._variants.shape[1]
            concrete = np.asarray(variants)
            if not np.all((concrete >= 0) & (concrete < n)):
                raise ValueError(f"variants must lie in [0, {n})")
        keys = self._row_keys(jax.random.key(0) if key is None else key)
        order = jnp.broadcast_to(
            jnp.arange(self._variants.shape[1], dtype=jnp.int32), (self.num_envs, self._variants.shape[1])
        )
        return self._start(order, variants, keys)

    def sample_goals(self, state: State) -> State:
        """Every env moves on to its next goal variant and starts a fresh episode (the reference's
        `sample_tasks` of ML envs: each env cycles through its own share of the variants in a
        shuffled order, reshuffling when it has used them all). With `goal_sampling="on_reset"`
        every env draws a new variant, as at any reset."""
        if self.goal_sampling == "on_reset":
            cursor, keys = self._draw_cursor(state.key)
            return self._start(state.goal_order, cursor, keys)
        cursor = state.goal_cursor + 1
        wrapped = cursor >= self._goal_pool_sizes
        reshuffled, keys = self._shuffled_pools(state.key)
        order = _select(wrapped, reshuffled, state.goal_order)
        return self._start(order, jnp.where(wrapped, 0, cursor), keys)

    def reset_to(self, rand_vecs: Array, key: Array | None = None) -> State:
        """A fresh episode in every env with the given goal variants (`(num_envs, d)`, the
        reference's `rand_vec`, zero-padded to the widest task of the set)."""
        rand_vecs = jnp.asarray(rand_vecs, jnp.float32)
        if rand_vecs.shape != (self.num_envs, self._variants.shape[2]):
            raise ValueError(
                f"rand_vecs must have shape {(self.num_envs, self._variants.shape[2])}, got {rand_vecs.shape}"
            )
        keys = self._row_keys(jax.random.key(0) if key is None else key)
        order, keys = self._shuffled_pools(keys)
        cursor = jnp.zeros(self.num_envs, jnp.int32)
        all_rows = jnp.ones(self.num_envs, bool)
        return self._reset_rows(self.physics.make_data(), rand_vecs, None, order, cursor, keys, all_rows)

    def replace(self, **changes: Any) -> Env | ShardedEnv:
        """The same env with some constructor arguments changed (a new, separately compiled env);
        `devices=` splits it over devices, as `make`'s."""
        config = {**self.config, **changes}
        devices = config.pop("devices", None)
        return Env(**config) if devices is None else make(devices=devices, **config)

    def restart(self, state: State, mask: Array | None = None) -> State:
        """Fresh episodes in the rows where `mask` (all by default), as an autoreset starts them:
        a new goal variant with `goal_sampling="on_reset"`, the same one with `"on_request"`."""
        mask = jnp.ones(self.num_envs, bool) if mask is None else jnp.asarray(mask, bool)
        return self._restart(state, mask)

    def observation_bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """The reference's observation box (hand box, gripper [-1, 1], unbounded objects, goal
        box or zeros when hidden), widened over the set's tasks, whose goal boxes differ."""
        if self.partially_observable:
            goal_low = goal_high = np.zeros(3, np.float32)
        else:
            goal_low = np.min(np.asarray(self._goal_low), axis=0)
            goal_high = np.max(np.asarray(self._goal_high), axis=0)
        frame_low = np.concatenate([_HAND_SPACE_LOW, [-1.0], np.full(OBJECTS_SIZE, -np.inf)])
        frame_high = np.concatenate([_HAND_SPACE_HIGH, [1.0], np.full(OBJECTS_SIZE, np.inf)])
        low = np.concatenate([frame_low, frame_low, goal_low]).astype(np.float32)
        high = np.concatenate([frame_high, frame_high, goal_high]).astype(np.float32)
        return low, high

    def task_one_hot(self) -> np.ndarray:
        """Each env's task id as a one-hot row, `(num_envs, tasks)`: the reference's `use_one_hot`."""
        return np.eye(len(self.task_list), dtype=np.float32)[self.task_ids]

    def task_rows(self, task: str) -> slice:
        """The rows of `task` in the env batch."""
        rows = self._task(task)
        return slice(rows.start, rows.start + rows.size)

    def kinematics(self, state: State, task: str) -> Kinematics:
        """qpos, qvel and the body/site/geom poses of `task`'s rows (its scene's ids)."""
        rows = self._task(task)
        return Kinematics.of(state.physics[rows.group]).rows(rows.local_start, rows.local_start + rows.size)

    def with_physics_state(self, state: State, physics: Mapping[str, Mapping[str, Array]]) -> State:
        """`state` with the dynamic physics state of some tasks' rows replaced (e.g. by recorded
        reference states): `{task: {"qpos", "qvel", "mocap_pos", "mocap_quat"}}`, the mocap
        entries being the hand's. Kinematics are recomputed; use `observe` for obs and rewards."""
        datas = list(state.physics)
        for task, fields in physics.items():
            rows = self._task(task)
            local = slice(rows.local_start, rows.local_start + rows.size)
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
        return dataclasses.replace(state, obs=obs, reward=reward, info=info, constants=constants)

    def step(self, state: State, action: Array) -> State:
        """One env step for the whole batch (5 physics steps), with rewards and autoreset.

        `action`: `(num_envs, 4)` floats in [-1, 1] (an array, or nested lists). Besides the task's
        reward terms and `success`, `state.info` holds per env: `episode_return` and
        `episode_length` (the episode's return and steps so far, including this step; at an
        autoreset, the finished episode's), `invalid_action` (this step's action had NaN or inf
        and was replaced by zeros), `physics_overflow` (Warp's `OverflowType` flags of this step)
        and `final_obs` (the last observation of an episode that ended at this step)."""
        action = self._check_action(action)
        valid = jnp.all(jnp.isfinite(action), axis=-1)
        action = jnp.where(valid[:, None], action, 0.0)

        datas = self.physics.step(self._apply_action(state.physics, action))
        kin = self._kinematics(datas)
        obs, reward, info, constants = self._observe_and_reward(kin, state, action)
        info["invalid_action"] = ~valid
        info["physics_overflow"] = self.physics.overflow(datas)
        steps = state.steps + 1
        episode_return = state.episode_return + reward
        info["episode_return"] = episode_return
        info["episode_length"] = steps
        truncated = steps >= self.max_episode_steps
        terminated = info["success"] if self.terminate_on_success else jnp.zeros_like(truncated)
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
            return jax.lax.cond(
                jnp.any(done),
                lambda s: self._autoreset(s, done),
                lambda s: self._with_final(s, done),
                stepped,
            )
        stepped = self._with_final(stepped, done)
        if self.autoreset == "disabled":
            return stepped
        # NEXT_STEP: an env whose episode ended at the previous call starts a new one instead.
        ended = state.terminated | state.truncated
        return jax.lax.cond(jnp.any(ended), lambda s: self._restart(s, ended), lambda s: s, stepped)

    def _row_keys(self, key: Array) -> Array:
        """One key per env, split from a reset's key (a sharded env's part on one device,
        `mwjax.sharding`, takes its rows of the whole batch's split instead)."""
        return jax.random.split(key, self.num_envs)

    def _task(self, task: str) -> _TaskRows:
        for rows in self._rows:
            if rows.spec.name == task:
                return rows
        raise ValueError(f"{task!r} is not in this env's tasks {self.task_list}")

    # ----------------------------------------------------------------------------------------
    # Reset

    def _shuffled_pools(self, keys: Array) -> tuple[Array, Array]:
        """Each env's pool of goal variants in a fresh random order (padding last), and next keys."""
        split = jax.vmap(jax.random.split)(keys)
        size = self._goal_pools.shape[1]
        noise = jax.vmap(lambda k: jax.random.uniform(k, (size,)))(split[:, 0])
        noise = jnp.where(jnp.arange(size) < self._goal_pool_sizes[:, None], noise, 2.0)
        order = jnp.take_along_axis(self._goal_pools, jnp.argsort(noise, axis=1), axis=1)
        return order, split[:, 1]

    def _draw_cursor(self, keys: Array) -> tuple[Array, Array]:
        """A uniform position in each env's pool (the reference's MT `RandomTaskSelectWrapper`)."""
        split = jax.vmap(jax.random.split)(keys)
        cursor = jax.vmap(lambda k, n: jax.random.randint(k, (), 0, n))(split[:, 0], self._goal_pool_sizes)
        return cursor.astype(jnp.int32), split[:, 1]

    def _goals(self, order: Array, cursor: Array) -> tuple[Array, Array]:
        """Each env's goal variant at `cursor` in its `order`, and that variant's vector."""
        variant = jnp.take_along_axis(order, cursor[:, None], axis=1)[:, 0]
        return variant, self._variants[jnp.asarray(self.task_ids), variant]

    def _start(self, order: Array, cursor: Array, keys: Array) -> State:
        variant, rand_vecs = self._goals(order, cursor)
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
            new_datas[g], group_placements, group_settled = self._reset_group(
                g, datas[g], rand_vecs, variant, done
            )
            placements.extend(group_placements)
            settled.extend(group_settled)
        datas = self.physics.kinematics(tuple(new_datas))
        kin = self._kinematics(datas)

        curr_parts, target_parts, constant_parts = [], [], []
        for rows, placement, rows_settled in zip(self._rows, placements, settled, strict=True):
            frames = kin[rows.group].rows(rows.local_start, rows.local_start + rows.size)
            model = self.physics.groups[rows.group].model

            def one(
                k: Kinematics, p: Placement, s: Kinematics, rows: _TaskRows = rows, model: Any = model
            ) -> tuple[Array, dict[str, Array]]:
                frame = Frame(model, k)
                return _current_obs(rows.spec, frame), rows.spec.constants(frame, p, Frame(model, s))

            curr, constants = jax.vmap(one)(frames, placement, rows_settled.kin)
            curr_parts.append(curr)
            # A goal read off the placed scene (e.g. a site on a moved fixture) overrides `place`'s.
            target_parts.append(constants.pop("target_pos", placement.target_pos))
            constant_parts.append(constants)
        curr = jnp.concatenate(curr_parts)
        target = jnp.concatenate(target_parts).astype(jnp.float32)
        goal = jnp.zeros_like(target) if self.partially_observable else target
        obs = jnp.concatenate([curr, curr, goal], axis=-1)
        zeros = jnp.zeros(self.num_envs, jnp.float32)
        info = {name: zeros for name in _REWARD_INFO}
        info["success"] = jnp.zeros(self.num_envs, bool)
        info["invalid_action"] = jnp.zeros(self.num_envs, bool)
        info["physics_overflow"] = jnp.zeros(self.num_envs, jnp.int32)
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

    def _reset_group(
        self, g: int, data: PhysicsState, rand_vecs: Array, variant: Array | None, done: Array
    ) -> tuple[PhysicsState, list[Placement], list[Settled]]:
        """Group `g`'s data with its `done` rows placed, and each member task's placements and
        settled states."""
        group = self.physics.groups[g]
        members = [r for r in self._rows if r.group == g]
        group_done = done[group.start : group.start + group.size]
        vecs = [rand_vecs[r.start : r.start + r.size, : len(r.spec.random_low)] for r in members]
        settled = self._settled(g, members, vecs, variant)
        placements = [
            _place(r.spec, group.model, v, s.kin) for r, v, s in zip(members, vecs, settled, strict=True)
        ]
        steps = max(r.spec.reset_env_steps for r in members)
        if steps == 0:
            placed = self._placed_data(
                data, group, list(zip(members, placements, settled, strict=True)), group_done
            )
            return placed, placements, settled

        # The reference steps the physics after moving fixed bodies but before writing joints:
        # move the bodies only, step, then place again on the stepped state.
        stepping = [r.spec.reset_env_steps > 0 for r in members]
        bodies_only = [
            dataclasses.replace(p, qpos=s.kin.qpos, qvel=s.kin.qvel) if st else p
            for p, s, st in zip(placements, settled, stepping, strict=True)
        ]
        pre = self._placed_data(
            data, group, list(zip(members, bodies_only, settled, strict=True)), group_done
        )
        for _ in range(steps):
            pre = self.physics.step_group(g, pre)
        stepped = Kinematics.of(pre)
        placements = [
            _place(r.spec, group.model, v, stepped.rows(r.local_start, r.local_start + r.size)) if st else p
            for r, v, p, st in zip(members, vecs, placements, stepping, strict=True)
        ]
        placed = self._placed_data(
            data, group, list(zip(members, placements, settled, strict=True)), group_done
        )
        stepped_rows = group_done & jnp.asarray(np.repeat(stepping, [r.size for r in members]))
        placed = placed.replace(
            qacc_warmstart=_select(stepped_rows, pre.qacc_warmstart, placed.qacc_warmstart)
        )
        return placed, placements, settled

    def _settled(
        self, g: int, members: list[_TaskRows], vecs: list[Array], variant: Array | None
    ) -> list[Settled]:
        """Each member task's settled state for its rows' goals, `(rows, ...)`: the recorded one,
        the one of the row's goal variant, or, for goals given as vectors, settled here."""
        settled: list[Settled | None] = []
        unsettled = []
        for i, rows in enumerate(members):
            if not rows.spec.settle_per_goal:
                settled.append(_broadcast(rows.settled, rows.size))
            elif variant is not None:
                rows_variant = variant[rows.start : rows.start + rows.size]
                settled.append(jax.tree.map(lambda x, v=rows_variant: x[v], rows.settled_per_variant))
            else:
                settled.append(None)
                unsettled.append(i)
        if unsettled:
            computed = self._settle(g, [(members[i], vecs[i]) for i in unsettled])
            for i, s in zip(unsettled, computed, strict=True):
                settled[i] = s
        return settled

    def _settle(self, g: int, parts: list[tuple[_TaskRows, Array]]) -> list[Settled]:
        """The reference's `_reset_hand` as a reset's second `reset_model` call runs it: from a
        fresh state (`mj_resetData`), with the fixed bodies already where the first call moved
        them for the goal, 50 env steps drive the hand to `hand_init_pos` with the fingers
        closing. `parts` are member tasks of group `g` with goal vectors `(rows, d)`; one settled
        batch per part, poses as the last `mj_step` leaves them."""
        group = self.physics.groups[g]
        sizes = [len(vecs) for _, vecs in parts]
        # Where the fixed bodies stand is set by the goal alone, so any settled state places them.
        poses = [
            _mocap_poses(
                group.model, rows, _place(rows.spec, group.model, vecs, _broadcast(rows.settled.kin, n))
            )
            for (rows, vecs), n in zip(parts, sizes, strict=True)
        ]
        data = self.physics.fresh(g, sum(sizes)).replace(
            mocap_pos=jnp.concatenate([pos for pos, _ in poses]),
            mocap_quat=jnp.concatenate([quat for _, quat in poses]),
            ctrl=_broadcast(parts[0][0].settled_data["ctrl"], sum(sizes)),
        )
        data = jax.lax.fori_loop(
            0, _SETTLE_ENV_STEPS, lambda _, d: self.physics.step_group(g, d, fresh_poses=False), data
        )
        kin, bounds = Kinematics.of(data), np.cumsum([0, *sizes])
        return [
            Settled(kin.rows(a, b), data.qacc_warmstart[a:b])
            for a, b in zip(bounds[:-1], bounds[1:], strict=True)
        ]

    def _with_settled_variants(
        self, rows: list[_TaskRows], variants: Mapping[str, np.ndarray], n_variants: int
    ) -> list[_TaskRows]:
        """`rows` with the settled state of each goal variant of every `settle_per_goal` task."""
        rows = list(rows)
        for g, group in enumerate(self.physics.groups):
            members = [i for i, r in enumerate(rows) if r.group == g and r.spec.settle_per_goal]
            if not members:
                continue
            vecs = [np.asarray(variants[rows[i].spec.name][:n_variants], np.float32) for i in members]
            key = (
                group.scene,
                group.mocap_bodies,
                self.physics.config,
                tuple((rows[i].spec.name, v.tobytes()) for i, v in zip(members, vecs, strict=True)),
            )
            if key not in _SETTLED_PER_VARIANT:
                parts = [rows[i] for i in members]
                settle = jax.jit(
                    lambda vs, g=g, parts=parts: self._settle(g, list(zip(parts, vs, strict=True)))
                )
                _SETTLED_PER_VARIANT[key] = settle([jnp.asarray(v) for v in vecs])
            for i, settled in zip(members, _SETTLED_PER_VARIANT[key], strict=True):
                rows[i] = dataclasses.replace(rows[i], settled_per_variant=settled)
        return rows

    def _placed_data(
        self,
        data: PhysicsState,
        group: Any,
        parts: list[tuple[_TaskRows, Placement, Settled]],
        done: Array,
    ) -> PhysicsState:
        model = group.model
        mocap_pos, mocap_quat, qpos, qvel, warm, ctrl = [], [], [], [], [], []
        for rows, placement, settled in parts:
            pos, quat = _mocap_poses(model, rows, placement)
            mocap_pos.append(pos)
            mocap_quat.append(quat)
            qpos.append(placement.qpos)
            qvel.append(placement.qvel)
            warm.append(settled.qacc_warmstart)
            ctrl.append(_broadcast(rows.settled_data["ctrl"], len(placement.qpos)))
        fresh = {
            "qpos": qpos,
            "qvel": qvel,
            "mocap_pos": mocap_pos,
            "mocap_quat": mocap_quat,
            "qacc_warmstart": warm,
            "ctrl": ctrl,
        }
        # These fields are the whole dynamic state; everything else is derived from them.
        fields = {
            name: _select(done, jnp.concatenate(parts).astype(jnp.float32), getattr(data, name))
            for name, parts in fresh.items()
        }
        return data.replace(time=jnp.where(done, 0.0, data.time), **fields)

    def _fresh(self, state: State, done: Array) -> State:
        """New episodes in the `done` rows (a new goal variant if `goal_sampling="on_reset"`)."""
        cursor, keys = state.goal_cursor, state.key
        if self.goal_sampling == "on_reset":
            cursor, keys = self._draw_cursor(keys)
        variant, rand_vecs = self._goals(state.goal_order, cursor)
        return self._reset_rows(state.physics, rand_vecs, variant, state.goal_order, cursor, keys, done)

    def _autoreset(self, state: State, done: Array) -> State:
        """SAME_STEP: the `done` rows carry the next episode's start, their step's reward, flags
        and info stay (they are the finished episode's final info), `final_obs` its last obs."""
        fresh = self._fresh(state, done)
        final = self._with_final(state, done)
        pick = functools.partial(_select, done)
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
        pick = functools.partial(_select, ended)
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

    def _check_action(self, action: Any) -> Array:
        if isinstance(action, (list, tuple)):
            # Nested lists (under jit, a pytree of scalar tracers) become one array; Python floats
            # give float32, Python ints an int array, refused below like any non-float dtype.
            action = jnp.asarray(action)
        shape = getattr(action, "shape", None)
        if shape is None:
            raise ValueError(f"actions must be a ({self.num_envs}, 4) array, got {type(action).__name__}")
        if shape != (self.num_envs, 4):
            raise ValueError(f"actions must have shape ({self.num_envs}, 4), got {shape}")
        dtype = getattr(action, "dtype", None)
        if dtype is None or not jnp.issubdtype(dtype, jnp.floating):
            raise ValueError(f"actions must be floating point, got dtype {dtype}")
        if not isinstance(action, jax.core.Tracer) and not bool(np.all(np.isfinite(np.asarray(action)))):
            raise ValueError("actions contain NaN or inf")
        return jnp.asarray(action, jnp.float32)

    def _apply_action(self, datas: tuple[PhysicsState, ...], action: Array) -> tuple[PhysicsState, ...]:
        """metaworld's set_xyz_action and gripper control: the hand's mocap moves by
        clip(a, -1, 1) / 100 within the task's mocap box; the fingers get [a3, -a3]."""
        delta = jnp.clip(action[:, :3], -1.0, 1.0) * _ACTION_SCALE
        out = []
        for group, data in zip(self.physics.groups, datas, strict=True):
            rows = slice(group.start, group.start + group.size)
            hand = jnp.clip(data.mocap_pos[:, 0] + delta[rows], self._mocap_low[rows], self._mocap_high[rows])
            out.append(
                data.replace(
                    mocap_pos=data.mocap_pos.at[:, 0].set(hand),
                    mocap_quat=data.mocap_quat.at[:, 0].set(jnp.asarray(_HAND_QUAT)),
                    ctrl=jnp.stack([action[rows, 3], -action[rows, 3]], axis=-1),
                )
            )
        return tuple(out)

    def _kinematics(self, datas: tuple[PhysicsState, ...]) -> tuple[Kinematics, ...]:
        return tuple(Kinematics.of(d) for d in datas)

    def _observe_and_reward(
        self, kin: tuple[Kinematics, ...], state: State, action: Array
    ) -> tuple[Array, Array, dict[str, Array], dict[str, Array]]:
        """Obs, reward and info after a step, and the constants with first-step latches applied."""
        curr_parts = []
        for rows in self._rows:
            model = self.physics.groups[rows.group].model
            frames = kin[rows.group].rows(rows.local_start, rows.local_start + rows.size)
            curr_parts.append(
                jax.vmap(lambda k, m=model, spec=rows.spec: _current_obs(spec, Frame(m, k)))(frames)
            )
        curr = jnp.concatenate(curr_parts)
        goal = jnp.zeros_like(state.target_pos) if self.partially_observable else state.target_pos
        obs = jnp.concatenate([curr, Observation(state.obs).frame, goal], axis=-1)
        obs = self._clip_obs(obs)

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

    def _clip_obs(self, obs: Array) -> Array:
        """The reference clips step observations to its observation space."""
        inf = jnp.full((self.num_envs, OBJECTS_SIZE), jnp.inf)
        hand_low = jnp.broadcast_to(jnp.asarray(_HAND_SPACE_LOW), (self.num_envs, 3))
        hand_high = jnp.broadcast_to(jnp.asarray(_HAND_SPACE_HIGH), (self.num_envs, 3))
        minus_one, one = -jnp.ones((self.num_envs, 1)), jnp.ones((self.num_envs, 1))
        if self.partially_observable:
            goal_low = goal_high = jnp.zeros((self.num_envs, 3))
        else:
            goal_low, goal_high = self._goal_low, self._goal_high
        low = jnp.concatenate([hand_low, minus_one, -inf, hand_low, minus_one, -inf, goal_low], axis=-1)
        high = jnp.concatenate([hand_high, one, inf, hand_high, one, inf, goal_high], axis=-1)
        return jnp.clip(obs, low, high)


def _place(spec: TaskSpec, model: Any, rand_vecs: Array, settled: Kinematics) -> Placement:
    """`spec.place` over a task's rows, each from its own settled (or stepped) state."""
    return jax.vmap(lambda v, k: spec.place(v, Frame(model, k)))(rand_vecs, settled)


def _broadcast(tree: Any, n: int) -> Any:
    """One env's arrays repeated over `n` rows."""
    return jax.tree.map(lambda x: jnp.broadcast_to(jnp.asarray(x), (n, *jnp.shape(x))), tree)


def _mocap_poses(model: Any, rows: _TaskRows, placement: Placement) -> tuple[Array, Array]:
    """Every mocap body's pose over a task's rows, `(rows, nmocap, 3 / 4)`: the hand's settled
    target, the fixed bodies the task moves where `placement` puts them, the rest as compiled."""
    n = len(placement.qpos)
    is_mocap = model.body_mocapid >= 0  # body order is mocap index order
    pos = jnp.asarray(np.broadcast_to(model.body_pos[is_mocap], (n, model.nmocap, 3)), jnp.float32)
    quat = jnp.asarray(np.broadcast_to(model.body_quat[is_mocap], (n, model.nmocap, 4)), jnp.float32)
    pos = pos.at[:, 0].set(rows.settled_data["mocap_pos"][0])
    quat = quat.at[:, 0].set(rows.settled_data["mocap_quat"][0])
    for name, value in placement.moved_bodies.items():
        pos = pos.at[:, int(model.body_mocapid[model.body(name).id])].set(value)
    return pos, quat


def _select(mask: Array, new: Array, old: Array) -> Array:
    """Row-wise `where` for arrays with a leading batch axis."""
    return jnp.where(mask.reshape(mask.shape + (1,) * (old.ndim - 1)), new, old)


def _current_obs(spec: TaskSpec, frame: Frame) -> Array:
    """The 18-value frame: hand position, gripper opening, then objects (pos + quat, padded)."""
    pos, quat = spec.objects(frame)
    objects = jnp.concatenate([pos, quat], axis=-1).reshape(-1)
    objects = jnp.pad(objects, (0, OBJECTS_SIZE - objects.shape[0]))
    return jnp.concatenate([frame.hand_pos, frame.gripper_distance[None], objects]).astype(jnp.float32)


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
    in total (`num_envs`, a multiple of the task count). `devices` (e.g. `jax.devices()`) splits
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
    if devices is not None:
        from mwjax.sharding import ShardedEnv

        return ShardedEnv(
            devices, tasks, envs_per_task=envs_per_task, seed=seed, reward_version=reward_version, **kwargs
        )
    return Env(tasks, envs_per_task=envs_per_task, seed=seed, reward_version=reward_version, **kwargs)


def _given_variants(given: Mapping[str, Any], names: Sequence[str]) -> dict[str, np.ndarray]:
    """Caller-chosen goal variants (`rand_vec`s), checked: one `(n, d)` array per task of the
    split, the same n for all, each row inside the task's random box."""
    if set(given) != set(names):
        raise ValueError(f"goal_variants must have exactly the tasks {sorted(names)}, got {sorted(given)}")
    variants = {}
    for name in names:
        spec = get_task(name)
        low, high = np.asarray(spec.random_low), np.asarray(spec.random_high)
        vecs = np.asarray(given[name], np.float64)
        if vecs.ndim != 2 or vecs.shape[1] != low.size or len(vecs) < 1:
            raise ValueError(f"goal_variants[{name!r}] must have shape (n, {low.size}), got {vecs.shape}")
        if not np.all(np.isfinite(vecs)) or np.any(vecs < low) or np.any(vecs > high):
            raise ValueError(f"goal_variants[{name!r}] has values outside the task's random box")
        variants[name] = vecs
    if len({len(v) for v in variants.values()}) > 1:
        raise ValueError("goal_variants must give every task the same number of variants")
    return variants


def _goal_pools(goal_sampling: str, envs_per_task: int, n_variants: int, n_tasks: int) -> tuple[Array, Array]:
    """Which goal variants each env may visit, `(num_envs, P)` padded, and how many.

    MT envs (`"on_reset"`) may draw any of their task's variants. ML envs (`"on_request"`) split
    them like the reference's ML envs: env i of a task owns variants i, i + E, i + 2E, ... (E
    envs per task); with more envs than variants, env i owns variant i mod the variant count."""
    if goal_sampling == "on_reset" or envs_per_task == 1:
        pools = [list(range(n_variants))] * envs_per_task
    else:
        pools = [list(range(i % n_variants, n_variants, envs_per_task)) for i in range(envs_per_task)]
    width = max(len(p) for p in pools)
    padded = np.array([p + [p[0]] * (width - len(p)) for p in pools], np.int32)
    sizes = np.array([len(p) for p in pools], np.int32)
    return jnp.asarray(np.tile(padded, (n_tasks, 1))), jnp.asarray(np.tile(sizes, n_tasks))
