"""Loading the recorded reference fixtures (tools/record_reference.py) and replaying them in mwjax."""

from __future__ import annotations

import dataclasses
import functools
import json
from collections.abc import Sequence
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np

import mwjax

FIXTURES = Path(__file__).parent / "fixtures" / "reference"


@functools.cache
def load(task: str) -> dict:
    with np.load(FIXTURES / f"{task}.npz") as archive:
        arrays = {key: archive[key] for key in archive.files}
    arrays["meta"] = json.loads(str(arrays["meta"]))
    return arrays


def recorded_tasks() -> list[str]:
    return sorted(p.stem for p in FIXTURES.glob("*-v3.npz"))


def shape(task: str) -> tuple[int, int]:
    """(resets, steps) recorded for `task`."""
    return load(task)["action"].shape[:2]


def rand_vec_rows(env: mwjax.Env, repeat: int) -> np.ndarray:
    """Each task's recorded goal variants, each repeated `repeat` times, in batch order."""
    width = max(v.shape[1] for v in env.goal_variants.values())
    vecs = [np.repeat(load(task)["rand_vec"], repeat, axis=0) for task in env.task_list]
    return np.concatenate([np.pad(v, ((0, 0), (0, width - v.shape[1]))) for v in vecs])


@dataclasses.dataclass(frozen=True)
class Replay:
    """mwjax's obs, reward and success on every recorded post-step state, per task, (R, T, ...)."""

    obs: dict[str, np.ndarray]
    reward: dict[str, np.ndarray]
    success: dict[str, np.ndarray]


def replay_recorded_states(
    tasks: list[str], reward_version: str = "v2", reference_init_tcp: Sequence[str] = ()
) -> Replay:
    """Loads each recorded post-step physics state into one batched env (one row per recorded
    step), with the recorded previous observation as the stacked frame, and evaluates it. Tasks in
    `reference_init_tcp` get the reference's recorded `init_tcp` episode constant.

    Constants latched on an episode's first step are evaluated on each reset's first recorded
    step, then given to that reset's later steps (evaluated as steps > 0, so they keep them)."""
    resets, steps = shape(tasks[0])
    env = mwjax.make(tasks, envs_per_task=resets * steps, reward_version=reward_version)
    order = env.task_list

    def rows(task: str, key: str) -> np.ndarray:
        value = load(task)[key]
        return value.reshape(resets * steps, *value.shape[2:])

    state = jax.jit(env.reset_to)(jnp.asarray(rand_vec_rows(env, steps)))
    recorded = {
        t: {
            "qpos": rows(t, "qpos"),
            "qvel": rows(t, "qvel"),
            "mocap_pos": rows(t, "mocap_pos")[:, 0],
            "mocap_quat": rows(t, "mocap_quat")[:, 0],
        }
        for t in order
    }
    state = jax.jit(env.with_physics_state)(state, recorded)
    init_tcp = np.array(state.constants["init_tcp"])
    for task in set(reference_init_tcp) & set(order):
        init_tcp[env.task_rows(task)] = np.repeat(load(task)["const_init_tcp"], steps, axis=0)
    state = dataclasses.replace(state, constants={**state.constants, "init_tcp": jnp.asarray(init_tcp)})
    actions = np.concatenate([rows(t, "action") for t in order])
    previous = [
        np.concatenate([load(t)["reset_obs"][:, None], load(t)["obs"][:, :-1]], axis=1) for t in order
    ]
    previous_obs = np.concatenate([p.reshape(resets * steps, -1) for p in previous])
    state = dataclasses.replace(state, obs=jnp.asarray(previous_obs, jnp.float32))
    observe = jax.jit(env.observe)
    first = observe(state, jnp.asarray(actions))
    episode_start = (np.arange(env.num_envs) // steps) * steps
    state = dataclasses.replace(
        state,
        constants={k: v[episode_start] for k, v in first.constants.items()},
        steps=jnp.asarray(np.arange(env.num_envs) % steps, jnp.int32),
    )
    state = observe(state, jnp.asarray(actions))

    def per_task(x: jax.Array) -> dict[str, np.ndarray]:
        x = np.asarray(x)
        return {t: x[env.task_rows(t)].reshape(resets, steps, *x.shape[1:]) for t in order}

    return Replay(
        obs=per_task(state.obs), reward=per_task(state.reward), success=per_task(state.info["success"])
    )
