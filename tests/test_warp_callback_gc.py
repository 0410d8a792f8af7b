"""Python's cyclic collector never starts inside a Warp FFI callback (`mwjax.warp_callback_gc`):
on a GPU a collection there can free a dropped render context's textures during a CUDA graph
capture, which CUDA refuses, breaking the capture."""

from __future__ import annotations

import contextlib
import gc
import os
import sys
from typing import Any

import jax
import pytest

import mwjax
from mwjax import scene_streams, warp_callback_gc, warp_cpu_graphs

# Side by side needs two scenes to run them through mwjax's own callback; in turn, one will do.
TASKS = {False: ["reach-v3"], True: ["reach-v3", "door-open-v3"]}
_WARP_FFI = os.path.join("warp", "_src", "jax", "ffi.py")


def _in_a_callback() -> bool:
    """Whether the calling thread is inside the work of a Warp FFI callback: Warp's own, its CPU
    replay (`mwjax.warp_cpu_graphs`) or mwjax's scene callback."""
    frame = sys._getframe(1)
    while frame is not None:
        code = frame.f_code
        if code.co_name == "ffi_callback" and code.co_filename.endswith(_WARP_FFI):
            return True
        if code in (scene_streams._run_in_order.__code__, warp_cpu_graphs._replay.__code__):
            return True
        frame = frame.f_back
    return False


def _collections(step: Any, state: Any, actions: jax.Array) -> tuple[dict[str, int], Any]:
    """Cyclic collections started inside and outside the callbacks over a call of the jitted
    `step`, with the collector's threshold at 1 (a collection at nearly every allocation)."""
    counts = {"inside": 0, "outside": 0}

    def count(phase: str, info: dict[str, Any]) -> None:
        if phase == "start":
            counts["inside" if _in_a_callback() else "outside"] += 1

    threshold = gc.get_threshold()
    gc.callbacks.append(count)
    gc.set_threshold(1)
    try:
        state = jax.block_until_ready(step(state, actions))
    finally:
        gc.set_threshold(*threshold)
        gc.callbacks.remove(count)
    return counts, state


@pytest.mark.parametrize("together", [False, True], ids=["in-turn", "side-by-side"])
def test_no_collection_starts_inside_a_warp_callback(together: bool, monkeypatch: pytest.MonkeyPatch):
    physics = mwjax.PhysicsConfig(concurrent_scenes=together)
    env = mwjax.make(TASKS[together], envs_per_task=1, seed=0, physics=physics)
    step = jax.jit(env.step)
    actions = jax.numpy.zeros((env.num_envs, 4))
    # Jitted: eagerly, each of the reset's operations would compile a program of its own.
    state = jax.jit(env.reset)(jax.random.key(0))
    state = jax.block_until_ready(step(state, actions))  # compiles
    held, state = _collections(step, state, actions)
    assert held["inside"] == 0 and held["outside"] > 0
    # Without the hold, the same steps do collect inside the callbacks: the check above can fail.
    monkeypatch.setattr(warp_callback_gc, "held", contextlib.nullcontext)
    assert _collections(step, state, actions)[0]["inside"] > 0
