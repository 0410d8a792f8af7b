"""V1 reward kernels of the peg-insert-side, peg-unplug-side tasks (`mwjax/tasks/peg.py`)."""

from __future__ import annotations

import jax.numpy as jnp

from mwjax.contracts import StepInputs
from mwjax.rewards_v1.terms import pick_and_place_v1, place_v1, reach_v1
from mwjax.rewards_v2.terms import info_terms

Array = jnp.ndarray


def peg_insert_side(step: StepInputs) -> tuple[Array, dict[str, Array]]:
    # `obs.obj` is the peg's grasp site; away from the hole the place progress follows the peg head.
    return pick_and_place_v1(step, lift=0.11, z_weight=1.0, head=step.frame.site_pos("pegHead"))


def peg_unplug_side(step: StepInputs) -> tuple[Array, dict[str, Array]]:
    c = step.constants
    obj = step.obs.obj
    # Quirk: the height change is measured from hand_init_pos, not init_tcp.
    reach, reach_dist = reach_v1(step, obj, c["hand_init_pos"][2], 0.05, 2.0, 0.05)
    placing_dist = jnp.linalg.norm(obj[:2] - step.target_pos[:2])
    place = jnp.where(reach_dist < 0.05, place_v1(placing_dist, c["max_placing_dist"]), 0.0)
    # evaluate_state reads V1's returned tcp_to_obj, a hard-coded 0, so near_object is always 1.
    return info_terms(
        reach + place,
        success=placing_dist <= 0.07,
        near_object=1.0,
        grasp_reward=0.0,
        in_place_reward=0.0,
        obj_to_target=placing_dist,
    )
