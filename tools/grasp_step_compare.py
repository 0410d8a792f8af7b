"""One env step off a box grasp, MJX-Warp against MuJoCo C (float64), with Warp's box-box pairs on
its mjc_BoxBox port (mwjax's default) and on its general convex path (Warp's own default).

The state: hand-insert, seed-42 goal 16, after 45 expert steps in mwjax. The box's velocity after
one more step, and the contact count at that state (read from Warp's private contact buffer,
for this diagnosis only).

    python tools/grasp_step_compare.py
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import mujoco
import numpy as np
from mujoco import mjx

import mwjax
from mwjax import policies
from mwjax.physics import PhysicsConfig
from mwjax.tasks import get_task

TASK, GOAL, STEPS = "hand-insert-v3", 16, 45
BOX_VEL = slice(9, 12)  # the box's free joint, linear velocity


def main() -> None:
    env = mwjax.make("MT1", task=TASK, seed=42, autoreset="disabled")
    expert, step = jax.jit(policies.expert_policy(env)), jax.jit(env.step)
    state = jax.jit(env.reset_with_variants)(jnp.array([GOAL]))
    for _ in range(STEPS):
        state = step(state, jnp.clip(expert(None, state.obs, None), -1.0, 1.0))
    action = jnp.clip(expert(None, state.obs, None), -1.0, 1.0)

    model = env.physics.groups[0].model
    data = mujoco.MjData(model)
    for field in ("qpos", "qvel", "mocap_pos", "mocap_quat", "qacc_warmstart", "ctrl"):
        getattr(data, field)[:] = np.asarray(getattr(state.physics[0], field)[0])
    mujoco.mj_forward(model, data)
    c_contacts = data.ncon
    low, high = (np.asarray(b, np.float64) for b in get_task(TASK).mocap_bounds)
    a = np.asarray(action[0], np.float64)
    data.mocap_pos[0] = np.clip(data.mocap_pos[0] + a[:3] / 100, low, high)
    data.mocap_quat[0] = [1.0, 0.0, 1.0, 0.0]
    data.ctrl[:] = [a[3], -a[3]]
    for _ in range(env.physics.config.substeps):
        mujoco.mj_step(model, data)
    print(
        f"MuJoCo C {mujoco.__version__}: {c_contacts} contacts, "
        f"box velocity {np.round(data.qvel[BOX_VEL], 5)}"
    )

    for label, collider in (("mjc_BoxBox port", "box_box"), ("convex path", "convex")):
        variant = env.replace(physics=PhysicsConfig(box_box_collider=collider))
        moved = jax.jit(lambda d, act, e=variant: e.physics.step(e.apply_action(d, act)))(
            state.physics, action
        )
        device = variant.physics.groups[0].device_model
        full = jax.jit(lambda s, e=variant: e.physics.data(0, s))(state.physics[0])
        forward = jax.jit(jax.vmap(mjx.forward, in_axes=(None, 0)))(device, full)
        contacts = int(np.asarray(forward._impl.nacon).ravel()[0])
        velocity = np.asarray(moved[0].qvel[0])[BOX_VEL]
        print(
            f"MJX-Warp, box-box on its {label}: {contacts} contacts, box velocity {np.round(velocity, 5)}, "
            f"max difference to C {np.abs(velocity - data.qvel[BOX_VEL]).max():.2g}"
        )


if __name__ == "__main__":
    main()
