"""V1 reward kernels of the assembly, disassemble tasks (`mwjax/tasks/assembly.py`)."""

from __future__ import annotations

import jax.numpy as jnp

from mwjax.contracts import StepInputs
from mwjax.rewards_v1.terms import dropped_v1, pick_v1, place_v1, progress_reward, reach_v1
from mwjax.rewards_v2.terms import info_terms

Array = jnp.ndarray


def assembly(step: StepInputs) -> tuple[Array, dict[str, Array]]:
    c = step.constants
    goal = step.target_pos
    height_target, obj_height = c["height_target"], c["obj_height"]
    # Reached at the observed handle point, placed by the nut body.
    reach, reach_dist = reach_v1(step, step.obs.obj, c["init_tcp"][2], 0.04, 1.0, 0.04)
    nut = step.frame.body_pos("RoundNut")
    placing_dist = jnp.linalg.norm(nut[:2] - goal[:2])
    height_error = jnp.abs(nut[2] - obj_height)
    picked = (nut[2] >= height_target - 0.01) & (reach_dist < 0.03)
    dropped = dropped_v1(nut[2], obj_height, placing_dist, reach_dist)
    over_peg = (jnp.abs(nut[0] - goal[0]) < 0.03) & (jnp.abs(nut[1] - goal[1]) < 0.03)
    pick = pick_v1(over_peg | (picked & ~dropped), nut[2], height_target, obj_height, reach_dist, 0.04)
    # Over the peg, a second (doubled, sharper) progress term rewards lowering back to the start height.
    place = progress_reward(placing_dist, c["max_placing_dist"])
    lowered = 2.0 * progress_reward(height_error, height_target, c2=0.003, c3=0.0003)
    place = place + jnp.where(over_peg, lowered, 0.0)
    carrying = over_peg | (picked & (reach_dist < 0.04) & ~dropped)
    place = jnp.where(carrying, jnp.maximum(place, 0.0), 0.0)
    # The reference reports only reward and success for V1 (the other terms are 0).
    return info_terms(
        reach + pick + place,
        success=over_peg & (height_error <= 0.04),
        near_object=0.0,
        grasp_reward=0.0,
        in_place_reward=0.0,
        obj_to_target=0.0,
    )


def disassemble(step: StepInputs) -> tuple[Array, dict[str, Array]]:
    c = step.constants
    obj = step.obs.obj
    height_target, obj_height = c["height_target"], c["obj_height"]
    reach, reach_dist = reach_v1(step, obj, c["init_tcp"][2], 0.04, 2.0, 0.04)
    placing_dist = jnp.linalg.norm(obj - step.target_pos)
    picked = (obj[2] >= height_target - 0.01) & (reach_dist < 0.04)
    dropped = dropped_v1(obj[2], obj_height, placing_dist, reach_dist)
    pick = pick_v1(picked & ~dropped, obj[2], height_target, obj_height, reach_dist, 0.04)
    carrying = picked & (reach_dist < 0.03) & ~dropped
    place = jnp.where(carrying, place_v1(placing_dist, c["max_placing_dist"]), 0.0)
    # Once the nut body is 5 cm off the peg in x or y, reach counts 0 and pick its maximum (the
    # place term is kept).
    nut, peg = step.frame.body_pos("RoundNut"), step.frame.body_pos("peg")
    off_peg = (jnp.abs(nut[0] - peg[0]) > 0.05) | (jnp.abs(nut[1] - peg[1]) > 0.05)
    reach = jnp.where(off_peg, 0.0, reach)
    pick = jnp.where(off_peg, 100.0 * height_target, pick)
    return info_terms(
        reach + pick + place,
        success=step.obs.obj[2] > step.target_pos[2],
        near_object=0.0,
        grasp_reward=0.0,
        in_place_reward=0.0,
        obj_to_target=0.0,
    )
