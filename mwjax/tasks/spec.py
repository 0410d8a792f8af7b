"""The declarative description of a task, and the read-only views task code sees.

A task is data plus four small pure functions of one env (they are vmapped by the core):

- `place(rand_vec, settled) -> Placement`: where the reset puts objects, fixed bodies and the goal,
  given the goal variant `rand_vec` and the settled hand state (`Frame` of the data as the
  reference reads it right after `_reset_hand`).
- `constants(frame, placement, settled) -> dict`: per-episode constants the reward reads, computed
  from the kinematics of the placed scene (e.g. the handle position after moving a door). A
  `"target_pos"` entry replaces `placement.target_pos` (for goals read off the placed scene).
- `objects(frame) -> (pos (k, 3), quat (k, 4))`: the object part of the observation.
- `reward_v2(step)` / `reward_v1(step) -> (reward, info)`: the reward of each version and its info
  terms, `info["success"]` included (the reference's success test can differ between versions).

Two rarer hooks: `latch(step) -> dict` updates constants on the first step of an episode (V2's
non-Markov corner, bin-picking), and `reset_env_steps` runs that many env steps of physics between
moving the fixed bodies and `place`'s joint writes, as box-close and door-lock do in their reset.
`settle_per_goal` marks the tasks whose settled state depends on the goal (the settling arm or
objects touch a fixed body that the goal moves).

The core knows nothing else about a task. What task code reads and returns (`Frame`, `Placement`,
`StepInputs`) lives in `mwjax.contracts`, which the reward kernels import too.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable

import jax
import jax.numpy as jnp
import numpy as np

from mwjax.contracts import Frame, Placement, StepInputs

Array = jax.Array


PlaceFn = Callable[[Array, Frame], Placement]
ConstantsFn = Callable[[Frame, Placement, Frame], dict[str, Array]]
ObjectsFn = Callable[[Frame], tuple[Array, Array]]
RewardFn = Callable[[StepInputs], tuple[Array, dict[str, Array]]]
LatchFn = Callable[[StepInputs], dict[str, Array]]


def _no_constants(frame: Frame, placement: Placement, settled: Frame) -> dict[str, Array]:
    return {}


# The hand box (`hand_low`/`hand_high`) that all but a few reference tasks declare.
HAND_LOW, HAND_HIGH = (-0.5, 0.40, 0.05), (0.5, 1.0, 0.5)


@dataclasses.dataclass(frozen=True)
class TaskSpec:
    """One Meta-World task. Bounds are the reference's, in metres.

    `goal_low`/`goal_high` are the reference's `goal_space`, which step observations clip the goal
    to; left out, they are the hand box, as many reference tasks declare it. The mocap box
    defaults to the hand box, as in the reference.
    """

    name: str
    scene: str
    hand_init_pos: tuple[float, float, float]
    random_low: tuple[float, ...]
    random_high: tuple[float, ...]
    place: PlaceFn
    objects: ObjectsFn
    reward_v2: RewardFn
    reward_v1: RewardFn
    constants: ConstantsFn = _no_constants
    # Constants the reference sets on the first step of an episode; `constants` must give each
    # key a placeholder of the same shape at reset.
    latch: LatchFn | None = None
    # Env steps (each `frame_skip` physics steps) the reference runs inside reset_model after
    # moving fixed bodies; `place` is then applied again to the stepped state (its `settled`).
    reset_env_steps: int = 0
    # The reference settles the hand (`_reset_hand`) with the fixed bodies already at the goal;
    # where the settling arm or objects touch them, the settled state is a function of the goal,
    # computed per goal variant (`mwjax.env`) instead of read from the recording.
    settle_per_goal: bool = False
    hand_low: tuple[float, float, float] = HAND_LOW
    hand_high: tuple[float, float, float] = HAND_HIGH
    goal_low: tuple[float, float, float] | None = None
    goal_high: tuple[float, float, float] | None = None
    mocap_low: tuple[float, float, float] | None = None
    mocap_high: tuple[float, float, float] | None = None
    moved_bodies: tuple[str, ...] = ()
    # The reference redraws rand_vec inside reset_model until this holds (numpy, host side).
    rand_vec_valid: Callable[[np.ndarray], bool] = lambda vec: True

    @property
    def mocap_bounds(self) -> tuple[np.ndarray, np.ndarray]:
        low = self.hand_low if self.mocap_low is None else self.mocap_low
        high = self.hand_high if self.mocap_high is None else self.mocap_high
        return np.asarray(low, np.float32), np.asarray(high, np.float32)

    @property
    def goal_bounds(self) -> tuple[np.ndarray, np.ndarray]:
        low = self.hand_low if self.goal_low is None else self.goal_low
        high = self.hand_high if self.goal_high is None else self.goal_high
        return np.asarray(low, np.float32), np.asarray(high, np.float32)


def set_object_xyz(settled: Frame, pos: Array, qpos_adr: int = 9, qvel_adr: int = 9) -> tuple[Array, Array]:
    """metaworld's `_set_obj_xyz` for a free joint: position set, its 6 velocities zeroed."""
    qpos = settled.qpos.at[qpos_adr : qpos_adr + 3].set(pos)
    qvel = settled.qvel.at[qvel_adr : qvel_adr + 6].set(0.0)
    return qpos, qvel


@jax.jit  # ~20 small ops: traced once per shape, not at each of a set's ~50 uses per program
def quat_from_xmat(mat: Array) -> Array:
    """scipy's `Rotation.from_matrix(mat).as_quat()` (x, y, z, w), with scipy's sign choice.

    Several reference tasks report object orientation this way instead of MuJoCo's (w, x, y, z)
    `xquat`; the sign and component order must match for the observation to match.
    """
    diag = jnp.diagonal(mat)
    trace = jnp.sum(diag)
    decision = jnp.concatenate([diag, trace[None]])
    choice = jnp.argmax(decision)

    def from_diagonal(i: int) -> Array:
        j, k = (i + 1) % 3, (i + 2) % 3
        q = jnp.zeros(4, mat.dtype)
        q = q.at[i].set(1.0 - trace + 2.0 * mat[i, i])
        q = q.at[j].set(mat[j, i] + mat[i, j])
        q = q.at[k].set(mat[k, i] + mat[i, k])
        return q.at[3].set(mat[k, j] - mat[j, k])

    from_trace = jnp.stack([mat[2, 1] - mat[1, 2], mat[0, 2] - mat[2, 0], mat[1, 0] - mat[0, 1], 1.0 + trace])
    candidates = jnp.stack([from_diagonal(0), from_diagonal(1), from_diagonal(2), from_trace])
    q = candidates[choice]
    return q / jnp.linalg.norm(q)
