"""Ball tasks: basketball (pick and dunk) and soccer (push into a goal)."""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np

from mwjax.contracts import Frame, Placement
from mwjax.rewards_v1 import ball as v1
from mwjax.rewards_v2 import ball as v2
from mwjax.tasks.spec import TaskSpec, quat_from_xmat, set_object_xyz

# Both balls start at init_config's height, whatever rand_vec's object z.
_BALL_Z = 0.03


def _ball_apart_from_goal(vec: np.ndarray) -> bool:
    """The reference redraws until ball and goal are at least 15 cm apart in the plane."""
    return bool(np.linalg.norm(vec[:2] - vec[3:5]) >= 0.15)


def _place_ball(rand_vec: jnp.ndarray, settled: Frame, goal_body: str) -> Placement:
    obj_init_pos = jnp.concatenate([rand_vec[:2], jnp.asarray([_BALL_Z], rand_vec.dtype)])
    qpos, qvel = set_object_xyz(settled, obj_init_pos)
    return Placement(qpos=qpos, qvel=qvel, target_pos=rand_vec[3:6], moved_bodies={goal_body: rand_vec[3:6]})


# ---- basketball ---------------------------------------------------------------------------------


def _basketball_objects(frame: Frame) -> tuple[jnp.ndarray, jnp.ndarray]:
    return frame.body_pos("bsktball")[None], frame.body_quat("bsktball")[None]


def _place_basketball(rand_vec: jnp.ndarray, settled: Frame) -> Placement:
    return _place_ball(rand_vec, settled, "basket_goal")


def _basketball_constants(frame: Frame, placement: Placement, settled: Frame) -> dict[str, jnp.ndarray]:
    obj_init_pos = placement.qpos[9:12]
    # The goal is the hoop's "goal" site. Reference quirk: `_target_pos` is a live view of that
    # site's xpos, read before the reset's mj_forward and written back into `model.site_pos`.
    # Neither matters: the view is read after the forward (the placed hoop), the site shares its
    # body's frame (MuJoCo ignores site_pos for such sites), and the hoop never moves afterwards,
    # so the placed site position is the goal for the whole episode.
    target = frame.site_pos("goal")
    obj_height = frame.geom_pos("objGeom")[2]
    height_target = obj_height + 0.3  # liftThresh
    above_start = jnp.concatenate([obj_init_pos[:2], height_target[None]])
    return {
        "target_pos": target,
        "obj_init_pos": obj_init_pos,
        "init_tcp": settled.tcp_center,
        "obj_height": obj_height,
        "height_target": height_target,
        "max_placing_dist": jnp.linalg.norm(above_start - target) + height_target,
    }


BASKETBALL = TaskSpec(
    name="basketball-v3",
    scene="sawyer_basketball.xml",
    hand_init_pos=(0.0, 0.6, 0.2),
    random_low=(-0.1, 0.6, 0.0299, -0.1, 0.85, 0.0),
    random_high=(0.1, 0.7, 0.0301, 0.1, 0.9 + 1e-7, 0.0),
    # The reference's goal space is the basket box shifted to the hoop (0, -0.083, 0.25).
    goal_low=(-0.1, 0.85 - 0.083, 0.2499),
    goal_high=(0.1, 0.9 + 1e-7 - 0.083, 0.2501),
    place=_place_basketball,
    constants=_basketball_constants,
    objects=_basketball_objects,
    reward_v2=v2.basketball,
    reward_v1=v1.basketball,
    moved_bodies=("basket_goal",),
    rand_vec_valid=_ball_apart_from_goal,
)


# ---- soccer -------------------------------------------------------------------------------------


def _soccer_objects(frame: Frame) -> tuple[jnp.ndarray, jnp.ndarray]:
    # scipy's (x, y, z, w) quaternion of the ball body's rotation, which its collision sphere
    # shares.
    return frame.body_pos("soccer_ball")[None], quat_from_xmat(frame.geom_xmat("objGeom"))[None]


def _place_soccer(rand_vec: jnp.ndarray, settled: Frame) -> Placement:
    return _place_ball(rand_vec, settled, "goal_whole")


def _soccer_constants(frame: Frame, placement: Placement, settled: Frame) -> dict[str, jnp.ndarray]:
    obj_init_pos = placement.qpos[9:12]
    return {
        "obj_init_pos": obj_init_pos,
        "init_tcp": settled.tcp_center,
        "max_push_dist": jnp.linalg.norm(obj_init_pos[:2] - placement.target_pos[:2]),
    }


SOCCER = TaskSpec(
    name="soccer-v3",
    scene="sawyer_soccer.xml",
    hand_init_pos=(0.0, 0.6, 0.2),
    random_low=(-0.1, 0.6, 0.03, -0.1, 0.8, 0.0),
    random_high=(0.1, 0.7, 0.03, 0.1, 0.9, 0.0),
    goal_low=(-0.1, 0.8, 0.0),
    goal_high=(0.1, 0.9, 0.0),
    place=_place_soccer,
    constants=_soccer_constants,
    objects=_soccer_objects,
    reward_v2=v2.soccer,
    reward_v1=v1.soccer,
    moved_bodies=("goal_whole",),
    rand_vec_valid=_ball_apart_from_goal,
)

TASKS: tuple[TaskSpec, ...] = (BASKETBALL, SOCCER)
