"""What the core, the tasks and the reward kernels exchange: read-only views of one env's physics
and the values passed between them.

Both `mwjax.tasks` (which names each task's reward kernels) and the kernels (`mwjax.rewards_v1`,
`mwjax.rewards_v2`) import this module, and it imports neither, so no import runs back up.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from typing import Any, NamedTuple

import jax
import jax.numpy as jnp
import mujoco

from mwjax.observation import Observation

Array = jax.Array


class Kinematics(NamedTuple):
    """The part of one env's physics state that task code reads (batched or not)."""

    qpos: Any
    qvel: Any
    xpos: Any
    xquat: Any
    site_xpos: Any
    site_xmat: Any
    geom_xpos: Any
    geom_xmat: Any

    @classmethod
    def of(cls, data: Any) -> Kinematics:
        return cls(*(getattr(data, field) for field in cls._fields))

    def rows(self, start: int, stop: int) -> Kinematics:
        return Kinematics(*(x[start:stop] for x in self))


class Frame:
    """Named, read-only access to one env's kinematics (mjx.Data or recorded numpy arrays).

    Positions are as MuJoCo computes them; `body_pos` is the body frame origin (`xpos`, what
    metaworld's `get_body_com` returns).
    """

    def __init__(self, model: mujoco.MjModel, data: Any) -> None:
        self._model = model
        self._data = data

    @property
    def qpos(self) -> Array:
        return self._data.qpos

    @property
    def qvel(self) -> Array:
        return self._data.qvel

    def body_pos(self, name: str) -> Array:
        return self._data.xpos[self._model.body(name).id]

    def body_quat(self, name: str) -> Array:
        return self._data.xquat[self._model.body(name).id]

    def site_pos(self, name: str) -> Array:
        return self._data.site_xpos[self._model.site(name).id]

    def site_xmat(self, name: str) -> Array:
        return self._data.site_xmat[self._model.site(name).id].reshape(3, 3)

    def geom_pos(self, name: str) -> Array:
        return self._data.geom_xpos[self._model.geom(name).id]

    def geom_xmat(self, name: str) -> Array:
        return self._data.geom_xmat[self._model.geom(name).id].reshape(3, 3)

    def joint_qpos(self, name: str) -> Array:
        return self._data.qpos[self._model.joint(name).qposadr[0]]

    def joint_qposadr(self, name: str) -> int:
        return int(self._model.joint(name).qposadr[0])

    def joint_dofadr(self, name: str) -> int:
        return int(self._model.joint(name).dofadr[0])

    # The gripper vocabulary every Sawyer task shares.
    @property
    def hand_pos(self) -> Array:
        return self.body_pos("hand")

    @property
    def tcp_center(self) -> Array:
        return (self.site_pos("rightEndEffector") + self.site_pos("leftEndEffector")) / 2.0

    @property
    def left_pad(self) -> Array:
        return self.body_pos("leftpad")

    @property
    def right_pad(self) -> Array:
        return self.body_pos("rightpad")

    @property
    def gripper_distance(self) -> Array:
        """Finger separation normalised to [0, 1] (fingers open ~0.1 m apart)."""
        gap = jnp.linalg.norm(self.body_pos("rightclaw") - self.body_pos("leftclaw"))
        return jnp.clip(gap / 0.1, 0.0, 1.0)


@jax.tree_util.register_dataclass
@dataclasses.dataclass(frozen=True)
class Placement:
    """What `place` decides at reset, for one env."""

    qpos: Array
    qvel: Array
    target_pos: Array
    moved_bodies: Mapping[str, Array] = dataclasses.field(default_factory=dict)


@dataclasses.dataclass(frozen=True)
class StepInputs:
    """Everything a reward kernel may read after a step, for one env."""

    frame: Frame
    obs: Observation
    action: Array
    target_pos: Array
    constants: Mapping[str, Array]
