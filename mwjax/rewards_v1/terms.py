"""The shared V1 terms: V1's progress reward and the reach / pick / place / fixture terms that
kernels of more than one family compose.
"""

from __future__ import annotations

import jax.numpy as jnp

from mwjax.contracts import StepInputs
from mwjax.rewards_v2.terms import info_terms

Array = jnp.ndarray


def progress_reward(dist: Array, max_dist: Array, c2: float = 0.01, c3: float = 0.001) -> Array:
    """V1's shaped progress toward a goal: 1000 (max_dist - dist) + 1000 (e^(-d²/c2) + e^(-d²/c3)).

    Not clipped: the reference clips it at 0 in most tasks, and callers do where it does."""
    return 1000.0 * (max_dist - dist) + 1000.0 * (jnp.exp(-(dist**2) / c2) + jnp.exp(-(dist**2) / c3))


# V1 counts the fixture as reached once the fingers are within 5 cm of it.
_REACHED = 0.05


def fixture_reward(
    obj: Array,
    finger: Array,
    dist: Array,
    max_dist: Array | float,
    clip: bool = True,
    c2: float = 0.01,
    c3: float = 0.001,
) -> Array:
    """-reachDist, plus (clipped) `progress_reward` toward the goal once within 5 cm of the fixture."""
    reach_dist = jnp.linalg.norm(obj - finger)
    return -reach_dist + progress_once_reached(reach_dist, dist, max_dist, clip, c2, c3)


def progress_once_reached(
    reach_dist: Array,
    dist: Array,
    max_dist: Array | float,
    clip: bool = True,
    c2: float = 0.01,
    c3: float = 0.001,
) -> Array:
    """`progress_reward` (clipped at 0 unless `clip` is off), counted only within 5 cm."""
    progress = progress_reward(dist, max_dist, c2, c3)
    if clip:
        progress = jnp.maximum(progress, 0.0)
    return jnp.where(reach_dist < _REACHED, progress, 0.0)


def fixture_info(reward: Array, dist: Array, success_radius: float) -> tuple[Array, dict[str, Array]]:
    """evaluate_state on V1\'s `(reward, 0, 0, dist, 0, 0)`: always near, success on `dist`."""
    return info_terms(
        reward,
        success=dist <= success_radius,
        near_object=1.0,
        grasp_reward=0.0,
        in_place_reward=0.0,
        obj_to_target=dist,
    )


def fixture_v1(
    step: StepInputs,
    dist: Array,
    max_dist: Array | float,
    success_radius: float,
    left_finger_only: bool = False,
    clip: bool = True,
    c2: float = 0.01,
    c3: float = 0.001,
) -> tuple[Array, dict[str, Array]]:
    """Reach the object (`obs.obj`) with the tcp (or left fingertip), then progress `dist` toward 0."""
    frame = step.frame
    finger = frame.site_pos("leftEndEffector") if left_finger_only else frame.tcp_center
    reward = fixture_reward(step.obs.obj, finger, dist, max_dist, clip, c2, c3)
    return fixture_info(reward, dist, success_radius)


def reach_v1(
    step: StepInputs, obj: Array, z_ref: Array, xy_radius: float, z_weight: float, grip_radius: float
) -> tuple[Array, Array]:
    """V1\'s reach term (planar, then 3-d, then a grip bonus within `grip_radius`) and reachDist."""
    tcp = step.frame.tcp_center
    reach_dist = jnp.linalg.norm(obj - tcp)
    reach_dist_xy = jnp.linalg.norm(obj[:2] - tcp[:2])
    far = -reach_dist_xy - z_weight * jnp.abs(tcp[2] - z_ref)
    reward = jnp.where(reach_dist_xy < xy_radius, -reach_dist, far)
    gripping = -reach_dist + jnp.maximum(step.action[-1], 0.0) / 50.0
    return jnp.where(reach_dist < grip_radius, gripping, reward), reach_dist


def dropped_v1(obj_z: Array, obj_height: Array, placing_dist: Array, reach_dist: Array) -> Array:
    """V1's `objDropped`: back on its start height, away from the goal and from the gripper."""
    return (obj_z < obj_height + 0.005) & (placing_dist > 0.02) & (reach_dist > 0.02)


def pick_v1(
    full: Array,
    obj_z: Array,
    height_target: Array,
    obj_height: Array,
    reach_dist: Array,
    reach_radius: float,
    baseline: Array | float = 0.0,
) -> Array:
    """V1\'s `pickRew`: 100 * (height reached, capped at height_target, - baseline); full when `full`."""
    lifting = (reach_dist < reach_radius) & (obj_z > obj_height + 0.005)
    reached = jnp.where(lifting, jnp.minimum(height_target, obj_z) - baseline, 0.0)
    return 100.0 * jnp.where(full, height_target - baseline, reached)


def place_v1(placing_dist: Array, max_placing_dist: Array) -> Array:
    """V1's `placeRew`: `progress_reward` toward the goal, clipped at 0."""
    return jnp.maximum(progress_reward(placing_dist, max_placing_dist), 0.0)


def pick_and_place_v1(
    step: StepInputs, lift: float, z_weight: float, head: Array | None = None
) -> tuple[Array, dict[str, Array]]:
    """V1's reach + pick + place reward (pick-place, pick-place-wall, peg-insert-side), from the
    pick-and-place vocabulary of the assembly section (`reach_v1`, `pick_v1`, `dropped_v1`,
    `place_v1`). peg-insert-side measures the place progress from the peg `head` until the head
    is within 5 cm of the goal.

    Per-episode constants as the reset computes them: objHeight is the object's height after
    placement, which is obj_init_pos's z (the geom or body it reads sits on the free joint's
    origin), heightTarget = objHeight + `lift`, and maxPlacingDist = |(obj_init_pos xy,
    heightTarget) - goal| + heightTarget.
    """
    obj, target = step.obs.obj, step.target_pos
    obj_init_pos = step.constants["obj_init_pos"]
    obj_height = obj_init_pos[2]
    height_target = obj_height + lift
    lifted_start = jnp.concatenate([obj_init_pos[:2], height_target[None]])
    max_placing_dist = jnp.linalg.norm(lifted_start - target) + height_target

    reach, reach_dist = reach_v1(step, obj, step.constants["init_tcp"][2], 0.05, z_weight, 0.05)
    placing_dist = jnp.linalg.norm(obj - target)
    picked = obj[2] >= height_target - 0.01
    dropped = dropped_v1(obj[2], obj_height, placing_dist, reach_dist)
    pick = pick_v1(picked & ~dropped, obj[2], height_target, obj_height, reach_dist, 0.1)
    place_dist = placing_dist
    if head is not None:
        head_dist = jnp.linalg.norm(head - target)
        place_dist = jnp.where(head_dist <= 0.05, placing_dist, head_dist)
    carrying = picked & (reach_dist < 0.1) & ~dropped
    place = jnp.where(carrying, place_v1(place_dist, max_placing_dist), 0.0)
    return fixture_info(reach + pick + place, placing_dist, success_radius=0.07)


def lift_and_place(step: StepInputs, pick_baseline: Array | float) -> tuple[Array, dict[str, Array]]:
    """pick-out-of-hole and shelf-place: reach, lift to height_target, carry to the goal."""
    c = step.constants
    obj = step.obs.obj
    height_target, obj_height = c["height_target"], c["obj_height"]
    reach, reach_dist = reach_v1(step, obj, c["init_tcp"][2], 0.05, 2.0, 0.05)
    placing_dist = jnp.linalg.norm(obj - step.target_pos)
    picked = obj[2] >= height_target - 0.01
    dropped = dropped_v1(obj[2], obj_height, placing_dist, reach_dist)
    pick = pick_v1(picked & ~dropped, obj[2], height_target, obj_height, reach_dist, 0.1, pick_baseline)
    carrying = picked & (reach_dist < 0.1) & ~dropped
    place = jnp.where(carrying, place_v1(placing_dist, c["max_placing_dist"]), 0.0)
    # evaluate_state reads V1's returned tcp_to_obj, a hard-coded 0, so near_object is always 1.
    return info_terms(
        reach + pick + place,
        success=placing_dist <= 0.07,
        near_object=1.0,
        grasp_reward=0.0,
        in_place_reward=0.0,
        obj_to_target=placing_dist,
    )
