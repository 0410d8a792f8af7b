"""One task set split over several devices: `mwjax.make(..., devices=jax.devices())`.

Every device runs the unsharded env's code on its own share of the batch: `ShardedEnv` builds one
`Env` with `envs_per_task / len(devices)` envs per task (the "local" env, the same scenes and
tasks) and runs its `reset`/`step`/... under `jax.shard_map`, each device on its rows of the
state. Rewards, observations, autoreset and goal sampling are the `Env`'s own, unchanged; the
physics (MJX-Warp's FFI calls) runs inside the map, one call per scene on every device.

Layout. The batch is device-major: device d holds rows [d * n, (d + 1) * n) (n = num_envs /
devices), laid out as a local env lays them out (task by task, `envs_per_task / devices` rows
each). Every device so steps an equal share of every task and scene. Env `e` of task `t`
(the unsharded env's row t * envs_per_task + e) lives on device e // (envs_per_task / devices);
`ShardedEnv.row_order[i]` is the unsharded row of row i and `unsharded(state)` reorders a state.
`task_names`, `task_ids` and `task_one_hot()` follow this layout.

Same results as the unsharded env. Each row's keys and goal pool are those of its unsharded
row (the reset's per-env keys are split from the whole batch's key, then each device takes its
rows), so for the same seed a sharded env produces the unsharded env's episodes, row for row
(bit for bit on the CPU, tests/test_sharding.py).

`check_vma=False`: with JAX's varying-axis checks on, a loop whose carry mixes values made
inside the map (`mjx.make_data`'s, invariant) with values from the sharded state (varying)
fails to trace, as a Warp FFI output is typed varying (Warp 1.18 marks every output with the
union of its inputs' axes). Nothing here communicates between devices, so the checks buy
nothing.
"""

from __future__ import annotations

import copy
import dataclasses
from collections.abc import Callable, Mapping, Sequence
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
from jax.sharding import Mesh, NamedSharding
from jax.sharding import PartitionSpec as P

from mwjax.config import EnvConfig
from mwjax.contracts import Kinematics
from mwjax.env import Env, State
from mwjax.goals import goal_pools
from mwjax.physics import PhysicsConfig, runs_scenes_together
from mwjax.sawyer import check_action

Array = jax.Array
AXIS = "envs"
# Warp 1.18's staged graph modes keep the graph they capture on a call's first run in the call's
# descriptor (one per traced call) and replay it on every later run, whatever the device; its
# "warp" mode keys graphs by device, call and buffers (warp/_src/jax/ffi.py, `ffi_callback`).
_ONE_GRAPH_PER_CALL = ("warp_staged", "warp_staged_ex")


class ShardedEnv:
    """A batched task set whose rows are split over `devices` (see the module docstring). It has
    `Env`'s functional API (`reset`, `step`, ...), each call one SPMD program over the devices."""

    def __init__(self, devices: Sequence[jax.Device], config: EnvConfig) -> None:
        devices = tuple(devices)
        if not devices:
            raise ValueError("devices must name at least one device")
        if len(set(devices)) != len(devices):
            raise ValueError(f"devices must be distinct, got {devices}")
        n = len(devices)
        envs_per_task = config.envs_per_task
        if envs_per_task % n:
            raise ValueError(
                f"envs_per_task={envs_per_task} is not a multiple of the {n} devices: every device "
                "steps an equal share of every task"
            )
        physics = config.physics or PhysicsConfig()
        if n > 1 and physics.graph_mode in _ONE_GRAPH_PER_CALL:
            raise ValueError(
                f"graph_mode={physics.graph_mode!r} keeps one CUDA graph per traced Warp call, which "
                "every device would replay; use 'warp' (one graph per device), 'jax' or 'none'"
            )
        # The default for scenes side by side depends on the device count, which the local env
        # does not see.
        together = runs_scenes_together(physics, devices[0].platform, n)
        config = dataclasses.replace(config, physics=dataclasses.replace(physics, concurrent_scenes=together))
        self.devices = devices
        self.mesh = Mesh(np.array(devices), (AXIS,))
        self.sharding = NamedSharding(self.mesh, P(AXIS))
        self.config = config
        self.local = local = Env(dataclasses.replace(config, envs_per_task=envs_per_task // n))
        for name in (
            "benchmark",
            "split",
            "reward_version",
            "partially_observable",
            "max_episode_steps",
            "autoreset",
            "terminate_on_success",
            "goal_sampling",
            "task_list",
            "goal_variants",
            "physics",
        ):
            setattr(self, name, getattr(local, name))
        self.envs_per_task = envs_per_task
        self.num_envs = n * local.num_envs
        self.task_ids = np.tile(local.task_ids, n)
        self.task_names = tuple(local.task_names) * n

        # Row i of this batch is row `row_order[i]` of the unsharded env's.
        share, n_tasks = envs_per_task // n, len(local.task_list)
        d, t, j = np.meshgrid(np.arange(n), np.arange(n_tasks), np.arange(share), indexing="ij")
        self.row_order = (t * envs_per_task + d * share + j).ravel()
        self._inverse = np.argsort(self.row_order)
        # The same for each scene group's physics rows (its member tasks, each `share` per device).
        self._group_inverse = []
        for group in local.physics.groups:
            members = group.size // share
            d, k, j = np.meshgrid(np.arange(n), np.arange(members), np.arange(share), indexing="ij")
            self._group_inverse.append(np.argsort((k * envs_per_task + d * share + j).ravel()))

        # What differs between devices: each row's goal pool (ML sets give env e of a task its own
        # share of the goal variants) and its place in the whole batch (for the reset keys). Both
        # follow from the device's index, computed inside the map from small host tables: a
        # device array here would span every process's devices, which no jitted function may
        # close over when one process drives each GPU (mwjax.distributed).
        n_variants = next(iter(local.goal_variants.values())).shape[0]
        pools, sizes = goal_pools(local.goal_sampling, envs_per_task, n_variants, 1)
        self._env_pools, self._env_pool_sizes = np.asarray(pools), np.asarray(sizes)
        self._mapped: dict[Any, Callable[..., Any]] = {}

    # ----------------------------------------------------------------------------------------
    # Env's functional API, sharded

    def reset(self, key: Array) -> State:
        return self._map("reset", lambda env, key: env.reset(key), replicated=(0,))(key)

    def reset_with_variants(self, variants: Array, key: Array | None = None) -> State:
        variants = jnp.asarray(variants, jnp.int32)
        if variants.shape != (self.num_envs,):
            raise ValueError(f"variants must have shape ({self.num_envs},), got {variants.shape}")
        if not isinstance(variants, jax.core.Tracer):
            n = self.local.goals.count
            if not bool(((variants >= 0) & (variants < n)).all()):
                raise ValueError(f"variants must lie in [0, {n})")
        key = jax.random.key(0) if key is None else key
        run = self._map("reset_with_variants", lambda env, v, k: env.reset_with_variants(v, k), (1,))
        return run(variants, key)

    def reset_to(self, rand_vecs: Array, key: Array | None = None) -> State:
        rand_vecs = jnp.asarray(rand_vecs, jnp.float32)
        width = self.local.goals.width
        if rand_vecs.shape != (self.num_envs, width):
            raise ValueError(f"rand_vecs must have shape {(self.num_envs, width)}, got {rand_vecs.shape}")
        key = jax.random.key(0) if key is None else key
        return self._map("reset_to", lambda env, r, k: env.reset_to(r, k), (1,))(rand_vecs, key)

    def sample_goals(self, state: State) -> State:
        return self._map("sample_goals", lambda env, s: env.sample_goals(s))(state)

    def restart(self, state: State, mask: Array | None = None) -> State:
        mask = jnp.ones(self.num_envs, bool) if mask is None else jnp.asarray(mask, bool)
        return self._map("restart", lambda env, s, m: env.restart(s, m))(state, mask)

    def step(self, state: State, action: Array) -> State:
        action = check_action(action, self.num_envs)
        return self._map("step", lambda env, s, a: env.step(s, a))(state, action)

    def observe(self, state: State, action: Array) -> State:
        return self._map("observe", lambda env, s, a: env.observe(s, a))(state, jnp.asarray(action))

    def kinematics(self, state: State, task: str) -> Kinematics:
        """`task`'s rows (env order, as `task_rows(task)` lists them) of `Env.kinematics`."""
        self.local._task(task)
        return self._map(("kinematics", task), lambda env, s: env.kinematics(s, task))(state)

    def with_physics_state(self, state: State, physics: Mapping[str, Mapping[str, Array]]) -> State:
        """`Env.with_physics_state`; each task's arrays are in env order (`(envs_per_task, ...)`)."""
        physics = {t: {k: jnp.asarray(v, jnp.float32) for k, v in f.items()} for t, f in physics.items()}
        return self._map("with_physics_state", lambda env, s, p: env.with_physics_state(s, p))(state, physics)

    def replace(self, **changes: Any) -> Env | ShardedEnv:
        """The same env with some config fields changed (`devices=None`: unsharded). Changing
        only the settings `Env.replace` shares the built env for does so here too."""
        devices = changes.pop("devices", self.devices)
        config = dataclasses.replace(self.config, **changes)
        if devices == self.devices and changes.keys() <= Env._TRACE_TIME_FIELDS:
            env = copy.copy(self)
            env.config, env.local, env._mapped = config, self.local.replace(**changes), {}
            for name in changes:
                setattr(env, name, getattr(env.local, name))
            return env
        return Env(config) if devices is None else ShardedEnv(devices, config)

    def observation_bounds(self) -> tuple[np.ndarray, np.ndarray]:
        return self.local.observation_bounds()

    def task_one_hot(self) -> np.ndarray:
        return np.eye(len(self.task_list), dtype=np.float32)[self.task_ids]

    def task_rows(self, task: str) -> np.ndarray:
        """The rows of `task` in this batch (spread over the devices), in env order."""
        self.local._task(task)
        return np.flatnonzero(np.asarray(self.task_names) == task)

    def unsharded(self, state: State) -> State:
        """`state` with its rows in the unsharded env's order (a gather over the devices)."""
        rows = jax.tree.map(lambda x: x[self._inverse], dataclasses.replace(state, physics=()))
        physics = tuple(
            jax.tree.map(lambda x, inverse=inverse: x[inverse], data)
            for data, inverse in zip(state.physics, self._group_inverse, strict=True)
        )
        return dataclasses.replace(rows, physics=physics)

    def device_env(self) -> Env:
        """Inside a `jax.shard_map` over `self.mesh` (axis `mwjax.sharding.AXIS`, the state split
        along it), the env of the calling device: an `Env` over its rows, as this env runs it.
        For loops that keep more than the env on each device (a training step, say)."""
        share = self.envs_per_task // len(self.devices)
        mine = jax.lax.axis_index(AXIS) * share + jnp.arange(share)  # its envs of each task
        tasks = len(self.local.task_list)
        rows = (np.arange(tasks)[:, None] * self.envs_per_task + mine).ravel()  # unsharded rows
        env = copy.copy(self.local)
        pools = jnp.tile(jnp.asarray(self._env_pools)[mine], (tasks, 1))
        sizes = jnp.tile(jnp.asarray(self._env_pool_sizes)[mine], tasks)
        env.goals = dataclasses.replace(env.goals, pools=pools, pool_sizes=sizes)
        batch = self.num_envs
        env._row_keys = lambda key: jax.random.split(key, batch)[rows]  # type: ignore[method-assign]
        return env

    # ----------------------------------------------------------------------------------------

    def _map(self, name: Any, fn: Callable[..., Any], replicated: tuple[int, ...] = ()) -> Callable[..., Any]:
        """`fn(device_env, *args)` on every device, on its rows of each argument (axis 0), except
        the `replicated` arguments, which every device sees whole. Jitted once per `name`."""
        if name not in self._mapped:

            def run(*args: Any) -> Any:
                specs = tuple(P() if i in replicated else P(AXIS) for i in range(len(args)))
                mapped = jax.shard_map(
                    lambda *args: fn(self.device_env(), *args),
                    mesh=self.mesh,
                    in_specs=specs,
                    out_specs=P(AXIS),
                    check_vma=False,
                )
                return mapped(*args)

            self._mapped[name] = jax.jit(run)
        return self._mapped[name]
