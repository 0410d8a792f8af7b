"""Meta-World's V1 reward functions (`reward_function_version="v1"`, the original 2019 rewards) in
jax.numpy, one per task, on one env (vmapped by the core).

V1 rewards are sums of hand-tuned terms in the reference's units (hundreds to thousands), read
per-episode constants fixed at reset (`heightTarget`, `maxPlacingDist`, ...), and branch on
thresholds; every branch is a `where` here. Kernels return `(reward, info)` like V2's, with the
info terms the reference's `evaluate_state` builds from V1's `compute_reward` outputs.
"""

from __future__ import annotations

import jax.numpy as jnp

from mwjax.rewards_v2 import info_terms
from mwjax.tasks.spec import StepInputs

Array = jnp.ndarray


def progress_reward(dist: Array, max_dist: Array, c2: float = 0.01, c3: float = 0.001) -> Array:
    """V1's shaped progress toward a goal: 1000 (max_dist - dist) + 1000 (e^(-d²/c2) + e^(-d²/c3)).

    Not clipped: the reference clips it at 0 in most tasks, and callers do where it does."""
    return 1000.0 * (max_dist - dist) + 1000.0 * (jnp.exp(-(dist**2) / c2) + jnp.exp(-(dist**2) / c3))


# ---- reach, push, pick-place (and walls), push-back, sweep(-into), peg-insert-side, plate-slide --


# ---- door-open, drawer, buttons, window, handle-press-side, handle-pull-side, faucet, dial-turn ---


# ---- assembly, disassemble, peg-unplug-side, pick-out-of-hole, shelf-place, bin-picking ----------


# ---- basketball, soccer, stick-push, stick-pull, hammer, hand-insert -----------------------------


# ---- box-close, coffee-button, coffee-pull, coffee-push, lever-pull ------------------------------


# ---- door-close, door-lock, door-unlock, handle-press, handle-pull -------------------------------

__all__ = ["Array", "StepInputs", "info_terms", "progress_reward"]
