"""box-close: pick the lid and put it on the box."""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np

from mwjax.contracts import Frame, Placement
from mwjax.rewards_v1 import box_close as v1
from mwjax.rewards_v2 import box_close as v2
from mwjax.tasks.spec import TaskSpec, set_object_xyz

_LID_Z = 0.02  # init_config's obj_init_pos z
_LIFT_THRESH = 0.12  # liftThresh: V1's target height above the handle's resting height


def _place(rand_vec: jnp.ndarray, settled: Frame) -> Placement:
    """The box moves under the goal (keeping the height read off the settled scene), the lid to
    rand_vec's start. The core calls this twice: before the reference's in-reset physics steps
    (only `moved_bodies` is used) and after them, on the stepped state, where the lid's
    `_set_obj_xyz` lands."""
    target = rand_vec[3:6]
    box = jnp.concatenate([target[:2], settled.body_pos("boxbody")[2][None]])
    lid = jnp.concatenate([rand_vec[:2], jnp.array([_LID_Z], rand_vec.dtype)])
    qpos, qvel = set_object_xyz(settled, lid)
    return Placement(qpos=qpos, qvel=qvel, target_pos=target, moved_bodies={"boxbody": box})


def _constants(frame: Frame, placement: Placement, settled: Frame) -> dict[str, jnp.ndarray]:
    # Read after set_state's mj_forward on the placed lid.
    obj_init_pos = placement.qpos[9:12]
    obj_height = frame.geom_pos("BoxHandleGeom")[2]
    height_target = obj_height + _LIFT_THRESH
    lifted_start = jnp.concatenate([obj_init_pos[:2], height_target[None]])
    return {
        "obj_init_pos": obj_init_pos,
        "init_tcp": settled.tcp_center,
        "obj_height": obj_height,
        "height_target": height_target,
        "max_placing_dist": jnp.linalg.norm(lifted_start - placement.target_pos) + height_target,
    }


def _lid(frame: Frame) -> tuple[jnp.ndarray, jnp.ndarray]:
    # MuJoCo's xquat of the lid: (w, x, y, z).
    return frame.body_pos("top_link")[None], frame.body_quat("top_link")[None]


def _box_away_from_lid(vec: np.ndarray) -> bool:
    """The reference redraws until the lid's start and the box are at least 25 cm apart in the plane."""
    return bool(np.linalg.norm(vec[:2] - vec[3:5]) >= 0.25)


BOX_CLOSE = TaskSpec(
    name="box-close-v3",
    settle_per_goal=True,
    scene="sawyer_box.xml",
    hand_init_pos=(0.0, 0.6, 0.2),
    random_low=(-0.05, 0.5, 0.02, -0.1, 0.7, 0.133),
    random_high=(0.05, 0.55, 0.02, 0.1, 0.8, 0.133),
    goal_low=(-0.1, 0.7, 0.133),
    goal_high=(0.1, 0.8, 0.133),
    place=_place,
    constants=_constants,
    objects=_lid,
    reward_v2=v2.box_close,
    reward_v1=v1.box_close,
    moved_bodies=("boxbody",),
    # reset_model runs frame_skip physics steps between moving the box and placing the lid.
    reset_env_steps=1,
    rand_vec_valid=_box_away_from_lid,
)

TASKS: tuple[TaskSpec, ...] = (BOX_CLOSE,)
