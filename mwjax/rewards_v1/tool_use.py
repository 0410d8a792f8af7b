"""V1 reward kernels of the stick-push, stick-pull, hammer tasks (`mwjax/tasks/tool_use.py`).

V1's tcp_to_obj is a hard-coded 0 in the stick tasks (not in hammer), so evaluate_state's
near_object (0 <= radius) is always 1 there.
"""

from __future__ import annotations

import jax.numpy as jnp

from mwjax.contracts import StepInputs
from mwjax.rewards_v1.terms import dropped_v1, pick_v1, progress_reward, reach_v1
from mwjax.rewards_v2.terms import info_terms

Array = jnp.ndarray


def _tool_v1(step: StepInputs, tool: Array, tool_height: Array, drop_dist: Array, carry: Array) -> Array:
    """stick-push, stick-pull and hammer: reach the tool, lift it to height_target, then earn
    `carry` (clipped at 0) while it is held up; `drop_dist` decides whether it was dropped."""
    height_target = step.constants["height_target"]
    # No planar phase: the reach term is -distance (plus the grip bonus within 5 cm).
    reach, reach_dist = reach_v1(step, tool, tool[2], jnp.inf, 0.0, 0.05)
    picked = tool[2] >= height_target - 0.01
    dropped = dropped_v1(tool[2], tool_height, drop_dist, reach_dist)
    pick = pick_v1(picked & ~dropped, tool[2], height_target, tool_height, reach_dist, 0.1)
    carrying = picked & (reach_dist < 0.1) & ~dropped
    return reach + pick + jnp.where(carrying, jnp.maximum(carry, 0.0), 0.0)


def _stick_v1(step: StepInputs, c2: float, c3: float) -> tuple[Array, Array]:
    """stick-push and stick-pull: bring the "object" to the stick, then it to the goal (in the
    plane). Quirk: the object is the observation's values 6 to 8, the stick's z and the first two
    components of its quaternion, not the thermos. Returns the reward and the object-goal distance."""
    stick = step.obs.obj
    obj = jnp.concatenate([stick[2:], step.obs.obj_quat[:2]])
    goal_dist = jnp.linalg.norm(obj[:2] - step.target_pos[:2])
    place_dist = jnp.linalg.norm(obj - stick)
    carry = progress_reward(place_dist, step.constants["max_place_dist"])
    # Within 5 cm of the stick, a second progress term with doubled exponentials.
    to_goal = 1000.0 * (step.constants["max_goal_dist"] - goal_dist)
    to_goal = to_goal + 2000.0 * (jnp.exp(-(goal_dist**2) / c2) + jnp.exp(-(goal_dist**2) / c3))
    carry = carry + jnp.where(place_dist < 0.05, to_goal, 0.0)
    return _tool_v1(step, stick, step.constants["stick_height"], goal_dist, carry), goal_dist


def stick_push(step: StepInputs) -> tuple[Array, dict[str, Array]]:
    reward, push_dist = _stick_v1(step, c2=0.001, c3=0.0001)
    # Success needs evaluate_state's grasp test, which requires V1's returned gripper opening
    # (a hard-coded 0) to be positive: V1 stick-push never succeeds.
    return info_terms(
        reward,
        success=False,
        near_object=1.0,
        grasp_reward=0.0,
        in_place_reward=0.0,
        obj_to_target=push_dist,
    )


def stick_pull(step: StepInputs) -> tuple[Array, dict[str, Array]]:
    reward, pull_dist = _stick_v1(step, c2=0.01, c3=0.001)
    # Success is V2's: the thermos handle near the goal with the stick hooked in it.
    handle, end_of_stick = step.obs.obj2, step.frame.site_pos("stick_end")
    inserted = (
        (end_of_stick[0] >= handle[0])
        & (jnp.abs(end_of_stick[1] - handle[1]) <= 0.040)
        & (jnp.abs(end_of_stick[2] - handle[2]) <= 0.060)
    )
    return info_terms(
        reward,
        success=(jnp.linalg.norm(handle - step.target_pos) <= 0.12) & inserted,
        near_object=1.0,
        grasp_reward=0.0,
        in_place_reward=0.0,
        obj_to_target=pull_dist,
    )


def hammer(step: StepInputs) -> tuple[Array, dict[str, Array]]:
    frame = step.frame
    nail = frame.site_pos("nailHead")
    hammer_dist = jnp.linalg.norm(nail - frame.geom_pos("HammerHead"))
    screw_dist = jnp.abs(nail[1] - step.target_pos[1])
    carry = progress_reward(hammer_dist + screw_dist, step.constants["max_hammer_dist"])
    reward = _tool_v1(step, step.obs.obj, step.constants["hammer_height"], hammer_dist, carry)
    # V1 returns 0 for the terms evaluate_state reports (near_object is its reward_ready).
    return info_terms(
        reward,
        success=frame.joint_qpos("NailSlideJoint") > 0.09,
        near_object=0.0,
        grasp_reward=0.0,
        in_place_reward=0.0,
        obj_to_target=0.0,
    )
