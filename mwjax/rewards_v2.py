"""Meta-World's V2 reward functions in jax.numpy, one per task, on one env (vmapped by the core).

The shared vocabulary (dm_control's `tolerance`, the hamacher product, the gripper-caging term) is
written once here; task kernels compose it exactly as `metaworld==3.1.1` does, including its quirks
(each one is named where it is reproduced). Every kernel returns `(reward, info)` where `info`
carries the reference's info terms and `success`.
"""

from __future__ import annotations

import jax.numpy as jnp

from mwjax.tasks.spec import StepInputs

Array = jnp.ndarray

_VALUE_AT_MARGIN = 0.1
TARGET_RADIUS = 0.05


def _sigmoid(x: Array, value_at_1: float, sigmoid: str) -> Array:
    if sigmoid == "long_tail":
        scale = jnp.sqrt(1.0 / value_at_1 - 1.0)
        return 1.0 / ((x * scale) ** 2 + 1.0)
    if sigmoid == "gaussian":
        scale = jnp.sqrt(-2.0 * jnp.log(value_at_1))
        return jnp.exp(-0.5 * (x * scale) ** 2)
    if sigmoid == "reciprocal":
        scale = 1.0 / value_at_1 - 1.0
        return 1.0 / (jnp.abs(x) * scale + 1.0)
    if sigmoid == "linear":
        scaled = x * (1.0 - value_at_1)
        return jnp.where(jnp.abs(scaled) < 1.0, 1.0 - scaled, 0.0)
    raise ValueError(f"unsupported sigmoid {sigmoid!r}")


def tolerance(
    x: Array,
    bounds: tuple[float | Array, float | Array] = (0.0, 0.0),
    margin: float | Array = 0.0,
    sigmoid: str = "gaussian",
    value_at_margin: float = _VALUE_AT_MARGIN,
) -> Array:
    """1 inside `bounds`, decaying with the distance to the nearest bound over `margin`.

    A zero margin gives a step; the reference branches on `margin == 0` with a Python `if`, so a
    traced margin takes the same branch through `where` (a tiny positive margin is not zero).
    """
    lower, upper = bounds
    in_bounds = (lower <= x) & (x <= upper)
    distance = jnp.where(x < lower, lower - x, x - upper)
    safe_margin = jnp.where(margin == 0, 1.0, margin)
    smooth = jnp.where(in_bounds, 1.0, _sigmoid(distance / safe_margin, value_at_margin, sigmoid))
    return jnp.where(margin == 0, jnp.where(in_bounds, 1.0, 0.0), smooth)


def hamacher_product(a: Array, b: Array) -> Array:
    """The Hamacher t-norm a*b / (a + b - a*b), defined as 0 when both are 0."""
    denominator = a + b - a * b
    return jnp.where(denominator > 0, a * b / jnp.where(denominator > 0, denominator, 1.0), 0.0)


def rect_prism_tolerance(curr: Array, zero: Array, one: Array) -> Array:
    """1 outside the prism spanned by `zero` and `one`, else the normalised depth toward `one`."""

    def inside(lo: Array, hi: Array, v: Array) -> Array:
        return ((lo <= v) & (v <= hi)) | ((hi <= v) & (v <= lo))

    is_inside = inside(zero[0], one[0], curr[0]) & inside(zero[1], one[1], curr[1]) & inside(
        zero[2], one[2], curr[2]
    )
    diff = one - zero
    depth = (curr - zero) / jnp.where(diff == 0, 1.0, diff)
    return jnp.where(is_inside, depth[0] * depth[1] * depth[2], 1.0)


def gripper_caging(
    step: StepInputs,
    obj_pos: Array,
    obj_radius: float,
    pad_success_thresh: float,
    object_reach_radius: float,
    xz_thresh: float,
    desired_gripper_effort: float = 1.0,
    high_density: bool = False,
    medium_density: bool = False,
) -> Array:
    """`SawyerXYZEnv._gripper_caging_reward`: pads straddling the object in y, tcp near it in xz,
    and the gripper closing once caged."""
    frame = step.frame
    obj_init_pos = step.constants["obj_init_pos"]
    init_tcp = step.constants["init_tcp"]
    pad_y = jnp.stack([frame.left_pad[1], frame.right_pad[1]])
    pad_to_obj = jnp.abs(pad_y - obj_pos[1])
    pad_to_obj_init = jnp.abs(pad_y - obj_init_pos[1])
    caging_margin = jnp.abs(pad_to_obj_init - pad_success_thresh)
    caging_lr = tolerance(
        pad_to_obj,
        bounds=(obj_radius, pad_success_thresh),
        margin=caging_margin,
        sigmoid="long_tail",
    )
    caging_y = hamacher_product(caging_lr[0], caging_lr[1])

    xz = jnp.array([0, 2])
    tcp = frame.tcp_center
    caging_xz_margin = jnp.linalg.norm(obj_init_pos[xz] - init_tcp[xz]) - xz_thresh
    caging_xz = tolerance(
        jnp.linalg.norm(tcp[xz] - obj_pos[xz]),
        bounds=(0.0, xz_thresh),
        margin=caging_xz_margin,
        sigmoid="long_tail",
    )
    gripper_closed = jnp.minimum(jnp.maximum(0.0, step.action[-1]), desired_gripper_effort)
    gripper_closed = gripper_closed / desired_gripper_effort

    caging = hamacher_product(caging_y, caging_xz)
    gripping = jnp.where(caging > 0.97, gripper_closed, 0.0)
    caging_and_gripping = hamacher_product(caging, gripping)
    if high_density:
        caging_and_gripping = (caging_and_gripping + caging) / 2
    if medium_density:
        tcp_to_obj = jnp.linalg.norm(obj_pos - tcp)
        tcp_to_obj_init = jnp.linalg.norm(obj_init_pos - init_tcp)
        reach = tolerance(
            tcp_to_obj,
            bounds=(0.0, object_reach_radius),
            margin=jnp.abs(tcp_to_obj_init - object_reach_radius),
            sigmoid="long_tail",
        )
        caging_and_gripping = (caging_and_gripping + reach) / 2
    return caging_and_gripping


def _info(
    reward: Array,
    success: Array,
    near_object: Array,
    grasp_reward: Array,
    in_place_reward: Array,
    obj_to_target: Array,
) -> tuple[Array, dict[str, Array]]:
    info = {
        "success": success,
        "near_object": near_object,
        "grasp_reward": grasp_reward,
        "in_place_reward": in_place_reward,
        "obj_to_target": obj_to_target,
        "unscaled_reward": reward,
    }
    return reward, {k: jnp.asarray(v, jnp.float32) for k, v in info.items()}


def _pick_place_caging(step: StepInputs, obj_pos: Array) -> Array:
    """pick-place's own `_gripper_caging_reward` override (y caging from the live pad positions).

    Reference quirk reproduced: `init_left_pad`/`init_right_pad` are assigned
    `get_body_com(...)`, a live view into `data.xpos`, so the "initial" pad positions it compares
    with are the current ones.
    """
    frame = step.frame
    pad_success_margin, xz_success_margin, obj_radius = 0.05, 0.005, 0.015
    left_pad, right_pad = frame.left_pad, frame.right_pad
    right_margin = jnp.abs(jnp.abs(obj_pos[1] - right_pad[1]) - pad_success_margin)
    left_margin = jnp.abs(jnp.abs(obj_pos[1] - left_pad[1]) - pad_success_margin)
    right_caging = tolerance(
        obj_pos[1] - right_pad[1],
        bounds=(obj_radius, pad_success_margin),
        margin=right_margin,
        sigmoid="long_tail",
    )
    left_caging = tolerance(
        left_pad[1] - obj_pos[1],
        bounds=(obj_radius, pad_success_margin),
        margin=left_margin,
        sigmoid="long_tail",
    )
    y_caging = hamacher_product(left_caging, right_caging)

    xz = jnp.array([0, 2])
    tcp = frame.tcp_center
    obj_init_pos, init_tcp = step.constants["obj_init_pos"], step.constants["init_tcp"]
    tcp_obj_xz = jnp.linalg.norm(tcp[xz] - obj_pos[xz])
    xz_margin = jnp.linalg.norm(obj_init_pos[xz] - init_tcp[xz]) - xz_success_margin
    xz_caging = tolerance(
        tcp_obj_xz, bounds=(0.0, xz_success_margin), margin=xz_margin, sigmoid="long_tail"
    )
    gripper_closed = jnp.minimum(jnp.maximum(0.0, step.action[-1]), 1.0)
    caging = hamacher_product(y_caging, xz_caging)
    gripping = jnp.where(caging > 0.97, gripper_closed, 0.0)
    return (hamacher_product(caging, gripping) + caging) / 2


def pick_place(step: StepInputs) -> tuple[Array, dict[str, Array]]:
    obj = step.obs[4:7]
    tcp_opened = step.obs[3]
    tcp = step.frame.tcp_center
    target = step.target_pos
    obj_init_pos = step.constants["obj_init_pos"]
    obj_to_target = jnp.linalg.norm(obj - target)
    tcp_to_obj = jnp.linalg.norm(obj - tcp)
    in_place = tolerance(
        obj_to_target,
        bounds=(0.0, TARGET_RADIUS),
        margin=jnp.linalg.norm(obj_init_pos - target),
        sigmoid="long_tail",
    )
    object_grasped = _pick_place_caging(step, obj)
    reward = hamacher_product(object_grasped, in_place)
    lifted = (tcp_to_obj < 0.02) & (tcp_opened > 0) & (obj[2] - 0.01 > obj_init_pos[2])
    reward = jnp.where(lifted, reward + 1.0 + 5.0 * in_place, reward)
    reward = jnp.where(obj_to_target < TARGET_RADIUS, 10.0, reward)
    return _info(
        reward,
        success=obj_to_target <= 0.07,
        near_object=tcp_to_obj <= 0.03,
        grasp_reward=object_grasped,
        in_place_reward=in_place,
        obj_to_target=obj_to_target,
    )


# ---- reach, push (reach_push_pick_place.py) ---------------------------------------------------


# ---- peg-insert-side (peg.py) ----------------------------------------------------------------


# ---- door, drawer (articulated.py) -----------------------------------------------------------


# ---- button-press-topdown, window (articulated.py) -------------------------------------------
