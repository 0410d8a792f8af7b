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
    xz_caging = tolerance(tcp_obj_xz, bounds=(0.0, xz_success_margin), margin=xz_margin, sigmoid="long_tail")
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
    return info_terms(
        reward,
        success=obj_to_target <= 0.07,
        near_object=tcp_to_obj <= 0.03,
        grasp_reward=object_grasped,
        in_place_reward=in_place,
        obj_to_target=obj_to_target,
    )


# ---- reach, push (reach_push_pick_place.py) ---------------------------------------------------


def _reach(step: StepInputs) -> tuple[Array, Array, Array]:
    """reach's V2 reward (shared by reach-wall): `(reward, tcp_to_target, in_place)`."""
    tcp_to_target = jnp.linalg.norm(step.frame.tcp_center - step.target_pos)
    in_place = tolerance(
        tcp_to_target,
        bounds=(0.0, TARGET_RADIUS),
        # Margin from the nominal hand_init_pos, not the settled init_tcp.
        margin=jnp.linalg.norm(step.constants["hand_init_pos"] - step.target_pos),
        sigmoid="long_tail",
    )
    return 10.0 * in_place, tcp_to_target, in_place


def reach(step: StepInputs) -> tuple[Array, dict[str, Array]]:
    reward, tcp_to_target, in_place = _reach(step)
    # Quirk: reach reports the raw tcp-goal distance as near_object and grasp_reward.
    return info_terms(
        reward,
        success=tcp_to_target <= 0.05,
        near_object=tcp_to_target,
        grasp_reward=tcp_to_target,
        in_place_reward=in_place,
        obj_to_target=tcp_to_target,
    )


def reach_wall(step: StepInputs) -> tuple[Array, dict[str, Array]]:
    reward, tcp_to_target, in_place = _reach(step)
    # reach-wall reports near_object and grasp_reward as constant 0.
    return info_terms(
        reward,
        success=tcp_to_target <= 0.05,
        near_object=0.0,
        grasp_reward=0.0,
        in_place_reward=in_place,
        obj_to_target=tcp_to_target,
    )


def push(step: StepInputs) -> tuple[Array, dict[str, Array]]:
    obj = step.obs[4:7]
    tcp_opened = step.obs[3]
    target = step.target_pos
    tcp_to_obj = jnp.linalg.norm(obj - step.frame.tcp_center)
    target_to_obj = jnp.linalg.norm(obj - target)
    in_place = tolerance(
        target_to_obj,
        bounds=(0.0, TARGET_RADIUS),
        margin=jnp.linalg.norm(step.constants["obj_init_pos"] - target),
        sigmoid="long_tail",
    )
    object_grasped = gripper_caging(
        step,
        obj,
        obj_radius=0.015,
        pad_success_thresh=0.05,
        object_reach_radius=0.01,
        xz_thresh=0.005,
        high_density=True,
    )
    reward = 2.0 * object_grasped
    # Quirk: `reward += 1.0 + reward + 5.0 * in_place` adds the caging term a second time.
    near = (tcp_to_obj < 0.02) & (tcp_opened > 0)
    reward = jnp.where(near, reward + 1.0 + reward + 5.0 * in_place, reward)
    reward = jnp.where(target_to_obj < TARGET_RADIUS, 10.0, reward)
    return info_terms(
        reward,
        success=target_to_obj <= TARGET_RADIUS,
        near_object=tcp_to_obj <= 0.03,
        grasp_reward=object_grasped,
        in_place_reward=in_place,
        obj_to_target=target_to_obj,
    )


def _around_wall(
    step: StepInputs,
    midpoint: Array,
    in_place_scaling: Array,
    pick: bool,
) -> tuple[Array, dict[str, Array]]:
    """push-wall and pick-place-wall: in place at a midpoint past the wall, then at the goal.

    The base is `2 * caging` for push-wall (high density caging) and `hamacher(caging, in_place
    at midpoint)` for pick-place-wall (plain caging), whose bonus also needs the puck lifted.
    """
    obj = step.obs[4:7]
    tcp_opened = step.obs[3]
    target = step.target_pos
    obj_init_pos = step.constants["obj_init_pos"]
    tcp_to_obj = jnp.linalg.norm(obj - step.frame.tcp_center)
    obj_to_midpoint = jnp.linalg.norm((obj - midpoint) * in_place_scaling)
    obj_to_midpoint_init = jnp.linalg.norm((obj_init_pos - midpoint) * in_place_scaling)
    obj_to_target = jnp.linalg.norm(obj - target)
    in_place_part1 = tolerance(
        obj_to_midpoint, bounds=(0.0, TARGET_RADIUS), margin=obj_to_midpoint_init, sigmoid="long_tail"
    )
    in_place_part2 = tolerance(
        obj_to_target,
        bounds=(0.0, TARGET_RADIUS),
        margin=jnp.linalg.norm(obj_init_pos - target),
        sigmoid="long_tail",
    )
    object_grasped = gripper_caging(
        step,
        obj,
        obj_radius=0.015,
        pad_success_thresh=0.05,
        object_reach_radius=0.01,
        xz_thresh=0.005,
        high_density=not pick,
    )
    base = hamacher_product(object_grasped, in_place_part1) if pick else 2.0 * object_grasped
    near = (tcp_to_obj < 0.02) & (tcp_opened > 0)
    if pick:
        near = near & (obj[2] - 0.015 > obj_init_pos[2])
    reward = jnp.where(near, base + 1.0 + 4.0 * in_place_part1, base)
    reward = jnp.where(near & (obj[1] > 0.75), base + 1.0 + 4.0 + 3.0 * in_place_part2, reward)
    reward = jnp.where(obj_to_target < TARGET_RADIUS, 10.0, reward)
    return info_terms(
        reward,
        success=obj_to_target <= 0.07,
        near_object=tcp_to_obj <= 0.03,
        grasp_reward=object_grasped,
        in_place_reward=in_place_part2,
        obj_to_target=obj_to_target,
    )


def push_wall(step: StepInputs) -> tuple[Array, dict[str, Array]]:
    # The midpoint's z follows the puck (so only x and y count).
    midpoint = jnp.stack([-0.05, 0.77, step.obs[6]])
    return _around_wall(step, midpoint, jnp.array([3.0, 1.0, 1.0]), pick=False)


def pick_place_wall(step: StepInputs) -> tuple[Array, dict[str, Array]]:
    midpoint = jnp.stack([step.target_pos[0], 0.77, 0.25])
    return _around_wall(step, midpoint, jnp.array([1.0, 1.0, 3.0]), pick=True)


def _pad_gripping_caging(
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
    x_z_caging = tolerance(
        tcp_obj_xz, bounds=(0.0, x_z_success_margin), margin=xz_margin, sigmoid="long_tail"
    )
    caging = hamacher_product(y_caging, x_z_caging)
    gripping = jnp.where(caging > 0.95, y_gripping, 0.0)
    return (caging + gripping) / 2


def push_back(step: StepInputs) -> tuple[Array, dict[str, Array]]:
    obj = step.obs[4:7]
    tcp_opened = step.obs[3]
    target = step.target_pos
    tcp_to_obj = jnp.linalg.norm(obj - step.frame.tcp_center)
    target_to_obj = jnp.linalg.norm(obj - target)
    target_to_obj_init = jnp.linalg.norm(step.constants["obj_init_pos"] - target)
    in_place = tolerance(
        target_to_obj, bounds=(0.0, TARGET_RADIUS), margin=target_to_obj_init, sigmoid="long_tail"
    )
    object_grasped = _pad_gripping_caging(
        step, obj, obj_radius=0.007, grip_success_margin=0.007 + 0.003, x_z_success_margin=0.01
    )
    reward = hamacher_product(object_grasped, in_place)
    pushing = (tcp_to_obj < 0.01) & (0 < tcp_opened) & (tcp_opened < 0.55)
    pushing = pushing & (target_to_obj_init - target_to_obj > 0.01)
    reward = jnp.where(pushing, reward + 1.0 + 5.0 * in_place, reward)
    reward = jnp.where(target_to_obj < TARGET_RADIUS, 10.0, reward)
    return info_terms(
        reward,
        success=target_to_obj <= 0.07,
        near_object=tcp_to_obj <= 0.03,
        grasp_reward=object_grasped,
        in_place_reward=in_place,
        obj_to_target=target_to_obj,
    )


# ---- peg-insert-side (peg.py) ----------------------------------------------------------------


def peg_insert_side(step: StepInputs) -> tuple[Array, dict[str, Array]]:
    frame = step.frame
    obj = step.obs[4:7]
    tcp_opened = step.obs[3]
    target = step.target_pos
    obj_head = frame.site_pos("pegHead")
    obj_init_pos = step.constants["obj_init_pos"]
    tcp_to_obj = jnp.linalg.norm(obj - frame.tcp_center)
    scale = jnp.array([1.0, 2.0, 2.0])
    obj_to_target = jnp.linalg.norm((obj_head - target) * scale)
    in_place = tolerance(
        obj_to_target,
        bounds=(0.0, 0.07),
        # peg_head_pos_init is the XML-default peg head (see peg.py), not this episode's.
        margin=jnp.linalg.norm((step.constants["peg_head_pos_init"] - target) * scale),
        sigmoid="long_tail",
    )
    collision_box_1 = rect_prism_tolerance(
        obj_head,
        zero=frame.site_pos("bottom_right_corner_collision_box_1"),
        one=frame.site_pos("top_left_corner_collision_box_1"),
    )
    collision_box_2 = rect_prism_tolerance(
        obj_head,
        zero=frame.site_pos("bottom_right_corner_collision_box_2"),
        one=frame.site_pos("top_left_corner_collision_box_2"),
    )
    in_place = hamacher_product(in_place, hamacher_product(collision_box_2, collision_box_1))
    object_grasped = gripper_caging(
        step,
        obj,
        obj_radius=0.0075,
        pad_success_thresh=0.03,
        object_reach_radius=0.01,
        xz_thresh=0.005,
        high_density=True,
    )
    lifted = (tcp_to_obj < 0.08) & (tcp_opened > 0) & (obj[2] - 0.01 > obj_init_pos[2])
    object_grasped = jnp.where(lifted, 1.0, object_grasped)
    reward = hamacher_product(object_grasped, in_place)
    reward = jnp.where(lifted, reward + 1.0 + 5.0 * in_place, reward)
    reward = jnp.where(obj_to_target <= 0.07, 10.0, reward)
    return info_terms(
        reward,
        success=obj_to_target <= 0.07,
        near_object=tcp_to_obj <= 0.03,
        grasp_reward=object_grasped,
        in_place_reward=in_place,
        obj_to_target=obj_to_target,
    )


# ---- door, drawer (articulated.py) -----------------------------------------------------------


def door_open(step: StepInputs) -> tuple[Array, dict[str, Array]]:
    """`SawyerDoorEnvV3.compute_reward` (v2): get above a funnel floor near the handle, then
    swing the hinge open."""
    obs = step.obs
    hand = obs[:3]
    door = obs[4:7] + jnp.array([-0.05, 0.0, 0.0])
    theta = step.frame.joint_qpos("doorjoint")
    reward_grab = (jnp.clip(step.action[3], -1.0, 1.0) + 1.0) / 2.0

    threshold = 0.12
    radius = jnp.linalg.norm(hand[:2] - door[:2])
    # The reference takes the log only when radius > threshold (a Python `if`).
    floor = jnp.where(radius <= threshold, 0.0, 0.04 * jnp.log(jnp.maximum(radius - threshold, 1e-30)) + 0.4)
    above_floor = jnp.where(
        hand[2] >= floor,
        1.0,
        tolerance(floor - hand[2], bounds=(0.0, 0.01), margin=floor / 2.0, sigmoid="long_tail"),
    )
    in_place = tolerance(
        jnp.linalg.norm(hand - door - jnp.array([0.05, 0.03, -0.01])),
        bounds=(0.0, threshold / 2.0),
        margin=0.5,
        sigmoid="long_tail",
    )
    ready_to_open = hamacher_product(above_floor, in_place)

    door_angle = -theta
    opened = 0.2 * (theta < -jnp.pi / 90.0) + 0.8 * tolerance(
        jnp.pi / 2.0 + jnp.pi / 6 - door_angle,
        bounds=(0.0, 0.5),
        margin=jnp.pi / 3.0,
        sigmoid="long_tail",
    )
    reward = 2.0 * hamacher_product(ready_to_open, reward_grab) + 8.0 * opened
    # Success and the reward override look only at the handle's x against the goal's x.
    success = jnp.abs(obs[4] - step.target_pos[0]) <= 0.08
    reward = jnp.where(success, 10.0, reward)
    return info_terms(
        reward,
        success=success,
        near_object=ready_to_open,  # the reference reports the readiness term as near_object
        grasp_reward=reward_grab,
        in_place_reward=opened,
        obj_to_target=0.0,  # the reference hard-codes 0
    )


def drawer_open(step: StepInputs) -> tuple[Array, dict[str, Array]]:
    """`SawyerDrawerOpenEnvV3.compute_reward` (v2): reach the handle, pull it to the goal."""
    max_dist = 0.2
    gripper = step.obs[:3]  # quirk: the hand body position, while the init term uses init_tcp
    handle = step.obs[4:7]
    target = step.target_pos
    handle_error = jnp.linalg.norm(handle - target)
    reward_for_opening = tolerance(handle_error, bounds=(0.0, 0.02), margin=max_dist, sigmoid="long_tail")
    handle_pos_init = target + jnp.array([0.0, max_dist, 0.0])
    scale = jnp.array([3.0, 3.0, 1.0])
    gripper_error = (handle - gripper) * scale
    gripper_error_init = (handle_pos_init - step.constants["init_tcp"]) * scale
    reward_for_caging = tolerance(
        jnp.linalg.norm(gripper_error),
        bounds=(0.0, 0.01),
        margin=jnp.linalg.norm(gripper_error_init),
        sigmoid="long_tail",
    )
    reward = 5.0 * (reward_for_caging + reward_for_opening)
    return info_terms(
        reward,
        success=handle_error <= 0.03,
        near_object=jnp.linalg.norm(handle - gripper) <= 0.03,
        grasp_reward=reward_for_caging,
        in_place_reward=reward_for_opening,
        obj_to_target=handle_error,
    )


def drawer_close(step: StepInputs) -> tuple[Array, dict[str, Array]]:
    """`SawyerDrawerCloseEnvV3.compute_reward` (v2): reach the handle with a closed gripper, push
    the drawer shut."""
    # Quirk: the class sets _TARGET_RADIUS = 0.04 but reads the base class's TARGET_RADIUS (0.05).
    radius = TARGET_RADIUS
    obj = step.obs[4:7]
    tcp = step.frame.tcp_center
    target = step.target_pos
    obj_init_pos, init_tcp = step.constants["obj_init_pos"], step.constants["init_tcp"]
    # The handle point sits 5 cm above the goal's z, so target_to_obj never drops below 0.05.
    target_to_obj = jnp.linalg.norm(obj - target)
    target_to_obj_init = jnp.linalg.norm(obj_init_pos - target)
    in_place = tolerance(
        target_to_obj,
        bounds=(0.0, radius),
        margin=jnp.abs(target_to_obj_init - radius),
        sigmoid="long_tail",
    )
    handle_reach_radius = 0.005
    tcp_to_obj = jnp.linalg.norm(obj - tcp)
    tcp_to_obj_init = jnp.linalg.norm(obj_init_pos - init_tcp)
    reach = tolerance(
        tcp_to_obj,
        bounds=(0.0, handle_reach_radius),
        margin=jnp.abs(tcp_to_obj_init - handle_reach_radius),
        sigmoid="gaussian",
    )
    gripper_closed = jnp.minimum(jnp.maximum(0.0, step.action[-1]), 1.0)
    reach = hamacher_product(reach, gripper_closed)
    reward = hamacher_product(reach, in_place)
    success = target_to_obj <= radius + 0.015
    reward = 10.0 * jnp.where(success, 1.0, reward)
    return info_terms(
        reward,
        success=success,
        near_object=tcp_to_obj <= 0.01,
        grasp_reward=reach,
        in_place_reward=in_place,
        obj_to_target=target_to_obj,
    )


# ---- button-press-topdown, window (articulated.py) -------------------------------------------


def _button_terms(step: StepInputs, axis: int, near_radius: float) -> tuple[Array, Array, Array, Array]:
    """The terms every V2 button reward shares: reach the button, press it along `axis`."""
    obj = step.obs[4:7]
    tcp_to_obj = jnp.linalg.norm(obj - step.frame.tcp_center)
    # Quirk: the "initial" reach distance uses the current button position with the initial tcp.
    tcp_to_obj_init = jnp.linalg.norm(obj - step.constants["init_tcp"])
    obj_to_target = jnp.abs(step.target_pos[axis] - obj[axis])
    near_button = tolerance(
        tcp_to_obj, bounds=(0.0, near_radius), margin=tcp_to_obj_init, sigmoid="long_tail"
    )
    button_pressed = tolerance(
        obj_to_target,
        bounds=(0.0, 0.005),
        margin=step.constants["obj_to_target_init"],
        sigmoid="long_tail",
    )
    return tcp_to_obj, obj_to_target, near_button, button_pressed


def _button_info(
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


def _button_reach_press(
    step: StepInputs,
    axis: int,
    near_radius: float,
    tcp_closed: Array,
    weights: tuple[float, float],
    press_radius: float,
    success_radius: float,
) -> tuple[Array, dict[str, Array]]:
    """`w0 * hamacher(tcp_closed, near_button)`, plus `w1 * button_pressed` once within reach."""
    terms = _button_terms(step, axis, near_radius)
    tcp_to_obj, _, near_button, button_pressed = terms
    reward = weights[0] * hamacher_product(tcp_closed, near_button)
    reward = jnp.where(tcp_to_obj <= press_radius, reward + weights[1] * button_pressed, reward)
    return _button_info(reward, success_radius, terms)


def button_press_topdown(step: StepInputs) -> tuple[Array, dict[str, Array]]:
    return _button_reach_press(step, 2, 0.01, 1.0 - step.obs[3], (5.0, 5.0), 0.03, 0.024)


def button_press_topdown_wall(step: StepInputs) -> tuple[Array, dict[str, Array]]:
    # Quirk: the wall variant's "tcp_closed" is max(obs[3], 0) (the opening), topdown's 1 - obs[3].
    return _button_reach_press(step, 2, 0.01, jnp.maximum(step.obs[3], 0.0), (5.0, 5.0), 0.03, 0.024)


def button_press(step: StepInputs) -> tuple[Array, dict[str, Array]]:
    # Quirk: "tcp_closed" is max(obs[3], 0), i.e. the gripper opening.
    return _button_reach_press(step, 1, 0.05, jnp.maximum(step.obs[3], 0.0), (2.0, 8.0), 0.05, 0.02)


def button_press_wall(step: StepInputs) -> tuple[Array, dict[str, Array]]:
    terms = _button_terms(step, 1, 0.01)
    tcp_to_obj, _, near_button, button_pressed = terms
    far = 2.0 * hamacher_product((1.0 - step.obs[3]) / 2.0, near_button)
    near = 2.0 + 2.0 * (1.0 + step.obs[3]) + 4.0 * button_pressed**2
    reward = jnp.where(tcp_to_obj > 0.07, far, near)
    return _button_info(reward, 0.03, terms)


def _window(
    step: StepInputs, handle_site: str, target_to_obj_init: Array, reach_sigmoid: str
) -> tuple[Array, dict[str, Array]]:
    """The shared V2 window reward: slide the handle to the target's x while reaching it."""
    obj = step.frame.site_pos(handle_site)
    tcp = step.frame.tcp_center
    target_to_obj = jnp.abs(obj[0] - step.target_pos[0])
    in_place = tolerance(
        target_to_obj,
        bounds=(0.0, TARGET_RADIUS),
        margin=jnp.abs(target_to_obj_init - TARGET_RADIUS),
        sigmoid="long_tail",
    )
    handle_radius = 0.02
    tcp_to_obj = jnp.linalg.norm(obj - tcp)
    tcp_to_obj_init = jnp.linalg.norm(step.constants["window_handle_pos_init"] - step.constants["init_tcp"])
    reach = tolerance(
        tcp_to_obj,
        bounds=(0.0, handle_radius),
        margin=jnp.abs(tcp_to_obj_init - handle_radius),
        sigmoid=reach_sigmoid,
    )
    reward = 10.0 * hamacher_product(reach, in_place)
    return info_terms(
        reward,
        success=target_to_obj <= TARGET_RADIUS,
        near_object=tcp_to_obj <= 0.05,
        grasp_reward=reach,
        in_place_reward=in_place,
        obj_to_target=target_to_obj,
    )


def window_open(step: StepInputs) -> tuple[Array, dict[str, Array]]:
    # Quirk: the initial distance is from the window body's x (obj_init_pos), not the handle's,
    # so the in-place margin is always |0.2 - 0.05|.
    target_to_obj_init = jnp.abs(step.constants["obj_init_pos"][0] - step.target_pos[0])
    return _window(step, "handleOpenStart", target_to_obj_init, reach_sigmoid="long_tail")


def window_close(step: StepInputs) -> tuple[Array, dict[str, Array]]:
    target_to_obj_init = jnp.abs(step.constants["window_handle_pos_init"][0] - step.target_pos[0])
    # Quirk: window-close's reach term uses a gaussian sigmoid where window-open uses long_tail.
    return _window(step, "handleCloseStart", target_to_obj_init, reach_sigmoid="gaussian")


# ---- handle press/pull (handles.py) ----------------------------------------------------------


def handle_press(step: StepInputs) -> tuple[Array, dict[str, Array]]:
    """handle-press-side (handle-press has the same code): reach the handle, push it down to the
    goal's z."""
    radius = 0.02  # the class's TARGET_RADIUS
    obj = step.frame.site_pos("handleStart")
    tcp = step.frame.tcp_center
    target = step.target_pos
    handle_init = step.constants["handle_init_pos"]
    target_to_obj = jnp.abs(obj[2] - target[2])
    target_to_obj_init = jnp.abs(handle_init[2] - target[2])
    in_place = tolerance(
        target_to_obj,
        bounds=(0.0, radius),
        margin=jnp.abs(target_to_obj_init - radius),
        sigmoid="long_tail",
    )
    handle_radius = 0.02
    tcp_to_obj = jnp.linalg.norm(obj - tcp)
    tcp_to_obj_init = jnp.linalg.norm(handle_init - step.constants["init_tcp"])
    reach = tolerance(
        tcp_to_obj,
        bounds=(0.0, handle_radius),
        margin=jnp.abs(tcp_to_obj_init - handle_radius),
        sigmoid="long_tail",
    )
    success = target_to_obj <= radius
    reward = 10.0 * jnp.where(success, 1.0, hamacher_product(reach, in_place))
    return info_terms(
        reward,
        success=success,
        near_object=tcp_to_obj <= 0.05,
        grasp_reward=reach,  # object_grasped = reach
        in_place_reward=in_place,
        obj_to_target=target_to_obj,
    )


def _handle_pull(
    step: StepInputs,
    target_to_obj: Array,
    target_to_obj_init: Array,
    pad_success_thresh: float,
    obj_radius: float,
    lift_axis: int,
    success_radius: float,
) -> tuple[Array, dict[str, Array]]:
    """The shared V2 handle-pull reward: cage the handle, lift it to the goal."""
    obj = step.obs[4:7]
    tcp_opened = step.obs[3]
    in_place = tolerance(
        target_to_obj,
        bounds=(0.0, TARGET_RADIUS),
        margin=target_to_obj_init,
        sigmoid="long_tail",
    )
    object_grasped = gripper_caging(
        step,
        obj,
        pad_success_thresh=pad_success_thresh,
        obj_radius=obj_radius,
        object_reach_radius=0.01,
        xz_thresh=0.01,
        high_density=True,
    )
    reward = hamacher_product(object_grasped, in_place)
    tcp_to_obj = jnp.linalg.norm(obj - step.frame.tcp_center)
    lifted = (
        (tcp_to_obj < 0.035) & (tcp_opened > 0) & (obj[lift_axis] - 0.01 > step.constants["obj_init_pos"][2])
    )
    reward = jnp.where(lifted, reward + 1.0 + 5.0 * in_place, reward)
    reward = jnp.where(target_to_obj < TARGET_RADIUS, 10.0, reward)
    return info_terms(
        reward,
        success=target_to_obj <= success_radius,
        near_object=tcp_to_obj <= 0.05,
        grasp_reward=object_grasped,
        in_place_reward=in_place,
        obj_to_target=target_to_obj,
    )


def handle_pull_side(step: StepInputs) -> tuple[Array, dict[str, Array]]:
    obj, target = step.obs[4:7], step.target_pos
    target_to_obj_init = jnp.linalg.norm(step.constants["obj_init_pos"] - target)
    # Quirk: success is obj_to_target <= 0.08 while the reward's 10.0 needs < TARGET_RADIUS (0.05).
    return _handle_pull(
        step,
        jnp.linalg.norm(obj - target),
        target_to_obj_init,
        pad_success_thresh=0.06,
        obj_radius=0.032,
        lift_axis=2,
        success_radius=0.08,
    )


# ---- faucet, dial (rotary.py) ----------------------------------------------------------------


def _faucet(step: StepInputs, obj: Array) -> tuple[Array, dict[str, Array]]:
    """The shared V2 faucet reward: reach the handle (gaussian), turn it to the goal."""
    radius = 0.07  # the class's _target_radius
    tcp = step.frame.tcp_center
    target = step.target_pos
    obj_init = step.constants["obj_init_pos"]
    target_to_obj = jnp.linalg.norm(obj - target)
    # Quirk: the initial distance is from the faucet base (obj_init_pos), not the handle.
    target_to_obj_init = jnp.linalg.norm(obj_init - target)
    in_place = tolerance(
        target_to_obj,
        bounds=(0.0, radius),
        margin=jnp.abs(target_to_obj_init - radius),
        sigmoid="long_tail",
    )
    reach_radius = 0.01
    tcp_to_obj = jnp.linalg.norm(obj - tcp)
    tcp_to_obj_init = jnp.linalg.norm(obj_init - step.constants["init_tcp"])
    reach = tolerance(
        tcp_to_obj,
        bounds=(0.0, reach_radius),
        margin=jnp.abs(tcp_to_obj_init - reach_radius),
        sigmoid="gaussian",
    )
    success = target_to_obj <= radius
    reward = jnp.where(success, 10.0, 2.0 * (2.0 * reach + 3.0 * in_place))
    return info_terms(
        reward,
        success=success,
        near_object=tcp_to_obj <= 0.01,
        grasp_reward=reach,  # object_grasped = reach
        in_place_reward=in_place,
        obj_to_target=target_to_obj,
    )


def faucet_open(step: StepInputs) -> tuple[Array, dict[str, Array]]:
    # Quirk: faucet-open shifts the observed handle by (-0.04, 0, 0.03); faucet-close does not.
    return _faucet(step, step.obs[4:7] + jnp.array([-0.04, 0.0, 0.03]))


def faucet_close(step: StepInputs) -> tuple[Array, dict[str, Array]]:
    return _faucet(step, step.obs[4:7])


def dial_turn(step: StepInputs) -> tuple[Array, dict[str, Array]]:
    """`SawyerDialTurnEnvV3.compute_reward` (v2): reach above the dial rim with the gripper
    closed, turn the rim point to the goal."""
    radius = 0.07  # TARGET_RADIUS
    frame = step.frame
    angle = frame.joint_qpos("knob_Joint_1")
    obj = frame.body_pos("dial") + 0.05 * jnp.stack([jnp.sin(angle), -jnp.cos(angle), 0.0 * angle])
    push_position = obj + jnp.array([0.05, 0.02, 0.09])
    push_init = step.constants["dial_push_position"]
    target = step.target_pos
    target_to_obj = jnp.linalg.norm(obj - target)
    # Quirk: the initial distance is from the push position (above the rim), not the rim point.
    target_to_obj_init = jnp.linalg.norm(push_init - target)
    in_place = tolerance(
        target_to_obj,
        bounds=(0.0, radius),
        margin=jnp.abs(target_to_obj_init - radius),
        sigmoid="long_tail",
    )
    reach_radius = 0.005
    tcp = frame.tcp_center
    tcp_to_obj = jnp.linalg.norm(push_position - tcp)
    tcp_to_obj_init = jnp.linalg.norm(push_init - step.constants["init_tcp"])
    reach = tolerance(
        tcp_to_obj,
        bounds=(0.0, reach_radius),
        margin=jnp.abs(tcp_to_obj_init - reach_radius),
        sigmoid="gaussian",
    )
    gripper_closed = jnp.minimum(jnp.maximum(0.0, step.action[-1]), 1.0)
    reach = hamacher_product(reach, gripper_closed)
    reward = 10.0 * hamacher_product(reach, in_place)
    return info_terms(
        reward,
        success=target_to_obj <= radius,
        near_object=tcp_to_obj <= 0.01,
        grasp_reward=reach,
        in_place_reward=in_place,
        obj_to_target=target_to_obj,
    )


# ---- plate slide (plate_slide.py) ------------------------------------------------------------


def _plate_terms(step: StepInputs, margin_offset: float) -> tuple[Array, Array, Array, Array, Array]:
    """Distances and tolerance terms every plate-slide variant shares; the side and back variants
    shrink both margins by TARGET_RADIUS (`margin_offset`)."""
    obj, target, tcp = step.obs[4:7], step.target_pos, step.frame.tcp_center
    obj_init_pos, init_tcp = step.constants["obj_init_pos"], step.constants["init_tcp"]
    obj_to_target = jnp.linalg.norm(obj - target)
    in_place = tolerance(
        obj_to_target,
        bounds=(0.0, TARGET_RADIUS),
        margin=jnp.linalg.norm(obj_init_pos - target) - margin_offset,
        sigmoid="long_tail",
    )
    tcp_to_obj = jnp.linalg.norm(tcp - obj)
    object_grasped = tolerance(
        tcp_to_obj,
        bounds=(0.0, TARGET_RADIUS),
        margin=jnp.linalg.norm(init_tcp - obj_init_pos) - margin_offset,
        sigmoid="long_tail",
    )
    return obj_to_target, in_place, tcp_to_obj, object_grasped, tcp


def _plate_info(
    reward: Array, obj_to_target: Array, in_place: Array, tcp_to_obj: Array, object_grasped: Array
) -> tuple[Array, dict[str, Array]]:
    reward = jnp.where(obj_to_target < TARGET_RADIUS, 10.0, reward)
    # Quirk: success is obj_to_target <= 0.07 while the reward's 10.0 needs < TARGET_RADIUS.
    return info_terms(
        reward,
        success=obj_to_target <= 0.07,
        near_object=tcp_to_obj <= 0.03,
        grasp_reward=object_grasped,
        in_place_reward=in_place,
        obj_to_target=obj_to_target,
    )


def plate_slide(step: StepInputs) -> tuple[Array, dict[str, Array]]:
    obj_to_target, in_place, tcp_to_obj, object_grasped, _ = _plate_terms(step, 0.0)
    reward = 8.0 * hamacher_product(object_grasped, in_place)
    return _plate_info(reward, obj_to_target, in_place, tcp_to_obj, object_grasped)


def plate_slide_side(step: StepInputs) -> tuple[Array, dict[str, Array]]:
    """plate-slide-side, -back and -back-side: reach reward, then 2 + 7 * in_place once the tcp is
    low and near the plate."""
    obj_to_target, in_place, tcp_to_obj, object_grasped, tcp = _plate_terms(step, TARGET_RADIUS)
    reward = jnp.where((tcp[2] <= 0.03) & (tcp_to_obj < 0.07), 2.0 + 7.0 * in_place, 1.5 * object_grasped)
    return _plate_info(reward, obj_to_target, in_place, tcp_to_obj, object_grasped)


# ---- sweep, sweep-into (reach_push_pick_place.py) ----------------------------------------------


def _sweep_reward(
    step: StepInputs, target: Array, grip_success_margin: float, x_z_success_margin: float
) -> tuple[Array, dict[str, Array]]:
    obj = step.obs[4:7]
    obj_to_target = jnp.linalg.norm(obj - target)
    tcp_to_obj = jnp.linalg.norm(obj - step.frame.tcp_center)
    in_place = tolerance(
        obj_to_target,
        bounds=(0.0, TARGET_RADIUS),
        margin=jnp.linalg.norm(step.constants["obj_init_pos"] - target),
        sigmoid="long_tail",
    )
    object_grasped = _pad_gripping_caging(step, obj, 0.02, grip_success_margin, x_z_success_margin)
    reward = 2.0 * object_grasped + 6.0 * hamacher_product(object_grasped, in_place)
    reward = jnp.where(obj_to_target < TARGET_RADIUS, 10.0, reward)
    return info_terms(
        reward,
        success=obj_to_target <= 0.05,
        near_object=tcp_to_obj <= 0.03,
        grasp_reward=object_grasped,
        in_place_reward=in_place,
        obj_to_target=obj_to_target,
    )


def sweep(step: StepInputs) -> tuple[Array, dict[str, Array]]:
    return _sweep_reward(step, step.target_pos, grip_success_margin=0.03, x_z_success_margin=0.005)


def sweep_into(step: StepInputs) -> tuple[Array, dict[str, Array]]:
    # The target's z follows the puck (so only x and y count), margin included.
    target = jnp.stack([step.target_pos[0], step.target_pos[1], step.obs[6]])
    return _sweep_reward(step, target, grip_success_margin=0.025, x_z_success_margin=0.01)


# ---- assembly, disassemble, peg-unplug-side, pick-out-of-hole, shelf-place, bin-picking ----------


# ---- basketball, soccer, stick-push, stick-pull, hammer, hand-insert -----------------------------


# ---- box-close, coffee-button, coffee-pull, coffee-push, lever-pull ------------------------------


# ---- door-close, door-lock, door-unlock, handle-press, handle-pull -------------------------------
