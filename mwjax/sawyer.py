"""The Sawyer arm's interface, over a whole batch: how an action moves the hand and the fingers,
and how an observation is laid out (`mwjax.observation`), bounded and clipped.

Every Meta-World task shares it; a task contributes only its objects' poses (`TaskSpec.objects`)
and its bounds (the mocap box the hand may move in, the goal box observations clip the goal to).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np

from mwjax.contracts import Frame
from mwjax.observation import OBJECTS_SIZE
from mwjax.physics import PhysicsState
from mwjax.tasks.spec import TaskSpec

Array = jax.Array

# The reference's `hand_space`, the observation box of both frames' hand positions.
HAND_SPACE_LOW = np.array([-0.525, 0.348, -0.0525], np.float32)
HAND_SPACE_HIGH = np.array([0.525, 1.025, 0.7], np.float32)
# The hand's mocap orientation, which every action resets.
HAND_QUAT = np.array([1.0, 0.0, 1.0, 0.0], np.float32)
ACTION_SCALE = 1.0 / 100


def check_action(action: Any, num_envs: int) -> Array:
    """`action` as a `(num_envs, 4)` float32 array; refuses (while tracing, too) other shapes and
    non-float dtypes, and, outside a trace, NaN or inf."""
    if isinstance(action, (list, tuple)):
        # Nested lists (under jit, a pytree of scalar tracers) become one array; Python floats
        # give float32, Python ints an int array, refused below like any non-float dtype.
        action = jnp.asarray(action)
    shape = getattr(action, "shape", None)
    if shape is None:
        raise ValueError(f"actions must be a ({num_envs}, 4) array, got {type(action).__name__}")
    if shape != (num_envs, 4):
        raise ValueError(f"actions must have shape ({num_envs}, 4), got {shape}")
    dtype = getattr(action, "dtype", None)
    if dtype is None or not jnp.issubdtype(dtype, jnp.floating):
        raise ValueError(f"actions must be floating point, got dtype {dtype}")
    if not isinstance(action, jax.core.Tracer) and not _all_finite(action):
        raise ValueError("actions contain NaN or inf")
    return jnp.asarray(action, jnp.float32)


def _all_finite(values: Any) -> bool:
    if isinstance(values, jax.Array) and not values.is_fully_addressable:
        return bool(jnp.isfinite(values).all())  # spread over processes: reduced on the devices
    return bool(np.all(np.isfinite(np.asarray(values))))


def frame_obs(spec: TaskSpec, frame: Frame) -> Array:
    """One env's 18-value frame: hand position, gripper opening, then objects (pos + quat, padded)."""
    pos, quat = spec.objects(frame)
    objects = jnp.concatenate([pos, quat], axis=-1).reshape(-1)
    objects = jnp.pad(objects, (0, OBJECTS_SIZE - objects.shape[0]))
    return jnp.concatenate([frame.hand_pos, frame.gripper_distance[None], objects]).astype(jnp.float32)


@dataclasses.dataclass(frozen=True, eq=False)
class Sawyer:
    """The arm's per-env bounds, `(num_envs, 3)` each: the mocap box the hand moves in and the
    goal box; `partially_observable` hides the goal (zeros) in observations."""

    mocap_low: Array
    mocap_high: Array
    goal_low: Array
    goal_high: Array
    partially_observable: bool

    @classmethod
    def of(cls, specs: Sequence[TaskSpec], envs_per_task: int, partially_observable: bool) -> Sawyer:
        """The bounds of a batch of `specs`' tasks, `envs_per_task` rows each."""

        def per_env(values: Sequence[Any]) -> Array:
            return jnp.asarray(np.repeat(np.asarray(values, np.float32), envs_per_task, axis=0))

        return cls(
            mocap_low=per_env([s.mocap_bounds[0] for s in specs]),
            mocap_high=per_env([s.mocap_bounds[1] for s in specs]),
            goal_low=per_env([s.goal_bounds[0] for s in specs]),
            goal_high=per_env([s.goal_bounds[1] for s in specs]),
            partially_observable=partially_observable,
        )

    def apply_action(
        self, groups: Sequence[Any], datas: tuple[PhysicsState, ...], action: Array
    ) -> tuple[PhysicsState, ...]:
        """metaworld's set_xyz_action and gripper control: the hand's mocap moves by
        clip(a, -1, 1) / 100 within the task's mocap box; the fingers get [a3, -a3]. `groups`
        are the physics groups (`Physics.groups`), one data each."""
        delta = jnp.clip(action[:, :3], -1.0, 1.0) * ACTION_SCALE
        out = []
        for group, data in zip(groups, datas, strict=True):
            rows = slice(group.start, group.start + group.size)
            hand = jnp.clip(data.mocap_pos[:, 0] + delta[rows], self.mocap_low[rows], self.mocap_high[rows])
            out.append(
                data.replace(
                    mocap_pos=data.mocap_pos.at[:, 0].set(hand),
                    mocap_quat=data.mocap_quat.at[:, 0].set(jnp.asarray(HAND_QUAT)),
                    ctrl=jnp.stack([action[rows, 3], -action[rows, 3]], axis=-1),
                )
            )
        return tuple(out)

    def observation(self, frame: Array, previous_frame: Array, target_pos: Array) -> Array:
        """The batch's observations `(num_envs, 39)` from its frames and goals (unclipped)."""
        goal = jnp.zeros_like(target_pos) if self.partially_observable else target_pos
        return jnp.concatenate([frame, previous_frame, goal], axis=-1)

    def clip(self, obs: Array) -> Array:
        """The reference clips step observations to its observation space."""
        n = obs.shape[0]
        inf = jnp.full((n, OBJECTS_SIZE), jnp.inf)
        hand_low = jnp.broadcast_to(jnp.asarray(HAND_SPACE_LOW), (n, 3))
        hand_high = jnp.broadcast_to(jnp.asarray(HAND_SPACE_HIGH), (n, 3))
        minus_one, one = -jnp.ones((n, 1)), jnp.ones((n, 1))
        if self.partially_observable:
            goal_low = goal_high = jnp.zeros((n, 3))
        else:
            goal_low, goal_high = self.goal_low, self.goal_high
        low = jnp.concatenate([hand_low, minus_one, -inf, hand_low, minus_one, -inf, goal_low], axis=-1)
        high = jnp.concatenate([hand_high, one, inf, hand_high, one, inf, goal_high], axis=-1)
        return jnp.clip(obs, low, high)

    def observation_bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """The reference's observation box (hand box, gripper [-1, 1], unbounded objects, goal
        box or zeros when hidden), widened over the batch's tasks, whose goal boxes differ."""
        if self.partially_observable:
            goal_low = goal_high = np.zeros(3, np.float32)
        else:
            goal_low = np.min(np.asarray(self.goal_low), axis=0)
            goal_high = np.max(np.asarray(self.goal_high), axis=0)
        frame_low = np.concatenate([HAND_SPACE_LOW, [-1.0], np.full(OBJECTS_SIZE, -np.inf)])
        frame_high = np.concatenate([HAND_SPACE_HIGH, [1.0], np.full(OBJECTS_SIZE, np.inf)])
        low = np.concatenate([frame_low, frame_low, goal_low]).astype(np.float32)
        high = np.concatenate([frame_high, frame_high, goal_high]).astype(np.float32)
        return low, high
