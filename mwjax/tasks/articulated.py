"""Tasks on a hinged or sliding fixture that the reset moves: door, drawer, window, button."""

from __future__ import annotations

from collections.abc import Sequence

import jax.numpy as jnp

from mwjax.contracts import Frame, Placement
from mwjax.rewards_v1 import articulated as v1
from mwjax.rewards_v2 import articulated as v2
from mwjax.tasks.spec import ConstantsFn, ObjectsFn, PlaceFn, TaskSpec, quat_from_xmat

HAND_INIT = (0.0, 0.6, 0.2)


def place_fixture(
    body: str,
    goal_offset: Sequence[float],
    joint: str | int | None = None,
    joint_pos: float = 0.0,
    zero_joint_qvel: bool = False,
) -> PlaceFn:
    """The shared reset of a fixture task: `model.body(body).pos = rand_vec`, goal at
    `rand_vec + goal_offset`, and optionally one joint's qpos written (its qvel zeroed only when
    the reference's `_set_obj_xyz` does so). Everything else stays as `_reset_hand` left it.

    `joint` is a joint name, or for an unnamed 1-dof joint the index the reference writes in both
    qpos and qvel (`qpos[9]`, `qvel[9]`)."""

    def place(rand_vec: jnp.ndarray, settled: Frame) -> Placement:
        qpos, qvel = settled.qpos, settled.qvel
        if joint is not None:
            if isinstance(joint, int):
                qpos_adr = dof_adr = joint
            else:
                qpos_adr, dof_adr = settled.joint_qposadr(joint), settled.joint_dofadr(joint)
            qpos = qpos.at[qpos_adr].set(joint_pos)
            if zero_joint_qvel:
                qvel = qvel.at[dof_adr].set(0.0)
        return Placement(
            qpos=qpos,
            qvel=qvel,
            target_pos=rand_vec[:3] + jnp.asarray(goal_offset, rand_vec.dtype),
            moved_bodies={body: rand_vec[:3]},
        )

    return place


# ---- door-open, drawer-open, drawer-close ------------------------------------------------------

# The drawer's handle relative to the `drawer_link` body origin, as each task reports it.
_DRAWER_OPEN_HANDLE = (0.0, -0.16, 0.0)
# drawer-close reports a point 5 cm higher than drawer-open does (its goal z stays at +0.09).
_DRAWER_CLOSE_HANDLE = (0.0, -0.16, 0.05)
# Both drawer tasks move the same body of the shared scene, so they list the same moved bodies.
_DRAWER_MOVED = ("drawer",)


def _door_handle(frame: Frame) -> tuple[jnp.ndarray, jnp.ndarray]:
    # scipy's as_quat of the handle geom's rotation: (x, y, z, w).
    return frame.geom_pos("handle")[None], quat_from_xmat(frame.geom_xmat("handle"))[None]


def _drawer_open_handle(frame: Frame) -> tuple[jnp.ndarray, jnp.ndarray]:
    # MuJoCo's xquat of drawer_link: (w, x, y, z), unlike the door's scipy quaternion.
    pos = frame.body_pos("drawer_link") + jnp.asarray(_DRAWER_OPEN_HANDLE)
    return pos[None], frame.body_quat("drawer_link")[None]


def _drawer_close_handle(frame: Frame) -> tuple[jnp.ndarray, jnp.ndarray]:
    # Reference quirk: drawer-close reports an all-zero quaternion for the drawer.
    pos = frame.body_pos("drawer_link") + jnp.asarray(_DRAWER_CLOSE_HANDLE)
    return pos[None], jnp.zeros((1, 4), pos.dtype)


def _door_open_constants(frame: Frame, placement: Placement, settled: Frame) -> dict[str, jnp.ndarray]:
    # V1's maxPullDist: the closed handle's xy distance to the goal, after _set_obj_xyz's mj_forward.
    pull = jnp.linalg.norm(frame.geom_pos("handle")[:2] - placement.target_pos[:2])
    return {"max_pull_dist": pull}


def _init_tcp(frame: Frame, placement: Placement, settled: Frame) -> dict[str, jnp.ndarray]:
    # init_tcp is taken at the end of _reset_hand, before the fixture moves.
    return {"init_tcp": settled.tcp_center}


def _drawer_close_constants(frame: Frame, placement: Placement, settled: Frame) -> dict[str, jnp.ndarray]:
    # obj_init_pos = _get_pos_objects() after set_state (mj_forward): the pulled-out handle.
    return {
        "obj_init_pos": _drawer_close_handle(frame)[0][0],
        "init_tcp": settled.tcp_center,
    }


DOOR_OPEN = TaskSpec(
    name="door-open-v3",
    scene="sawyer_door_pull.xml",
    hand_init_pos=HAND_INIT,
    random_low=(0.0, 0.85, 0.15),
    random_high=(0.1, 0.95, 0.15),
    goal_low=(-0.3, 0.4, 0.1499),
    goal_high=(-0.2, 0.5, 0.1501),
    # _set_obj_xyz(0): door hinge closed and its velocity zeroed.
    place=place_fixture("door", (-0.3, -0.45, 0.0), joint="doorjoint", joint_pos=0.0, zero_joint_qvel=True),
    constants=_door_open_constants,
    objects=_door_handle,
    reward_v2=v2.door_open,
    reward_v1=v1.door_open,
    moved_bodies=("door",),
)

DRAWER_OPEN = TaskSpec(
    name="drawer-open-v3",
    scene="sawyer_drawer.xml",
    hand_init_pos=HAND_INIT,
    random_low=(-0.1, 0.9, 0.0),
    random_high=(0.1, 0.9, 0.0),
    # No joint write: the drawer slide keeps its settled qpos (target = closed handle - maxDist 0.2).
    place=place_fixture("drawer", (0.0, -0.16 - 0.2, 0.09)),
    constants=_init_tcp,
    objects=_drawer_open_handle,
    reward_v2=v2.drawer_open,
    reward_v1=v1.drawer_open,
    moved_bodies=_DRAWER_MOVED,
)

DRAWER_CLOSE = TaskSpec(
    name="drawer-close-v3",
    scene="sawyer_drawer.xml",
    hand_init_pos=HAND_INIT,
    random_low=(-0.1, 0.9, 0.0),
    random_high=(0.1, 0.9, 0.0),
    # Reference quirk: its _set_obj_xyz(-maxDist) writes qpos[9] only and keeps the drawer's qvel.
    place=place_fixture("drawer", (0.0, -0.16, 0.09), joint="goal_slidey", joint_pos=-0.15),
    constants=_drawer_close_constants,
    objects=_drawer_close_handle,
    reward_v2=v2.drawer_close,
    reward_v1=v1.drawer_close,
    moved_bodies=_DRAWER_MOVED,
)

_DOOR_DRAWER_TASKS = (DOOR_OPEN, DRAWER_OPEN, DRAWER_CLOSE)

# ---- door-close, door-lock, door-unlock ---------------------------------------------------------

# door-close starts its hand far left, beside the open door.
_HAND_INIT_DOOR_CLOSE = (-0.5, 0.6, 0.2)
# The lock tasks' hand box (and so mocap box and door-lock's goal box) reaches below the table.
_LOCK_HAND_LOW = (-0.5, 0.40, -0.15)
# The lock's hinge is unnamed; the reference writes qpos[9] / qvel[9] directly.
_LOCK_ADR = 9
# Goals relative to the lock's hinge (lock_link's origin): down for lock, sideways for unlock.
_LOCK_GOAL_OFFSET = (0.0, -0.04, -0.1)
_UNLOCK_GOAL_OFFSET = (0.1, -0.04, 0.0)


def _door_close_constants(frame: Frame, placement: Placement, settled: Frame) -> dict[str, jnp.ndarray]:
    handle = frame.geom_pos("handle")
    return {
        "obj_init_pos": placement.moved_bodies["door"],  # rand_vec: the door body position
        # V2's hand margin starts at the nominal hand_init_pos (float32 in the reference).
        "hand_init_pos": jnp.asarray(_HAND_INIT_DOOR_CLOSE, jnp.float32),
        # V1's maxPullDist: the opened handle's xy distance to the goal, after set_state.
        "max_pull_dist": jnp.linalg.norm(handle[:2] - placement.target_pos[:2]),
    }


def _lock_objects(site: str) -> ObjectsFn:
    def objects(frame: Frame) -> tuple[jnp.ndarray, jnp.ndarray]:
        # MuJoCo's xquat of the (fixed) door: (w, x, y, z).
        return frame.site_pos(site)[None], frame.body_quat("door_link")[None]

    return objects


def _lock_constants(goal_offset: Sequence[float]) -> ConstantsFn:
    """The goal is lock_link's position after the reset (plus `goal_offset`), a fresh copy; V1's
    maxPullDist is the offset's length."""

    def constants(frame: Frame, placement: Placement, settled: Frame) -> dict[str, jnp.ndarray]:
        offset = jnp.asarray(goal_offset, jnp.float32)
        return {
            "target_pos": frame.body_pos("lock_link") + offset,
            "init_tcp": settled.tcp_center,
            "max_pull_dist": jnp.linalg.norm(offset),
        }

    return constants


DOOR_CLOSE = TaskSpec(
    name="door-close-v3",
    scene="sawyer_door_pull.xml",
    hand_init_pos=_HAND_INIT_DOOR_CLOSE,
    random_low=(0.0, 0.85, 0.15),
    random_high=(0.1, 0.95, 0.15),
    goal_low=(0.2, 0.65, 0.1499),
    goal_high=(0.3, 0.75, 0.1501),
    # _set_obj_xyz(-1.5708): the door starts swung open, its hinge velocity zeroed.
    place=place_fixture("door", (0.2, -0.2, 0.0), joint="doorjoint", joint_pos=-1.5708, zero_joint_qvel=True),
    constants=_door_close_constants,
    objects=_door_handle,
    reward_v2=v2.door_close,
    reward_v1=v1.door_close,
    moved_bodies=("door",),  # door-open shares the scene
)

DOOR_LOCK = TaskSpec(
    name="door-lock-v3",
    settle_per_goal=True,
    scene="sawyer_door_lock.xml",
    hand_init_pos=HAND_INIT,
    random_low=(-0.1, 0.8, 0.15),
    random_high=(0.1, 0.85, 0.15),
    hand_low=_LOCK_HAND_LOW,
    # No joint write: reset_model moves the door, then runs one env step of physics (the lock
    # settles under gravity) before it reads the lock.
    place=place_fixture("door", (0.0, 0.0, 0.0)),
    reset_env_steps=1,
    constants=_lock_constants(_LOCK_GOAL_OFFSET),
    objects=_lock_objects("lockStartLock"),
    reward_v2=v2.door_lock,
    reward_v1=v1.door_lock,
    moved_bodies=("door",),
)

DOOR_UNLOCK = TaskSpec(
    name="door-unlock-v3",
    settle_per_goal=True,
    scene="sawyer_door_lock.xml",
    hand_init_pos=HAND_INIT,
    random_low=(-0.1, 0.8, 0.15),
    random_high=(0.1, 0.85, 0.15),
    hand_low=_LOCK_HAND_LOW,
    goal_low=(0.0, 0.64, 0.2100),
    goal_high=(0.2, 0.7, 0.2111),
    # _set_obj_xyz(1.5708): the lock starts turned down (locked), its velocity zeroed.
    place=place_fixture("door", (0.0, 0.0, 0.0), joint=_LOCK_ADR, joint_pos=1.5708, zero_joint_qvel=True),
    constants=_lock_constants(_UNLOCK_GOAL_OFFSET),
    objects=_lock_objects("lockStartUnlock"),
    reward_v2=v2.door_unlock,
    reward_v1=v1.door_unlock,
    moved_bodies=("door",),
)

_DOOR_LOCK_TASKS = (DOOR_CLOSE, DOOR_LOCK, DOOR_UNLOCK)

# ---- button-press-topdown, window ---------------------------------------------------------------

# These tasks start the hand at y = 0.4 (the door/drawer tasks use 0.6).
_HAND_INIT_NEAR = (0.0, 0.4, 0.2)
# window-open and window-close share their scene, so they list the same moved bodies.
_WINDOW_MOVED = ("window",)


def _button_objects(offset: Sequence[float]) -> ObjectsFn:
    """The button body origin shifted to its face (`offset`), with MuJoCo's xquat (w, x, y, z)."""

    def objects(frame: Frame) -> tuple[jnp.ndarray, jnp.ndarray]:
        pos = frame.body_pos("button") + jnp.asarray(offset)
        return pos[None], frame.body_quat("button")[None]

    return objects


def _button_constants(axis: int) -> ConstantsFn:
    """Read after mj_forward (or set_state) on the moved box: the goal is the site "hole", not
    rand_vec, and the initial press distance is measured along the press `axis`."""

    def constants(frame: Frame, placement: Placement, settled: Frame) -> dict[str, jnp.ndarray]:
        target = frame.site_pos("hole")
        return {
            "target_pos": target,
            "init_tcp": settled.tcp_center,
            "obj_to_target_init": jnp.abs(target[axis] - frame.site_pos("buttonStart")[axis]),
        }

    return constants


# Top-down buttons are pressed along z (face 0.193 above the body), front buttons along y.
_button_topdown = _button_objects((0.0, 0.0, 0.193))
_button_front = _button_objects((0.0, -0.193, 0.0))
_button_topdown_constants = _button_constants(2)
_button_front_constants = _button_constants(1)
# The top-down tasks move only the box (mj_forward, no joint write): the button keeps its settled
# joint state. The goal placed here is replaced by the "hole" site in constants.
_place_button_topdown = place_fixture("box", (0.0, 0.0, 0.0))
# The front tasks' _set_obj_xyz(0) writes the button joint (qpos[9]) and zeroes its qvel.
_place_button_front = place_fixture(
    "box", (0.0, 0.0, 0.0), joint="btnbox_joint", joint_pos=0.0, zero_joint_qvel=True
)


def _stale_window_site(frame: Frame, settled: Frame, site: str) -> jnp.ndarray:
    """A window site as reset_model reads it, before any mj_forward: kinematics are those of
    `_reset_hand`, where the window body already sits at this episode's position (the first of the
    two reset_model calls per reset moved it) and the slide joint is in its settled state."""
    return frame.body_pos("window") + (settled.site_pos(site) - settled.body_pos("window"))


def _window_open_handle(frame: Frame) -> tuple[jnp.ndarray, jnp.ndarray]:
    # Reference: _get_quat_objects is np.zeros(4).
    pos = frame.site_pos("handleOpenStart")
    return pos[None], jnp.zeros((1, 4), pos.dtype)


def _window_close_handle(frame: Frame) -> tuple[jnp.ndarray, jnp.ndarray]:
    pos = frame.site_pos("handleCloseStart")
    return pos[None], jnp.zeros((1, 4), pos.dtype)


def _window_open_constants(frame: Frame, placement: Placement, settled: Frame) -> dict[str, jnp.ndarray]:
    return {
        "obj_init_pos": placement.moved_bodies["window"],  # rand_vec: the window body position
        "init_tcp": settled.tcp_center,
        "window_handle_pos_init": _stale_window_site(frame, settled, "handleOpenStart"),
    }


def _window_close_constants(frame: Frame, placement: Placement, settled: Frame) -> dict[str, jnp.ndarray]:
    # Quirk: read before the slide is set to 0.2 (stale, slide settled at 0), then shifted +0.2 in
    # x by hand, which lands on the handle of the opened window the reset actually places.
    handle = _stale_window_site(frame, settled, "handleCloseStart") + jnp.asarray((0.2, 0.0, 0.0))
    return {
        "obj_init_pos": placement.moved_bodies["window"],
        "init_tcp": settled.tcp_center,
        "window_handle_pos_init": handle,
    }


BUTTON_PRESS_TOPDOWN = TaskSpec(
    name="button-press-topdown-v3",
    scene="sawyer_button_press_topdown.xml",
    hand_init_pos=_HAND_INIT_NEAR,
    random_low=(-0.1, 0.8, 0.115),
    random_high=(0.1, 0.9, 0.115),
    place=_place_button_topdown,
    constants=_button_topdown_constants,
    objects=_button_topdown,
    reward_v2=v2.button_press_topdown,
    reward_v1=v1.button_press_topdown,
    moved_bodies=("box",),
)

WINDOW_OPEN = TaskSpec(
    name="window-open-v3",
    scene="sawyer_window_horizontal.xml",
    hand_init_pos=_HAND_INIT_NEAR,
    random_low=(-0.1, 0.7, 0.16),
    random_high=(0.1, 0.9, 0.16),
    # data.joint("window_slide").qpos = 0 is a bare write: the slide's qvel is kept.
    place=place_fixture("window", (0.2, 0.0, 0.0), joint="window_slide", joint_pos=0.0),
    constants=_window_open_constants,
    objects=_window_open_handle,
    reward_v2=v2.window_open,
    reward_v1=v1.window_open,
    moved_bodies=_WINDOW_MOVED,
)

WINDOW_CLOSE = TaskSpec(
    name="window-close-v3",
    scene="sawyer_window_horizontal.xml",
    hand_init_pos=_HAND_INIT_NEAR,
    random_low=(0.0, 0.75, 0.2),
    random_high=(0.0, 0.9, 0.2),
    # The window starts open (slide 0.2, bare qpos write); the goal is rand_vec itself.
    place=place_fixture("window", (0.0, 0.0, 0.0), joint="window_slide", joint_pos=0.2),
    constants=_window_close_constants,
    objects=_window_close_handle,
    reward_v2=v2.window_close,
    reward_v1=v1.window_close,
    moved_bodies=_WINDOW_MOVED,
)

BUTTON_PRESS_TOPDOWN_WALL = TaskSpec(
    name="button-press-topdown-wall-v3",
    scene="sawyer_button_press_topdown_wall.xml",
    hand_init_pos=_HAND_INIT_NEAR,
    random_low=(-0.1, 0.8, 0.115),
    random_high=(0.1, 0.9, 0.115),
    place=_place_button_topdown,
    constants=_button_topdown_constants,
    objects=_button_topdown,
    reward_v2=v2.button_press_topdown_wall,
    reward_v1=v1.button_press_topdown_wall,
    moved_bodies=("box",),
)

BUTTON_PRESS = TaskSpec(
    name="button-press-v3",
    scene="sawyer_button_press.xml",
    hand_init_pos=_HAND_INIT_NEAR,
    random_low=(-0.1, 0.85, 0.115),
    random_high=(0.1, 0.9, 0.115),
    place=_place_button_front,
    constants=_button_front_constants,
    objects=_button_front,
    reward_v2=v2.button_press,
    reward_v1=v1.button_press,
    moved_bodies=("box",),
)

BUTTON_PRESS_WALL = TaskSpec(
    name="button-press-wall-v3",
    scene="sawyer_button_press_wall.xml",
    hand_init_pos=_HAND_INIT_NEAR,
    random_low=(-0.05, 0.85, 0.1149),
    random_high=(0.05, 0.9, 0.1151),
    place=_place_button_front,
    constants=_button_front_constants,
    objects=_button_front,
    reward_v2=v2.button_press_wall,
    reward_v1=v1.button_press_wall,
    moved_bodies=("box",),
)

_BUTTON_WINDOW_TASKS = (
    BUTTON_PRESS_TOPDOWN,
    WINDOW_OPEN,
    WINDOW_CLOSE,
    BUTTON_PRESS_TOPDOWN_WALL,
    BUTTON_PRESS,
    BUTTON_PRESS_WALL,
)

TASKS: tuple[TaskSpec, ...] = (*_DOOR_DRAWER_TASKS, *_DOOR_LOCK_TASKS, *_BUTTON_WINDOW_TASKS)
