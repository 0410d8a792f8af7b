"""V1 reward kernels of the plate-slide (and its side and back variants) tasks
(`mwjax/tasks/plate_slide.py`).
"""

from __future__ import annotations

import jax.numpy as jnp

from mwjax.contracts import StepInputs
from mwjax.rewards_v1.terms import fixture_v1

Array = jnp.ndarray


def _plate_slide_v1(step: StepInputs, start: Array) -> tuple[Array, dict[str, Array]]:
    """Reach the plate, then slide it toward the goal in xy; maxDist is |start - goal| in xy."""
    obj, target = step.obs.obj, step.target_pos
    pull_dist = jnp.linalg.norm(obj[:2] - target[:2])
    return fixture_v1(step, pull_dist, jnp.linalg.norm(start[:2] - target[:2]), success_radius=0.07)


def plate_slide(step: StepInputs) -> tuple[Array, dict[str, Array]]:
    """plate-slide and plate-slide-side: maxDist from obj_init_pos (rand_vec[:3])."""
    return _plate_slide_v1(step, step.constants["obj_init_pos"])


def plate_slide_back(step: StepInputs) -> tuple[Array, dict[str, Array]]:
    """plate-slide-back and -back-side: maxDist from the plate geom's position after placement,
    which differs from obj_init_pos (rand_vec[:3] there is the goal net's position)."""
    return _plate_slide_v1(step, step.constants["plate_init_pos"])
