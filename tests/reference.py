"""Loading the recorded reference fixtures (tools/record_reference.py) and replaying them in mwjax."""

from __future__ import annotations

import dataclasses
import functools
import json
import os
import sys
from collections.abc import Sequence
from pathlib import Path

import children
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import mwjax
from mwjax.tasks import TASKS

# Recorded by tools/record_reference.py; point MWJAX_REFERENCE_FIXTURES at a fresh recording (any
# seed, all tasks) to run the parity suite on it.
# Whole recorded episodes (tools/record_episodes.py), the engine-only baseline on them and the
# reference's own replay from a nudged start (tools/reference_baseline.py, without and with
# --perturb 1e-4); the variables point the suite at a fresh recording.
EPISODES = Path(os.environ.get("MWJAX_EPISODE_FIXTURES", Path(__file__).parent / "fixtures" / "episodes"))
BASELINE = Path(
    os.environ.get("MWJAX_EPISODE_BASELINE", Path(__file__).parent / "fixtures" / "episodes_baseline")
)
PERTURBED = Path(
    os.environ.get("MWJAX_EPISODE_PERTURBED", Path(__file__).parent / "fixtures" / "episodes_perturbed")
)
FIXTURES = Path(os.environ.get("MWJAX_REFERENCE_FIXTURES", Path(__file__).parent / "fixtures" / "reference"))


@functools.cache
def load(task: str) -> dict:
    """One task's parity recording (tools/record_reference.py)."""
    return load_episodes(FIXTURES, task)


def recorded_tasks() -> list[str]:
    return sorted(p.stem for p in FIXTURES.glob("*-v3.npz"))


def ported_tasks() -> list[str]:
    """The recorded tasks that mwjax implements."""
    return [task for task in recorded_tasks() if task in TASKS]


def shape(task: str) -> tuple[int, int]:
    """(resets, steps) recorded for `task`."""
    return load(task)["action"].shape[:2]


@dataclasses.dataclass(frozen=True)
class Replay:
    """mwjax's obs, reward and success on every recorded post-step state, per task, (R, T, ...)."""

    obs: dict[str, np.ndarray]
    reward: dict[str, np.ndarray]
    success: dict[str, np.ndarray]


REPLAY_FIELDS = [field.name for field in dataclasses.fields(Replay)]


def replay_recorded_states(
    tasks: list[str], versions: Sequence[str] = ("v2",), reference_init_tcp: Sequence[str] = ()
) -> dict[str, Replay]:
    """Loads each recorded post-step physics state into one batched env (one row per recorded
    step), with the recorded previous observation as the stacked frame, and evaluates it with
    each reward version of `versions` (one `Replay` each). Episode constants are mwjax's own, from
    its reset to each recorded goal, except that the tasks in `reference_init_tcp` get the
    reference's recorded `init_tcp`.

    Constants latched on an episode's first step are evaluated on each reset's first recorded
    step, then given to that reset's later steps (evaluated as steps > 0, so they keep them).
    The reset and the loaded state are the first version's; the versions differ only in the
    reward, so the others evaluate the same state (and compile only their own `observe`)."""
    resets, steps = shape(tasks[0])
    goals = {task: load(task)["rand_vec"] for task in tasks}
    env = mwjax.make(tasks, envs_per_task=resets * steps, reward_version=versions[0], goal_variants=goals)
    order = env.task_list

    def rows(task: str, key: str) -> np.ndarray:
        value = load(task)[key]
        return value.reshape(resets * steps, *value.shape[2:])

    state = jax.jit(env.reset_with_variants)(jnp.tile(jnp.repeat(jnp.arange(resets), steps), len(order)))
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
    for task in reference_init_tcp:
        init_tcp[env.task_rows(task)] = np.repeat(load(task)["const_init_tcp"], steps, axis=0)
    state = dataclasses.replace(state, constants={**state.constants, "init_tcp": jnp.asarray(init_tcp)})
    actions = jnp.asarray(np.concatenate([rows(t, "action") for t in order]))
    previous = [
        np.concatenate([load(t)["reset_obs"][:, None], load(t)["obs"][:, :-1]], axis=1) for t in order
    ]
    previous_obs = np.concatenate([p.reshape(resets * steps, -1) for p in previous])
    state = dataclasses.replace(state, obs=jnp.asarray(previous_obs, jnp.float32))
    episode_start = (np.arange(env.num_envs) // steps) * steps

    def per_task(x: jax.Array) -> dict[str, np.ndarray]:
        x = np.asarray(x)
        return {t: x[env.task_rows(t)].reshape(resets, steps, *x.shape[1:]) for t in order}

    replays = {}
    for version in versions:
        observe = jax.jit((env if version == versions[0] else env.replace(reward_version=version)).observe)
        first = observe(state, actions)
        latched = dataclasses.replace(
            state,
            constants={k: v[episode_start] for k, v in first.constants.items()},
            steps=jnp.asarray(np.arange(env.num_envs) % steps, jnp.int32),
        )
        final = observe(latched, actions)
        replays[version] = Replay(
            obs=per_task(final.obs), reward=per_task(final.reward), success=per_task(final.info["success"])
        )
    return replays


def load_episodes(directory: Path, task: str) -> dict:
    """One task's recording in `directory`, its JSON `meta` decoded: parity fixtures, episodes
    (tools/record_episodes.py) or a baseline (tools/reference_baseline.py)."""
    with np.load(directory / f"{task}.npz") as archive:
        arrays = {key: archive[key] for key in archive.files}
    arrays["meta"] = json.loads(str(arrays["meta"]))
    return arrays


def engine_reset_gap(task: str, rand_vec: np.ndarray) -> list[dict[str, float]] | None:
    """Per reset, how far the engine-only baseline's own reset (the reference's code on MuJoCo
    3.17) lands from the recorded one: `qpos/qvel/obs_max_abs_diff`, for the goals `rand_vec`
    if the baseline's recording is of those goals, else None."""
    if not (BASELINE / f"{task}.npz").exists() or not (EPISODES / f"{task}.npz").exists():
        return None
    episodes, baseline = load_episodes(EPISODES, task), load_episodes(BASELINE, task)
    recorded = episodes["rand_vec"]
    if baseline["meta"]["fixture_seed"] != episodes["meta"]["seed"] or len(recorded) < len(rand_vec):
        return None
    if not np.array_equal(recorded[: len(rand_vec)], rand_vec):
        return None
    return baseline["meta"]["own_reset_vs_fixture"][: len(rand_vec)]


# Steps of the parity free run (`parity_free_run`), from each parity recording's reset.
FREE_RUN_STEPS = 10


def _reset_arrays(env: mwjax.Env, state: mwjax.State, tasks: Sequence[str]) -> dict[str, dict]:
    """Per task, the reset state's qpos, qvel and observation."""
    out = {}
    for task in tasks:
        kin = env.kinematics(state, task)
        out[task] = {
            "reset_qpos": np.asarray(kin.qpos),
            "reset_qvel": np.asarray(kin.qvel),
            "reset_obs": np.asarray(state.obs[env.task_rows(task)]),
        }
    return out


def parity_free_run(all_tasks) -> dict[str, dict[str, np.ndarray]]:
    """mwjax's own trajectory from each parity recording's reset, driven by its recorded actions
    for `FREE_RUN_STEPS`: per task, the reset qpos/qvel/obs (R, ...) and the observations (R, T, 39)."""
    env = all_tasks.env
    state = all_tasks.reset_to_recorded(first_variant=0)
    out = _reset_arrays(env, state, env.task_list)
    actions = np.concatenate([load(t)["action"][:, :FREE_RUN_STEPS] for t in env.task_list])
    obs = []
    for t in range(FREE_RUN_STEPS):
        state = all_tasks.step(state, jnp.asarray(actions[:, t]))
        obs.append(np.asarray(state.obs))
    obs = np.stack(obs, axis=1)
    for task in env.task_list:
        out[task]["obs"] = obs[env.task_rows(task)]
    return out


def episode_free_run(all_tasks, tasks: Sequence[str]) -> dict[str, dict[str, np.ndarray]]:
    """mwjax's own episodes for the recorded ones in `EPISODES`: reset to each recorded goal, then
    the recorded actions, open loop. Per task: reset qpos/qvel/obs (R, ...) and per-step V2 reward
    and success (R, T). Runs every task of `all_tasks` (one env per recorded episode)."""
    env = all_tasks.env
    episodes = {task: load_episodes(EPISODES, task) for task in env.task_list}
    resets, steps = episodes[env.task_list[0]]["action"].shape[:2]
    actions = np.concatenate([e["action"] for e in episodes.values()])
    state = all_tasks.reset_to_recorded(first_variant=resets)
    out = _reset_arrays(env, state, tasks)
    reward, success = [], []
    for t in range(steps):
        state = all_tasks.step(state, jnp.asarray(actions[:, t]))
        reward.append(np.asarray(state.reward))
        success.append(np.asarray(state.info["success"]))
    reward, success = np.stack(reward, axis=1), np.stack(success, axis=1)
    for task in tasks:
        rows = env.task_rows(task)
        out[task].update(reward=reward[rows], success=success[rows])
    return out


# Steps of the short random-action run (`soak_run`; tests/test_soak.py has the long one).
SOAK_STEPS = 20


def soak_run(all_tasks) -> dict[str, dict[str, np.ndarray]]:
    """Random goal variants and uniform random actions (NumPy seed 0) for `SOAK_STEPS` steps: per
    task, whether each env's observation and reward were finite at each step, (envs, T)."""
    env = all_tasks.env
    rng = np.random.default_rng(0)
    variants = rng.integers(len(next(iter(env.goal_variants.values()))), size=env.num_envs)
    state = all_tasks.reset_with_variants(jnp.asarray(variants))
    finite = []
    for _ in range(SOAK_STEPS):
        state = all_tasks.step(state, jnp.asarray(rng.uniform(-1, 1, (env.num_envs, 4)), jnp.float32))
        finite.append(np.isfinite(np.asarray(state.obs)).all(axis=1) & np.isfinite(np.asarray(state.reward)))
    finite = np.stack(finite, axis=1)
    return {task: {"finite": finite[env.task_rows(task)]} for task in env.task_list}


# The free runs of the all-task env (`conftest.make_all_tasks`) in one child process: on the CPU
# it compiles the 36-scene reset and step once for test_parity, test_episodes and test_soak (~2
# minutes), on the second core while the parent runs the rest of the suite. The same child then
# replays test_parity's recorded states (`parity_replays`): on the 2-core CPU the parent's own work
# outlasts this child's, and the parent's last minutes run alone on one core, so the replay's
# minute and a half of CPU is cheaper here than in the parent.
_ALL_TASK_RUNS = """
import sys
import numpy as np
sys.path.insert(0, "tests")
from conftest import make_all_tasks
from reference import REPLAY_FIELDS, all_task_runs, parity_replays
all_tasks = make_all_tasks()
runs = all_task_runs(all_tasks)
for version, replay in parity_replays().items():
    runs[f"replay-{version}"] = {
        task: {field: getattr(replay, field)[task] for field in REPLAY_FIELDS} for task in replay.obs
    }
np.savez(sys.argv[1], **{f"{run}/{task}/{key}": value for run, tasks in runs.items()
                         for task, arrays in tasks.items() for key, value in arrays.items()})
"""


def all_task_runs(all_tasks, runs: Sequence[str] = ("parity", "episodes", "soak")) -> dict[str, dict]:
    """The free runs `runs` of every task: {"parity": ..., "episodes": ..., "soak": ...}."""
    tasks = sorted(p.stem for p in EPISODES.glob("*-v3.npz"))
    make = {"parity": parity_free_run, "episodes": lambda at: episode_free_run(at, tasks), "soak": soak_run}
    return {run: make[run](all_tasks) for run in runs}


def all_task_runs_child(workdir: Path) -> tuple[list[str], dict[str, str]]:
    """The `child` mark's command of the tests that read `all_task_runs` (tests/children.py)."""
    return [sys.executable, "-c", _ALL_TASK_RUNS, str(workdir / "runs.npz")], dict(os.environ)


def free_runs(request, run: str) -> dict[str, dict[str, np.ndarray]]:
    """`all_task_runs(...)[run]` for a module's tests: on the CPU read from the shared child,
    which one of the module's tests marked `child(all_task_runs_child)` anchors; elsewhere (a GPU
    holds one process's memory at a time) computed in this process."""
    anchor = _anchor(request)
    if anchor is None:
        return all_task_runs(request.getfixturevalue("all_tasks"), [run])[run]
    return _child_run(anchor, run)


def _anchor(request) -> pytest.Item | None:
    """The test of `request`'s module whose `child` mark runs `all_task_runs_child`, on the CPU."""
    module = request.module
    anchor = [i for i in request.session.items if i.module is module and i.get_closest_marker("child")]
    return anchor[0] if jax.default_backend() == "cpu" and anchor else None


def _child_run(anchor: pytest.Item, run: str) -> dict[str, dict[str, np.ndarray]]:
    result, workdir = children.result(anchor)
    assert result.returncode == 0, result.stderr[-3000:]
    out: dict[str, dict[str, np.ndarray]] = {}
    with np.load(workdir / "runs.npz") as arrays:
        for name in arrays.files:
            which, task, key = name.split("/")
            if which == run:
                out.setdefault(task, {})[key] = arrays[name]
    return out


# Given-state rewards use mwjax's own episode constants, except where a reset deviates
# (test_parity's RESET_DEVIATIONS) and the reward reads the settled hand: with its own `init_tcp`,
# door-unlock's V2 reward matches on 55% of seed 0's steps (one goal's settling finger strikes the
# lock, which moves the settled tcp by 7 mm), handle-press's and handle-pull's on 75% of seed 23's
# (the arm settles 1.3e-2 rad away in one goal, MuJoCo C 3.17 1.1e-2). Their reward kernels are
# checked with the reference's `init_tcp`; the whole-episode returns (test_episodes) use mwjax's own.
REFERENCE_INIT_TCP = ["door-unlock-v3", "handle-press-v3", "handle-pull-v3"]


def parity_replays() -> dict[str, Replay]:
    """test_parity's given-state replay: every ported task's recorded states, V2 and V1."""
    return replay_recorded_states(ported_tasks(), ("v2", "v1"), reference_init_tcp=REFERENCE_INIT_TCP)


def given_state_replays(request) -> dict[str, Replay]:
    """`parity_replays()` for test_parity: on the CPU read from the all-task child (see
    `free_runs`), elsewhere computed in this process."""
    anchor = _anchor(request)
    if anchor is None:
        return parity_replays()
    out = {}
    for version in ("v2", "v1"):
        arrays = _child_run(anchor, f"replay-{version}")
        fields = {key: {task: a[key] for task, a in arrays.items()} for key in REPLAY_FIELDS}
        out[version] = Replay(**fields)
    return out
