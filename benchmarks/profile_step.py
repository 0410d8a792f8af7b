"""Where an env step's time goes: the same rollout with parts of `Env.step` removed.

    python benchmarks/profile_step.py --set MT10 --batch 65530 --steps 100

Variants, each a jitted `lax.scan` of `--steps` steps timed after a warm-up:
  env step            the public `env.step` (autoreset on)
  env step, no reset  `autoreset="disabled"`
  action + physics    metaworld's action written into the data, then the physics (no obs/reward)
  physics only        the physics calls alone (5 substeps + kinematics per scene)
  fast preset         `env.step` with 10 solver iterations (not the reference's physics)
"""

from __future__ import annotations

import argparse
import dataclasses
import datetime
import json
import time
from collections.abc import Callable
from pathlib import Path

import jax
from common import commit

import mwjax
from mwjax.benchmarks import task_names

RESULTS = Path(__file__).parent / "results" / "profile"


def rate(env: mwjax.Env, step: Callable, steps: int) -> float:
    def rollout(state: mwjax.State, key: jax.Array) -> mwjax.State:
        def body(state: mwjax.State, key: jax.Array) -> tuple:
            action = jax.random.uniform(key, (env.num_envs, 4), minval=-1.0, maxval=1.0)
            return step(state, action), None

        return jax.lax.scan(body, state, jax.random.split(key, steps))[0]

    run = jax.jit(rollout, donate_argnums=0)
    state = jax.block_until_ready(run(jax.jit(env.reset)(jax.random.key(0)), jax.random.key(1)))
    start = time.perf_counter()
    jax.block_until_ready(run(state, jax.random.key(2)))
    return env.num_envs * steps / (time.perf_counter() - start)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--set", default="MT10")
    parser.add_argument("--batch", type=int, default=65530)
    parser.add_argument("--steps", type=int, default=100)
    args = parser.parse_args()
    per_task = args.batch // len(task_names(args.set))

    env = mwjax.make(args.set, envs_per_task=per_task)
    plain = mwjax.make(args.set, envs_per_task=per_task, autoreset="disabled")
    fast = mwjax.make(
        args.set, envs_per_task=per_task, physics=mwjax.PhysicsConfig(iterations=10, ls_iterations=10)
    )

    def action_and_physics(state: mwjax.State, action: jax.Array) -> mwjax.State:
        datas = plain.physics.step(plain.apply_action(state.physics, action))
        return dataclasses.replace(state, physics=datas)

    def physics_only(state: mwjax.State, action: jax.Array) -> mwjax.State:
        return dataclasses.replace(state, physics=plain.physics.step(state.physics))

    variants = {
        "env step": (env, env.step),
        "env step, no reset": (plain, plain.step),
        "action + physics": (plain, action_and_physics),
        "physics only": (plain, physics_only),
        "fast preset": (fast, fast.step),
    }
    rows = {}
    for name, (which, step) in variants.items():
        rows[name] = rate(which, step, args.steps)
        print(f"{name:>20}: {rows[name]:>12,.0f} env steps/s", flush=True)
    device = jax.devices()[0]
    result = {
        "device": getattr(device, "device_kind", str(device)),
        "set": args.set,
        "num_envs": env.num_envs,
        "commit": commit(),
        "steps": args.steps,
        "date": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds"),
        "env_steps_per_s": rows,
    }
    name = f"profile-{args.set}-{result['device']}-{result['date'][:10]}".replace(" ", "_").replace(":", "_")
    out = RESULTS / f"{name}.json"
    out.write_text(json.dumps(result, indent=2))
    print(f"-> {out}")


if __name__ == "__main__":
    main()
