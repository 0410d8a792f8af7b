"""The GPU-determinism switch's plumbing, on the CPU: `MWJAX_DETERMINISTIC=1` puts Warp's
kernels in deterministic mode and XLA's flag in place before JAX starts, and the physics it
builds steps exactly as the default (the CPU is bit-reproducible either way)."""

from __future__ import annotations

import os
import sys
from pathlib import Path

import children
import jax
import numpy as np
import pytest

import mwjax
from mwjax import determinism, kernels
from mwjax.physics import PhysicsConfig, warp_model

ROLLOUT = """
import os, sys, jax, jax.numpy as jnp, numpy as np, warp
import mwjax
from mwjax import determinism
env = mwjax.make(["reach-v3"], envs_per_task=1, seed=0)
state, step = jax.jit(env.reset)(jax.random.key(0)), jax.jit(env.step)
for i in range(3):
    state = step(state, jax.random.uniform(jax.random.key(i), (1, 4), minval=-1, maxval=1))
np.save(sys.argv[1], np.asarray(state.obs))
modules = list(warp._src.context.user_modules.values())
assert determinism.enabled() == (os.environ.get("MWJAX_DETERMINISTIC") == "1")
assert all(m.options["deterministic"] == warp.config.deterministic for m in modules), "a module kept its mode"
named = warp._src.context.user_modules
bounds = {name: named[name].options.get("deterministic_max_records") for name in determinism.LOOP_RECORDS}
assert not determinism.enabled() or bounds == determinism.LOOP_RECORDS, bounds
graph_mode = env.physics.groups[0].device_model.opt._impl.graph_mode
from mujoco.mjx.third_party.mujoco_warp._src import solver
cone = getattr(solver, determinism.CONE_HESSIAN)
rehomed = cone.module.name != solver.__name__ and cone.module.options["deterministic_max_records"] >= 1
assert rehomed == determinism.enabled() and (not rehomed or cone.module.execs), "cone Hessian kernel"
assert determinism.enabled() == (graph_mode == warp.JaxCallableGraphMode.NONE), graph_mode
print(os.environ.get("XLA_FLAGS", ""))
"""


def _child(workdir: Path) -> tuple[list[str], dict[str, str]]:
    # The parent's XLA flags (the same compiler settings: the rollouts are compared bit for bit),
    # less the one the switch must add by itself.
    environ = {k: v for k, v in os.environ.items() if k != "MWJAX_DETERMINISTIC"}
    flags = [f for f in environ.get("XLA_FLAGS", "").split() if f != determinism.XLA_FLAG]
    environ |= {"XLA_FLAGS": " ".join(flags), "MWJAX_DETERMINISTIC": "1"}
    return [sys.executable, "-c", ROLLOUT, str(workdir / "obs.npy")], environ


@pytest.mark.child.with_args(_child)
def test_the_switch_reaches_warp_and_xla_and_steps_as_the_default(request):
    # Jitted, as the child: stepped op by op, each step compiles ~90 programs (its Warp calls
    # are traced afresh at every call), jitted 18 in all.
    env = mwjax.make(["reach-v3"], envs_per_task=1, seed=0)
    state, step = jax.jit(env.reset)(jax.random.key(0)), jax.jit(env.step)
    for i in range(3):
        state = step(state, jax.random.uniform(jax.random.key(i), (1, 4), minval=-1, maxval=1))
    run, workdir = children.result(request.node)
    assert run.returncode == 0, run.stderr[-3000:]
    assert "--xla_gpu_deterministic_ops=true" in run.stdout
    np.testing.assert_array_equal(np.load(workdir / "obs.npy"), np.asarray(state.obs))


def test_loop_records_cover_the_deepest_dof_chain_of_every_scene():
    # MJWarp's mass-matrix kernel records once per ancestor dof of each dof (mwjax.determinism).
    bound = determinism.LOOP_RECORDS["mujoco.mjx.third_party.mujoco_warp._src.smooth"]
    config = PhysicsConfig()
    for scene, bodies in kernels.scenes("MT50"):
        model = warp_model(scene, bodies, config)
        depths = []
        for dof in range(model.nv):
            depth = 0
            while dof >= 0:
                depth, dof = depth + 1, model.dof_parentid[dof]
            depths.append(depth)
        assert max(depths) <= bound, f"{scene}: a chain of {max(depths)} dofs"


def test_cone_hessian_records_cover_every_contact_a_thread_visits():
    # MJWarp launches the kernel on dim_block x ntri threads, each visiting ceil(naconmax /
    # dim_block) contacts with one record each (mwjax.determinism): the bound must cover that
    # for any batch, here from 1 to 409,600 envs of 64 contacts on GPUs of 16 to 132 SMs.
    for nv in (9, 12, 16):
        ntri = nv * (nv + 1) // 2
        for sm_count in (16, 108, 132):
            dim_block = -(-sm_count * 6 * 256 // ntri)
            for envs in (1, 1024, 13107, 409600):
                bound = determinism.cone_hessian_records(64 * envs, nv, sm_count)
                assert bound * dim_block >= 64 * envs and bound & (bound - 1) == 0
                assert bound < 2 * -(-64 * envs // dim_block) or bound == 1
