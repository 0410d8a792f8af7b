"""The shared vocabulary of the V2 rewards, written once: dm_control's `tolerance` (and `within`,
its most common use), the hamacher product, the gripper-caging terms, the funnel floor, and
`info_terms`, the info every kernel returns (`grasp_place_info` is its grasp-and-place form).
Terms used by kernels of more than one family live here; the rest stay with their family.
"""

from __future__ import annotations

import jax.numpy as jnp

from mwjax.contracts import StepInputs

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


def within(distance: Array, radius: float | Array, margin: float | Array) -> Array:
    """The reference's most common term: 1 while `distance` is at most `radius`, then a long-tail
    decay over `margin` (`tolerance` with bounds (0, radius) and the long-tail sigmoid)."""
    return tolerance(distance, bounds=(0.0, radius), margin=margin, sigmoid="long_tail")


def hamacher_product(a: Array, b: Array) -> Array:
    """The Hamacher t-norm a*b / (a + b - a*b), defined as 0 when both are 0."""
    denominator = a + b - a * b
    return jnp.where(denominator > 0, a * b / jnp.where(denominator > 0, denominator, 1.0), 0.0)


def rect_prism_tolerance(curr: Array, zero: Array, one: Array) -> Array:
    """1 outside the prism spanned by `zero` and `one`, else the normalised depth toward `one`."""

    def inside(lo: Array, hi: Array, v: Array) -> Array:
        return ((lo <= v) & (v <= hi)) | ((hi <= v) & (v <= lo))

    is_inside = (
        inside(zero[0], one[0], curr[0]) & inside(zero[1], one[1], curr[1]) & inside(zero[2], one[2], curr[2])
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
    caging_xz = within(jnp.linalg.norm(tcp[xz] - obj_pos[xz]), xz_thresh, caging_xz_margin)
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
        reach = within(tcp_to_obj, object_reach_radius, jnp.abs(tcp_to_obj_init - object_reach_radius))
        caging_and_gripping = (caging_and_gripping + reach) / 2
    return caging_and_gripping


def info_terms(
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


def grasp_place_info(
    reward: Array,
    obj_to_target: Array,
    tcp_to_obj: Array,
    grasped: Array,
    in_place: Array,
    success_radius: float,
    near_radius: float,
) -> tuple[Array, dict[str, Array]]:
    """`info_terms` of a grasp-and-place kernel: success once the object is within
    `success_radius` of the target, near once the tcp is within `near_radius` of the object."""
    return info_terms(
        reward,
        success=obj_to_target <= success_radius,
        near_object=tcp_to_obj <= near_radius,
        grasp_reward=grasped,
        in_place_reward=in_place,
        obj_to_target=obj_to_target,
    )


def funnel_floor(radius: Array, threshold: float, scale: float, height: float) -> Array:
    """A log funnel's floor at `radius` off its axis: 0 within `threshold`, else scale * log + height."""
    # The reference takes the log only outside the threshold (a Python `if`).
    return jnp.where(
        radius > threshold, scale * jnp.log(jnp.maximum(radius - threshold, 1e-30)) + height, 0.0
    )


def above_floor_term(z: Array, floor: Array, margin: Array | float) -> Array:
    """1 at or above `floor`, else a long-tail tolerance of the depth below it over `margin`."""
    return jnp.where(
        z >= floor,
        1.0,
        within(jnp.maximum(floor - z, 0.0), 0.01, margin),
    )


def pick_place_caging(step: StepInputs, obj_pos: Array) -> Array:
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
    xz_caging = within(tcp_obj_xz, xz_success_margin, xz_margin)
    gripper_closed = jnp.minimum(jnp.maximum(0.0, step.action[-1]), 1.0)
    caging = hamacher_product(y_caging, xz_caging)
    gripping = jnp.where(caging > 0.97, gripper_closed, 0.0)
    return (hamacher_product(caging, gripping) + caging) / 2


def pad_gripping_caging(
    step: StepInputs,
    obj_pos: Array,
    obj_radius: float,
    grip_success_margin: float,
    x_z_success_margin: float,
) -> Array:
    """The `_gripper_caging_reward` override of push-back, sweep and sweep-into: y caging, and
    y gripping from the pads instead of the gripper command.

    Reference quirk reproduced: `init_left_pad`/`init_right_pad` are live views into
    `data.xpos`, so the margins are measured from the current pads.
    """
    frame = step.frame
    pad_success_margin = 0.05
    left_pad, right_pad = frame.left_pad, frame.right_pad
    delta_right = obj_pos[1] - right_pad[1]
    delta_left = left_pad[1] - obj_pos[1]
    right_margin = jnp.abs(jnp.abs(obj_pos[1] - right_pad[1]) - pad_success_margin)
    left_margin = jnp.abs(jnp.abs(obj_pos[1] - left_pad[1]) - pad_success_margin)

    def pads(upper: float) -> Array:
        right = tolerance(delta_right, bounds=(obj_radius, upper), margin=right_margin, sigmoid="long_tail")
        left = tolerance(delta_left, bounds=(obj_radius, upper), margin=left_margin, sigmoid="long_tail")
        return hamacher_product(right, left)

    y_caging, y_gripping = pads(pad_success_margin), pads(grip_success_margin)
    xz = jnp.array([0, 2])
    obj_init_pos, init_tcp = step.constants["obj_init_pos"], step.constants["init_tcp"]
    tcp_obj_xz = jnp.linalg.norm(frame.tcp_center[xz] - obj_pos[xz])
    xz_margin = jnp.linalg.norm(obj_init_pos[xz] - init_tcp[xz]) - x_z_success_margin
    x_z_caging = within(tcp_obj_xz, x_z_success_margin, xz_margin)
    caging = hamacher_product(y_caging, x_z_caging)
    gripping = jnp.where(caging > 0.95, y_gripping, 0.0)
    return (caging + gripping) / 2


def button_terms(step: StepInputs, axis: int, near_radius: float) -> tuple[Array, Array, Array, Array]:
    """The terms every V2 button reward shares: reach the button, press it along `axis`."""
    obj = step.obs.obj
    tcp_to_obj = jnp.linalg.norm(obj - step.frame.tcp_center)
    # Quirk: the "initial" reach distance uses the current button position with the initial tcp.
    tcp_to_obj_init = jnp.linalg.norm(obj - step.constants["init_tcp"])
    obj_to_target = jnp.abs(step.target_pos[axis] - obj[axis])
    near_button = within(tcp_to_obj, near_radius, tcp_to_obj_init)
    button_pressed = within(obj_to_target, 0.005, step.constants["obj_to_target_init"])
    return tcp_to_obj, obj_to_target, near_button, button_pressed


def button_info(
    reward: Array, success_radius: float, terms: tuple[Array, Array, Array, Array]
) -> tuple[Array, dict[str, Array]]:
    tcp_to_obj, obj_to_target, near_button, button_pressed = terms
    return info_terms(
        reward,
        success=obj_to_target <= success_radius,
        near_object=tcp_to_obj <= 0.05,
        grasp_reward=near_button,
        in_place_reward=button_pressed,
        obj_to_target=obj_to_target,
    )


def button_reach_press(
    step: StepInputs,
    axis: int,
    near_radius: float,
    tcp_closed: Array,
    weights: tuple[float, float],
    press_radius: float,
    success_radius: float,
) -> tuple[Array, dict[str, Array]]:
    """`w0 * hamacher(tcp_closed, near_button)`, plus `w1 * button_pressed` once within reach."""
    terms = button_terms(step, axis, near_radius)
    tcp_to_obj, _, near_button, button_pressed = terms
    reward = weights[0] * hamacher_product(tcp_closed, near_button)
    reward = jnp.where(tcp_to_obj <= press_radius, reward + weights[1] * button_pressed, reward)
    return button_info(reward, success_radius, terms)
