"""Tasks on knobs, handles and levers that turn: faucet-open, faucet-close, dial-turn, lever-pull."""

from __future__ import annotations

import jax.numpy as jnp

from mwjax.contracts import Frame, Placement
from mwjax.rewards_v1 import rotary as v1
from mwjax.rewards_v2 import rotary as v2
from mwjax.tasks.articulated import place_fixture
from mwjax.tasks.spec import ObjectsFn, RewardFn, TaskSpec, quat_from_xmat

# ---- faucet-open, faucet-close -------------------------------------------------------------------

_FAUCET_HANDLE_LENGTH = 0.175
# Both faucet tasks move the same body of the shared scene, so they list the same moved bodies.
_FAUCET_MOVED = ("faucetBase",)
# The faucet tasks let the hand go below the table: hand (and so goal and mocap) box z from -0.15.
_FAUCET_HAND_LOW = (-0.5, 0.40, -0.15)


def _faucet_handle(site: str) -> ObjectsFn:
    """The handle site 1 cm lower, with MuJoCo's xquat (w, x, y, z) of the faucet base."""

    def objects(frame: Frame) -> tuple[jnp.ndarray, jnp.ndarray]:
        pos = frame.site_pos(site) + jnp.asarray((0.0, 0.0, -0.01))
        return pos[None], frame.body_quat("faucetBase")[None]

    return objects


def _faucet_constants(frame: Frame, placement: Placement, settled: Frame) -> dict[str, jnp.ndarray]:
    return {
        "obj_init_pos": placement.moved_bodies["faucetBase"],  # rand_vec: the faucet base position
        "init_tcp": settled.tcp_center,  # taken at the end of _reset_hand
    }


def _faucet(
    name: str, site: str, direction: float, low_x: float, reward: RewardFn, reward_v1: RewardFn
) -> TaskSpec:
    return TaskSpec(
        name=name,
        scene="sawyer_faucet.xml",
        hand_init_pos=(0.0, 0.4, 0.2),
        random_low=(low_x, 0.8, 0.0),
        random_high=(-low_x, 0.85, 0.0),
        hand_low=_FAUCET_HAND_LOW,
        # No joint write: the handle keeps its settled joint state.
        place=place_fixture("faucetBase", (direction * _FAUCET_HANDLE_LENGTH, 0.0, 0.125)),
        constants=_faucet_constants,
        objects=_faucet_handle(site),
        reward_v2=reward,
        reward_v1=reward_v1,
        moved_bodies=_FAUCET_MOVED,
    )


FAUCET_OPEN = _faucet("faucet-open-v3", "handleStartOpen", +1.0, -0.05, v2.faucet_open, v1.faucet_open)
FAUCET_CLOSE = _faucet("faucet-close-v3", "handleStartClose", -1.0, -0.1, v2.faucet_close, v1.faucet_close)

# ---- dial-turn -----------------------------------------------------------------------------------

_DIAL_RADIUS = 0.05


def dial_point(frame: Frame) -> jnp.ndarray:
    """The dial's rim point at its knob angle (the reference's `_get_pos_objects`)."""
    angle = frame.joint_qpos("knob_Joint_1")
    return frame.body_pos("dial") + _DIAL_RADIUS * jnp.stack([jnp.sin(angle), -jnp.cos(angle), 0.0 * angle])


def _dial_objects(frame: Frame) -> tuple[jnp.ndarray, jnp.ndarray]:
    return dial_point(frame)[None], frame.body_quat("dial")[None]


def _dial_constants(frame: Frame, placement: Placement, settled: Frame) -> dict[str, jnp.ndarray]:
    # Read before any mj_forward, but the dial (a fixed body under the world) already sits at
    # rand_vec from the first reset_model call, and the knob angle is read from qpos directly.
    return {
        "dial_push_position": dial_point(frame) + jnp.asarray((0.05, 0.02, 0.09)),
        "init_tcp": settled.tcp_center,
    }


DIAL_TURN = TaskSpec(
    name="dial-turn-v3",
    scene="sawyer_dial.xml",
    hand_init_pos=(0.0, 0.6, 0.2),
    random_low=(-0.1, 0.7, 0.0),
    random_high=(0.1, 0.8, 0.0),
    goal_low=(-0.1, 0.73, 0.0299),
    goal_high=(0.1, 0.83, 0.0301),
    place=place_fixture("dial", (0.0, 0.03, 0.03)),
    constants=_dial_constants,
    objects=_dial_objects,
    reward_v2=v2.dial_turn,
    reward_v1=v1.dial_turn,
    moved_bodies=("dial",),
)

# ---- lever-pull ----------------------------------------------------------------------------------

# The lever's axis sits 12 cm to the side and 25 cm above its base; its handle is 20 cm out.
_LEVER_AXIS = (0.12, 0.0, 0.25)
_LEVER_RADIUS = 0.2


# The handle mesh geom's frame in its link (MuJoCo quaternion, w first) as the reference's MuJoCo
# 3.3.0 compiles it: the mesh's principal axes. The mesh is nearly symmetric, and newer MuJoCo
# versions pick axes turned by about 1e-3 rad, which would show in the observed quaternion.
_HANDLE_IN_LINK = (0.662500038723091, 0.662500038723091, -0.24717139537556432, 0.24717139537556432)


def _rotation_matrix(q: jnp.ndarray) -> jnp.ndarray:
    """The rotation matrix of a unit quaternion (w, x, y, z)."""
    w, x, y, z = q
    return jnp.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
        ]
    )


def _lever_objects(frame: Frame) -> tuple[jnp.ndarray, jnp.ndarray]:
    # scipy's as_quat (x, y, z, w) of the handle geom's rotation, in the reference's mesh frame.
    link = _rotation_matrix(frame.body_quat("lever_link1"))
    handle = link @ _rotation_matrix(jnp.asarray(_HANDLE_IN_LINK, link.dtype))
    return frame.site_pos("leverStart")[None], quat_from_xmat(handle)[None]


def _lever_constants(frame: Frame, placement: Placement, settled: Frame) -> dict[str, jnp.ndarray]:
    obj_init_pos = placement.moved_bodies["lever"]  # rand_vec: the lever base position
    return {
        "obj_init_pos": obj_init_pos,
        "init_tcp": settled.tcp_center,
        # The handle of the lowered lever, straight out in front of the axis.
        "lever_pos_init": obj_init_pos + jnp.asarray(_LEVER_AXIS) + jnp.asarray((0.0, -_LEVER_RADIUS, 0.0)),
        "max_pull_dist": jnp.linalg.norm(placement.target_pos - obj_init_pos),
    }


LEVER_PULL = TaskSpec(
    name="lever-pull-v3",
    scene="sawyer_lever_pull.xml",
    hand_init_pos=(0.0, 0.4, 0.2),
    random_low=(-0.1, 0.7, 0.0),
    random_high=(0.1, 0.8, 0.0),
    # The hand (and so goal and mocap) box reaches below the table: z from -0.15.
    hand_low=(-0.5, 0.40, -0.15),
    # No joint write: the lever keeps its settled angle. The goal is the raised handle, straight up.
    place=place_fixture("lever", (_LEVER_AXIS[0], 0.0, _LEVER_AXIS[2] + _LEVER_RADIUS)),
    constants=_lever_constants,
    objects=_lever_objects,
    reward_v2=v2.lever_pull,
    reward_v1=v1.lever_pull,
    moved_bodies=("lever",),
)

TASKS: tuple[TaskSpec, ...] = (FAUCET_OPEN, FAUCET_CLOSE, DIAL_TURN, LEVER_PULL)
