"""MJX-Warp's CPU calls replayed as recorded Warp graphs (`mwjax.warp_cpu_graphs`) step bit for bit
as Warp's eager calls do: CPU rollouts stay exactly reproducible."""

from __future__ import annotations

import threading

import jax
import numpy as np
import pytest

import mwjax
from mwjax import warp_cpu_graphs


@pytest.mark.skipif(jax.default_backend() != "cpu", reason="the replay is for the CPU backend")
def test_replayed_steps_equal_eager_steps():
    # A contact-rich scene (the grasped puck, table and bin walls) and a contact-free one.
    env = mwjax.make(["pick-place-v3", "reach-v3"], envs_per_task=2, seed=0)
    reset, step = jax.jit(env.reset), jax.jit(env.step)
    actions = jax.random.uniform(jax.random.key(1), (4, env.num_envs, 4), minval=-1, maxval=1)

    def rollout() -> list[np.ndarray]:
        state = reset(jax.random.key(0))
        out = []
        for a in actions:
            state = step(state, a)
            out += [np.asarray(state.obs), np.asarray(state.reward)]
            out += [np.asarray(x) for x in jax.tree.leaves(state.physics)]
        return out

    assert warp_cpu_graphs.enabled()
    replayed = rollout()
    with warp_cpu_graphs.eager():
        eager = rollout()
    for ours, theirs in zip(replayed, eager, strict=True):
        np.testing.assert_array_equal(ours, theirs)


def test_python_side_warp_work_waits_for_the_ffi_calls():
    """Building MJWarp data on the Python thread takes the lock that every FFI call (and so every
    graph recording) holds: a recording sees no Warp work from another thread."""
    from mujoco import mjx
    from warp._src.jax import ffi

    from mwjax.models import load_scene

    model = load_scene("sawyer_reach_v3.xml")
    done = threading.Event()
    worker = threading.Thread(target=lambda: (mjx.make_data(model, impl="warp"), done.set()))
    with ffi._FFI_CALLBACK_LOCK:  # as an FFI call on one of XLA's threads holds it
        worker.start()
        assert not done.wait(timeout=2.0)
    assert done.wait(timeout=120.0)
    worker.join()
