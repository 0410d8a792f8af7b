"""Handle tasks: a lever on a box that the reset moves, pushed down or pulled up.

The sideways tasks share `sawyer_handle_press_sideways.xml`, handle-press and handle-pull share
`sawyer_handle_press.xml`. All move the `box` body to `rand_vec` and write the lever's (unnamed)
slide joint, qpos[9], with its qvel zeroed (`_set_obj_xyz` then `set_state`, which runs
mj_forward), so every constant below is read off fresh kinematics.
"""

from __future__ import annotations

import jax.numpy as jnp

from mwjax.contracts import Frame, Placement
from mwjax.rewards_v1 import handles as v1
from mwjax.rewards_v2 import handles as v2
from mwjax.tasks.articulated import HAND_INIT, place_fixture
from mwjax.tasks.spec import ObjectsFn, PlaceFn, TaskSpec

# The lever joint is unnamed in the scenes; the reference writes qpos[9] / qvel[9] directly.
_LEVER_ADR = 9
# Every handle task moves only the box (tasks sharing a scene list the same moved bodies).
_BOX_MOVED = ("box",)
_SIDE_XML = "sawyer_handle_press_sideways.xml"


def _place_box(lever_pos: float) -> PlaceFn:
    """`model.body("box").pos = rand_vec`, then `_set_obj_xyz(lever_pos)` (qpos[9], qvel[9] = 0)."""
    return place_fixture("box", (0.0, 0.0, 0.0), joint=_LEVER_ADR, joint_pos=lever_pos, zero_joint_qvel=True)


def _handle_site(site: str) -> ObjectsFn:
    def objects(frame: Frame) -> tuple[jnp.ndarray, jnp.ndarray]:
        # Reference: _get_quat_objects is np.zeros(4).
        pos = frame.site_pos(site)
        return pos[None], jnp.zeros((1, 4), pos.dtype)

    return objects


def _press_constants(frame: Frame, placement: Placement, settled: Frame) -> dict[str, jnp.ndarray]:
    # Goal and initial handle are read after set_state (mj_forward); init_tcp from _reset_hand.
    return {
        "target_pos": frame.site_pos("goalPress"),
        "handle_init_pos": frame.site_pos("handleStart"),
        "init_tcp": settled.tcp_center,
    }


def _pull_side_constants(frame: Frame, placement: Placement, settled: Frame) -> dict[str, jnp.ndarray]:
    # handle-pull-side re-reads obj_init_pos = handleCenter after set_state.
    return {
        "target_pos": frame.site_pos("goalPull"),
        "obj_init_pos": frame.site_pos("handleCenter"),
        "init_tcp": settled.tcp_center,
    }


HANDLE_PRESS_SIDE = TaskSpec(
    name="handle-press-side-v3",
    settle_per_goal=True,
    scene=_SIDE_XML,
    hand_init_pos=HAND_INIT,
    random_low=(-0.35, 0.65, -0.001),
    random_high=(-0.25, 0.75, 0.001),
    place=_place_box(-0.001),
    constants=_press_constants,
    objects=_handle_site("handleStart"),
    reward_v2=v2.handle_press,
    reward_v1=v1.handle_press_side,
    moved_bodies=_BOX_MOVED,
)

HANDLE_PULL_SIDE = TaskSpec(
    name="handle-pull-side-v3",
    settle_per_goal=True,
    scene=_SIDE_XML,
    hand_init_pos=HAND_INIT,
    random_low=(-0.35, 0.65, 0.0),
    random_high=(-0.25, 0.75, 0.0),
    place=_place_box(-0.1),
    constants=_pull_side_constants,
    objects=_handle_site("handleCenter"),
    reward_v2=v2.handle_pull_side,
    reward_v1=v1.handle_pull_side,
    moved_bodies=_BOX_MOVED,
)

_FRONT_XML = "sawyer_handle_press.xml"
# The handleStart site's z in its body (handle_link) frame, which handle-pull's V1 maxDist reads.
_HANDLE_START_LOCAL_Z = 0.022


def _pull_constants(frame: Frame, placement: Placement, settled: Frame) -> dict[str, jnp.ndarray]:
    target = frame.site_pos("goalPull")
    return {
        "target_pos": target,
        "obj_init_pos": placement.moved_bodies["box"],  # rand_vec: the box origin, not the handle
        "init_tcp": settled.tcp_center,
        # Reference quirk: maxDist reads model.site("handleStart").pos, the site's offset in its
        # body frame, instead of its world position.
        "max_pull_dist": jnp.abs(_HANDLE_START_LOCAL_Z - target[2]),
    }


HANDLE_PRESS = TaskSpec(
    name="handle-press-v3",
    settle_per_goal=True,
    scene=_FRONT_XML,
    hand_init_pos=HAND_INIT,
    random_low=(-0.1, 0.8, -0.001),
    random_high=(0.1, 0.9, 0.001),
    goal_low=(-0.1, 0.55, 0.04),
    goal_high=(0.1, 0.70, 0.08),
    place=_place_box(-0.001),
    constants=_press_constants,
    objects=_handle_site("handleStart"),
    reward_v2=v2.handle_press,
    reward_v1=v1.handle_press,
    moved_bodies=_BOX_MOVED,
)

HANDLE_PULL = TaskSpec(
    name="handle-pull-v3",
    settle_per_goal=True,
    scene=_FRONT_XML,
    hand_init_pos=HAND_INIT,
    random_low=(-0.1, 0.8, -0.001),
    random_high=(0.1, 0.9, 0.001),
    goal_low=(-0.1, 0.55, 0.04),
    goal_high=(0.1, 0.70, 0.18),
    place=_place_box(-0.1),
    constants=_pull_constants,
    objects=_handle_site("handleRight"),
    reward_v2=v2.handle_pull,
    reward_v1=v1.handle_pull,
    moved_bodies=_BOX_MOVED,
)

TASKS: tuple[TaskSpec, ...] = (HANDLE_PRESS_SIDE, HANDLE_PULL_SIDE, HANDLE_PRESS, HANDLE_PULL)
