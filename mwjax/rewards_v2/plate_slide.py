"""V2 reward kernels of the plate-slide (and its side and back variants) tasks
(`mwjax/tasks/plate_slide.py`).
"""

from __future__ import annotations

import jax.numpy as jnp

from mwjax.contracts import StepInputs
from mwjax.rewards_v2.terms import TARGET_RADIUS, grasp_place_info, hamacher_product, within

Array = jnp.ndarray


def _plate_terms(step: StepInputs, margin_offset: float) -> tuple[Array, Array, Array, Array, Array]:
    """Distances and tolerance terms every plate-slide variant shares; the side and back variants
    shrink both margins by TARGET_RADIUS (`margin_offset`)."""
    obj, target, tcp = step.obs.obj, step.target_pos, step.frame.tcp_center
    obj_init_pos, init_tcp = step.constants["obj_init_pos"], step.constants["init_tcp"]
    obj_to_target = jnp.linalg.norm(obj - target)
    in_place = within(obj_to_target, TARGET_RADIUS, jnp.linalg.norm(obj_init_pos - target) - margin_offset)
    tcp_to_obj = jnp.linalg.norm(tcp - obj)
    object_grasped = within(
        tcp_to_obj, TARGET_RADIUS, jnp.linalg.norm(init_tcp - obj_init_pos) - margin_offset
    )
    return obj_to_target, in_place, tcp_to_obj, object_grasped, tcp


def _plate_info(
    reward: Array, obj_to_target: Array, in_place: Array, tcp_to_obj: Array, object_grasped: Array
) -> tuple[Array, dict[str, Array]]:
    reward = jnp.where(obj_to_target < TARGET_RADIUS, 10.0, reward)
    # Quirk: success is obj_to_target <= 0.07 while the reward's 10.0 needs < TARGET_RADIUS.
    return grasp_place_info(
        reward, obj_to_target, tcp_to_obj, object_grasped, in_place, success_radius=0.07, near_radius=0.03
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
