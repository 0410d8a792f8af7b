"""The Sawyer observation's layout, by name: the one place that knows which of its 39 values is what.

The reference's observation is two 18-value frames and the goal:

    [ hand (3) | gripper (1) | obj (3) | obj_quat (4) | obj2 (3) | obj2_quat (4) ]   this step
    [ the same 18 values, as the previous step left them                        ]
    [ goal (3), zeros when it is hidden                                         ]

A task with one object has zeros for `obj2`/`obj2_quat`; a task reports its objects' orientations
as its reference does (MuJoCo's w-first `xquat`, or scipy's w-last quaternion). Rewards, experts,
the core and the wrappers read fields through `Observation` rather than slicing by hand.
"""

from __future__ import annotations

from typing import NamedTuple

import jax

Array = jax.Array

OBS_SIZE = 39
FRAME_SIZE = 18
OBJECTS_SIZE = 14  # up to two objects, position + quaternion each


class Observation(NamedTuple):
    """A named view of one env's observation (39,) (or of a batch's, `(..., 39)`); reading a field
    slices the vector, nothing is copied or computed."""

    vector: Array

    @property
    def hand(self) -> Array:
        """The hand's position (3,)."""
        return self.vector[..., 0:3]

    @property
    def gripper(self) -> Array:
        """The gripper's opening, finger separation normalised to [0, 1] (a scalar)."""
        return self.vector[..., 3]

    @property
    def obj(self) -> Array:
        """The first object's position (3,)."""
        return self.vector[..., 4:7]

    @property
    def obj_quat(self) -> Array:
        """The first object's quaternion (4,)."""
        return self.vector[..., 7:11]

    @property
    def obj2(self) -> Array:
        """The second object's position (3,)."""
        return self.vector[..., 11:14]

    @property
    def obj2_quat(self) -> Array:
        """The second object's quaternion (4,)."""
        return self.vector[..., 14:18]

    @property
    def frame(self) -> Array:
        """This step's 18 values: hand, gripper and objects."""
        return self.vector[..., :FRAME_SIZE]

    @property
    def previous_frame(self) -> Array:
        """The previous step's 18 values (at a reset, this step's again)."""
        return self.vector[..., FRAME_SIZE : 2 * FRAME_SIZE]

    @property
    def goal(self) -> Array:
        """The goal position (3,), zeros when the env is partially observable."""
        return self.vector[..., 2 * FRAME_SIZE : OBS_SIZE]
