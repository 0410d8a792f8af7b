"""Sideways handle tasks: a lever on a box that the reset moves, pushed down or pulled up.

Both share `sawyer_handle_press_sideways.xml`, move the `box` body to `rand_vec` and write the
lever's (unnamed) slide joint, qpos[9], with its qvel zeroed (`_set_obj_xyz` then `set_state`,
which runs mj_forward), so every constant below is read off fresh kinematics.

handle-press-v3 and handle-pull-v3 (`sawyer_handle_press.xml`) are not here yet: in that scene the
reference's hand settling touches the box, so the settled state differs per goal variant and one
recorded state per task cannot reproduce it.
"""

from __future__ import annotations

import dataclasses

import jax.numpy as jnp

from mwjax import rewards_v2
from mwjax.tasks.articulated import HAND_INIT, place_fixture
from mwjax.tasks.spec import Frame, ObjectsFn, PlaceFn, Placement, TaskSpec

# The lever joint is unnamed in the scenes; the reference writes qpos[9] / qvel[9] directly.
_LEVER_ADR = 9
# Both tasks move only the box (tasks sharing a scene list the same moved bodies).
_BOX_MOVED = ("box",)
_SIDE_XML = "sawyer_handle_press_sideways.xml"


def _place_box(lever_pos: float) -> PlaceFn:
    """`model.body("box").pos = rand_vec`, then `_set_obj_xyz(lever_pos)` (qpos[9], qvel[9] = 0)."""
    base = place_fixture("box", (0.0, 0.0, 0.0))

    def place(rand_vec: jnp.ndarray, settled: Frame) -> Placement:
        placement = base(rand_vec, settled)
        return dataclasses.replace(
            placement,
            qpos=placement.qpos.at[_LEVER_ADR].set(lever_pos),
            qvel=placement.qvel.at[_LEVER_ADR].set(0.0),
        )

    return place


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
    scene=_SIDE_XML,
    hand_init_pos=HAND_INIT,
    random_low=(-0.35, 0.65, -0.001),
    random_high=(-0.25, 0.75, 0.001),
    place=_place_box(-0.001),
    constants=_press_constants,
    objects=_handle_site("handleStart"),
    reward_v2=rewards_v2.handle_press,
    moved_bodies=_BOX_MOVED,
)

HANDLE_PULL_SIDE = TaskSpec(
    name="handle-pull-side-v3",
    scene=_SIDE_XML,
    hand_init_pos=HAND_INIT,
    random_low=(-0.35, 0.65, 0.0),
    random_high=(-0.25, 0.75, 0.0),
    place=_place_box(-0.1),
    constants=_pull_side_constants,
    objects=_handle_site("handleCenter"),
    reward_v2=rewards_v2.handle_pull_side,
    moved_bodies=_BOX_MOVED,
)

TASKS: tuple[TaskSpec, ...] = (HANDLE_PRESS_SIDE, HANDLE_PULL_SIDE)
