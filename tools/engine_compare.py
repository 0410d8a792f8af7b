"""The jax experts on one task with MuJoCo C (float64) stepping mwjax's own scene instead of Warp.

Each episode starts from mwjax's reset state for a goal variant (seed 42); every env step applies
the expert's action as the env does (hand mocap += clip(a)/100 within the task's mocap box,
fingers [a3, -a3]), runs the scene's substeps with `mujoco.mj_step`, and reads observation and
success back through `env.observe`. Comparing its success with `benchmarks/experts.py` separates
MJX-Warp's dynamics from everything else mwjax does (scene conversion, resets, rewards).

    python tools/engine_compare.py hand-insert-v3            # all 50 goals
"""

from __future__ import annotations

import argparse

import jax
import jax.numpy as jnp
import mujoco
import numpy as np

import mwjax
from mwjax import policies
from mwjax.tasks import get_task


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("task")
    parser.add_argument("--goals", type=int, nargs="*", default=list(range(50)))
    parser.add_argument("--steps", type=int, default=500)
    args = parser.parse_args()

    env = mwjax.make("MT1", task=args.task, seed=42, autoreset="disabled")
    expert = jax.jit(policies.expert_policy(env))
    observe, with_state = jax.jit(env.observe), jax.jit(env.with_physics_state)
    reset = jax.jit(env.reset_with_variants)
    model = env.physics.groups[0].model
    low, high = (np.asarray(b, np.float64) for b in get_task(args.task).mocap_bounds)
    failed = []
    for goal in args.goals:
        state = reset(jnp.array([goal]))
        start = state.physics[0]
        data = mujoco.MjData(model)
        for field in ("qpos", "qvel", "mocap_pos", "mocap_quat", "qacc_warmstart", "ctrl"):
            getattr(data, field)[:] = np.asarray(getattr(start, field)[0])
        mujoco.mj_forward(model, data)
        solved = False
        for _ in range(args.steps):
            action = np.clip(np.asarray(expert(None, state.obs, None))[0], -1.0, 1.0)
            data.mocap_pos[0] = np.clip(data.mocap_pos[0] + action[:3] / 100, low, high)
            data.mocap_quat[0] = [1.0, 0.0, 1.0, 0.0]
            data.ctrl[:] = [action[3], -action[3]]
            for _ in range(env.physics.config.substeps):
                mujoco.mj_step(model, data)
            fields = {"qpos": data.qpos, "qvel": data.qvel, "mocap_pos": data.mocap_pos[0]}
            fields["mocap_quat"] = data.mocap_quat[0]
            state = with_state(state, {args.task: {k: v[None] for k, v in fields.items()}})
            state = observe(state, jnp.asarray(action[None], jnp.float32))
            if bool(state.info["success"][0]):
                solved = True
                break
        if not solved:
            failed.append(goal)
    rate = 1 - len(failed) / len(args.goals)
    print(
        f"{args.task}: MuJoCo C {mujoco.__version__} on mwjax's scene, "
        f"success {rate:.2f}; failed goals {failed}"
    )


if __name__ == "__main__":
    main()
