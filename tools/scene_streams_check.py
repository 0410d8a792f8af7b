"""Does an env step with its scenes on separate streams (`PhysicsConfig.concurrent_scenes`) follow
the same physics as with one call per scene?

Runs one seeded random-action rollout three times in this process: scenes in turn, in turn again,
then together. On the CPU all three must agree bit for bit. On a GPU, Warp's atomics make even two
runs in turn differ in the last bits, and a rollout amplifies that; the together run must stay as
close to the first as the second in-turn run does. The three envs start from the same per-goal
settled states (`mwjax.placement` computes them once per process for both kinds of env): that
settling amplifies tiny differences for a few tasks (peg-unplug-side most), and computed anew on
a GPU it would start those envs elsewhere, a difference of the reset, not of the step. Prints
per-step maximum observation differences, the tasks whose envs differ most (which scenes a fault
touches), a verdict (`follows_in_turn`: no env overflowed and no task's together difference
exceeds 10x its own in-turn noise, `beyond_noise`) and a JSON row (`--out`).

    XLA_PYTHON_CLIENT_MEM_FRACTION=0.45 python tools/scene_streams_check.py --set MT50 \\
        --envs-per-task 64 --steps 200
    JAX_PLATFORMS=cpu python tools/scene_streams_check.py --set reach-v3,door-lock-v3 \\
        --envs-per-task 2 --steps 5
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import jax
import numpy as np

sys.path.insert(0, str(Path(__file__).parents[1]))
import mwjax  # noqa: E402
from benchmarks.common import (  # noqa: E402
    add_scenes_per_call_argument,
    add_set_argument,
    provenance,
    scene_settings,
    tasks_arg,
)


def rollout(
    tasks: object, envs_per_task: int, steps: int, concurrent: bool, **settings: object
) -> tuple[np.ndarray, dict, list[str]]:
    env = mwjax.make(
        tasks,
        envs_per_task=envs_per_task,
        seed=0,
        physics=mwjax.PhysicsConfig(concurrent_scenes=concurrent, **settings),
        max_episode_steps=max(2, steps // 2),  # every env autoresets inside the rollout
    )

    def body(state: mwjax.State, key: jax.Array) -> tuple[mwjax.State, tuple[jax.Array, ...]]:
        action = jax.random.uniform(key, (env.num_envs, 4), minval=-1.0, maxval=1.0)
        state = env.step(state, action)
        return state, (state.obs, state.reward, state.info["physics_overflow"])

    run = jax.jit(lambda s, k: jax.lax.scan(body, s, jax.random.split(k, steps)))
    state = jax.jit(env.reset)(jax.random.key(0))
    t0 = time.perf_counter()
    compiled = run.lower(state, jax.random.key(1)).compile()
    compile_s = time.perf_counter() - t0
    t0 = time.perf_counter()
    _, (obs, reward, overflow) = jax.block_until_ready(compiled(state, jax.random.key(1)))
    first_s = time.perf_counter() - t0
    t0 = time.perf_counter()
    jax.block_until_ready(compiled(state, jax.random.key(1)))
    again_s = time.perf_counter() - t0
    timing = {"compile_s": compile_s, "first_run_s": first_s, "second_run_s": again_s}
    timing["concurrent"] = env.physics.config.concurrent_scenes
    timing["scenes_per_call"] = env.physics.config.scenes_per_call
    timing["overflow_envs"] = int((np.asarray(overflow) != 0).any(axis=0).sum())
    trajectory = np.concatenate([np.asarray(obs), np.asarray(reward)[..., None]], axis=-1)
    return trajectory, timing, list(env.task_list)


# A task's together rollout counts as apart from in turn when it differs by more than this many
# times the task's own in-turn noise (a second in-turn rollout), with a floor for tasks whose
# in-turn runs agree nearly exactly: one sample of chaotic noise varies a few-fold between tasks.
NOISE_FACTOR, NOISE_FLOOR = 10.0, 1e-4


def max_diff_per_task(
    first: np.ndarray, other: np.ndarray, names: list[str], envs_per_task: int
) -> dict[str, float]:
    """Over two rollouts `(steps, envs, ...)`, the largest difference in each task's envs (batch
    order is task by task): which scenes a fault touches."""
    diff = np.abs(other - first).reshape(len(first), len(names), envs_per_task, -1)
    return dict(zip(names, diff.max(axis=(0, 2, 3)).tolist(), strict=True))


def beyond_noise(again: dict[str, float], together: dict[str, float]) -> list[str]:
    """The tasks whose together difference exceeds `NOISE_FACTOR` times their in-turn noise."""
    return [task for task, diff in together.items() if diff > NOISE_FACTOR * max(again[task], NOISE_FLOOR)]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    add_set_argument(parser, default="MT10")
    parser.add_argument("--envs-per-task", type=int, default=16)
    parser.add_argument("--steps", type=int, default=100)
    add_scenes_per_call_argument(parser)
    parser.add_argument("--out", default=None, help="JSON path")
    args = parser.parse_args()
    tasks = tasks_arg(args.set)
    first, t_first, names = rollout(tasks, args.envs_per_task, args.steps, False)
    second, t_second, _ = rollout(tasks, args.envs_per_task, args.steps, False)
    together, t_together, _ = rollout(tasks, args.envs_per_task, args.steps, True, **scene_settings(args))

    def per_step(other: np.ndarray) -> list[float]:
        return np.abs(other - first).reshape(args.steps, -1).max(axis=1).tolist()

    again = max_diff_per_task(first, second, names, args.envs_per_task)
    apart = max_diff_per_task(first, together, names, args.envs_per_task)
    beyond = beyond_noise(again, apart)
    overflow = any(timing["overflow_envs"] for timing in (t_first, t_second, t_together))
    row = {
        "set": args.set,
        "envs_per_task": args.envs_per_task,
        "steps": args.steps,
        "in_turn_again_max_diff": per_step(second),
        "together_max_diff": per_step(together),
        "in_turn_again_max_diff_per_task": again,
        "together_max_diff_per_task": apart,
        "tasks_beyond_in_turn_noise": beyond,
        "follows_in_turn": not beyond and not overflow,
        "in_turn_again_identical": bool(np.array_equal(first, second)),
        "together_identical": bool(np.array_equal(first, together)),
        "timing": {"in_turn": t_first, "in_turn_again": t_second, "together": t_together},
        **provenance(),
    }
    for step in sorted({0, 1, 4, 9, args.steps // 2, args.steps - 1} & set(range(args.steps))):
        print(
            f"step {step + 1:>4}: max |diff| in turn again {row['in_turn_again_max_diff'][step]:.3g}, "
            f"together {row['together_max_diff'][step]:.3g}",
            flush=True,
        )
    worst = sorted(row["together_max_diff_per_task"].items(), key=lambda item: -item[1])[:5]
    print("tasks furthest apart together: " + ", ".join(f"{t} {d:.3g}" for t, d in worst), flush=True)
    verdict = "follows" if row["follows_in_turn"] else "does NOT follow"
    detail = f"tasks beyond the noise: {beyond or 'none'}; overflow: {overflow}"
    print(f"together {verdict} the in-turn physics ({detail})", flush=True)
    print(json.dumps({k: v for k, v in row.items() if "max_diff" not in k}), flush=True)
    if args.out:
        Path(args.out).parent.mkdir(parents=True, exist_ok=True)
        Path(args.out).write_text(json.dumps(row, indent=1) + "\n")


if __name__ == "__main__":
    main()
