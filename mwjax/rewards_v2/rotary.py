"""V2 reward kernels of the faucet, dial-turn, lever-pull tasks (`mwjax/tasks/rotary.py`)."""

from __future__ import annotations

import jax.numpy as jnp

from mwjax.contracts import StepInputs
from mwjax.rewards_v2.terms import grasp_place_info, hamacher_product, info_terms, tolerance, within

Array = jnp.ndarray


def _faucet(step: StepInputs, obj: Array) -> tuple[Array, dict[str, Array]]:
    """The shared V2 faucet reward: reach the handle (gaussian), turn it to the goal."""
    radius = 0.07  # the class's _target_radius
    tcp = step.frame.tcp_center
    target = step.target_pos
    obj_init = step.constants["obj_init_pos"]
    target_to_obj = jnp.linalg.norm(obj - target)
    # Quirk: the initial distance is from the faucet base (obj_init_pos), not the handle.
    target_to_obj_init = jnp.linalg.norm(obj_init - target)
    in_place = within(target_to_obj, radius, jnp.abs(target_to_obj_init - radius))
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
    return _faucet(step, step.obs.obj + jnp.array([-0.04, 0.0, 0.03]))


def faucet_close(step: StepInputs) -> tuple[Array, dict[str, Array]]:
    return _faucet(step, step.obs.obj)


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
    in_place = within(target_to_obj, radius, jnp.abs(target_to_obj_init - radius))
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
    return grasp_place_info(
        reward, target_to_obj, tcp_to_obj, reach, in_place, success_radius=radius, near_radius=0.01
    )


def lever_pull(step: StepInputs) -> tuple[Array, dict[str, Array]]:
    """`SawyerLeverPullEnvV3.compute_reward` (v2): get the arm's "shoulder" under the lever, lift
    the lever's end to the goal above its axis."""
    gripper, lever, target = step.obs.hand, step.obs.obj, step.target_pos
    lever_pos_init = step.constants["lever_pos_init"]
    # y de-emphasised; the offset puts the point below the fingers under the lever.
    scale = jnp.array([4.0, 1.0, 4.0])
    offset = jnp.array([0.0, 0.055, 0.07])
    shoulder_to_lever = jnp.linalg.norm((gripper + offset - lever) * scale)
    # Quirk: the initial distance mixes init_tcp (the finger centre) with the hand-based current one.
    shoulder_to_lever_init = jnp.linalg.norm((step.constants["init_tcp"] + offset - lever_pos_init) * scale)
    ready_to_lift = within(shoulder_to_lever, 0.02, shoulder_to_lever_init)
    lever_error = jnp.abs(-step.frame.joint_qpos("LeverAxis") - jnp.pi / 2.0)
    lever_engagement = within(lever_error, jnp.pi / 48.0, jnp.pi / 2.0 - jnp.pi / 12.0)
    in_place = within(jnp.linalg.norm(lever - target), 0.04, jnp.linalg.norm(lever_pos_init - target))
    # The reward ignores lever_engagement; success and in_place_reward use only it.
    reward = 10.0 * hamacher_product(ready_to_lift, in_place)
    return info_terms(
        reward,
        success=lever_error <= jnp.pi / 24.0,
        near_object=shoulder_to_lever < 0.03,
        grasp_reward=ready_to_lift,
        in_place_reward=lever_engagement,
        obj_to_target=shoulder_to_lever,  # the reference reports the shoulder distance here
    )
