"""Where does a task's physics diverge, and does MuJoCo C diverge from the same state?

Runs one task's envs through whole episodes under a stress policy of
`benchmarks/stress_buffers.py` (default `jammed`), finds every env step that mwjax flagged in
`info["physics_reset"]` (its state held a NaN or a value past `mjMAXVAL`), and replays that env
step in MuJoCo C (the same engine version, float64) from the state mwjax stepped it from: same
qpos, qvel, warm start, mocap poses and controls. It prints, per divergence, how fast the env
already moved before it and whether C's own checks (`mjWARN_BADQPOS/QVEL/QACC`) fired. With
`--lead L` it also replays the L env steps before it in C, from the state mwjax was in L steps
earlier, with the hand targets and gripper controls mwjax applied at each step (open loop): does C
run up to the same speeds, or stay calm where mwjax did not?

    python tools/divergence_probe.py --task peg-unplug-side-v3 --envs 1024 --policy jammed

Writes a JSON (and prints a table) under `benchmarks/results/fidelity/`.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import jax
import jax.numpy as jnp
import mujoco
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))

from common import provenance, result_path  # noqa: E402
from stress_buffers import POLICIES, stress_actions  # noqa: E402

import mwjax  # noqa: E402

FIELDS = ("qpos", "qvel", "qacc_warmstart", "mocap_pos", "mocap_quat", "ctrl")
BAD = (mujoco.mjtWarning.mjWARN_BADQPOS, mujoco.mjtWarning.mjWARN_BADQVEL, mujoco.mjtWarning.mjWARN_BADQACC)


def replay_in_c(model: mujoco.MjModel, start: dict[str, np.ndarray], substeps: int) -> dict:
    """One env step of MuJoCo C from `start` (the `FIELDS` of the state mwjax stepped from):
    which of C's own divergence checks fired, and its fastest joint speed after the step."""
    data = mujoco.MjData(model)
    for f, value in start.items():
        getattr(data, f)[:] = value
    mujoco.mj_step(model, data, nstep=substeps)
    return {
        "c_warnings": [w.name for w in BAD if data.warning[w].number],
        "c_qvel_max_after": float(np.nan_to_num(np.abs(data.qvel), nan=np.inf).max()),
    }


CONTROLS = ("mocap_pos", "mocap_quat", "ctrl")


def replay_run_up_in_c(model: mujoco.MjModel, states: list[dict[str, np.ndarray]], substeps: int) -> dict:
    """Env steps of MuJoCo C from `states[0]` (all `FIELDS`), then with each later state's
    `CONTROLS` written in before its step, as mwjax applied them: C's fastest joint speed after
    each step, and the first step (0-based) at which one of C's divergence checks fired."""
    data = mujoco.MjData(model)
    for f, value in states[0].items():
        getattr(data, f)[:] = value
    speeds, first_warning = [], None
    for k, state in enumerate(states):
        for f in CONTROLS:
            getattr(data, f)[:] = state[f]
        mujoco.mj_step(model, data, nstep=substeps)
        if first_warning is None and any(data.warning[w].number for w in BAD):
            first_warning = k
        speeds.append(float(np.nan_to_num(np.abs(data.qvel), nan=np.inf).max()))
    return {"c_run_up_qvel_max": speeds, "c_run_up_first_warning": first_warning}


def run_up(previous: dict | None, current: dict, i: int, row: int, lead: int) -> list[dict[str, np.ndarray]]:
    """The states mwjax stepped env `row` from in the `lead` env steps before step `i` of the
    current chunk and in that step, reaching back into the previous chunk where needed."""
    window = []
    for j in range(i - lead, i + 1):
        source, index = (current, j) if j >= 0 else (previous, j)
        if source is not None:
            window.append({f: np.asarray(source[f][index, row], np.float64) for f in FIELDS})
    return window


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--task", default="peg-unplug-side-v3")
    parser.add_argument("--envs", type=int, default=1024)
    parser.add_argument("--policy", choices=POLICIES, default="jammed")
    parser.add_argument("--steps", type=int, default=500)
    parser.add_argument("--chunk", type=int, default=50, help="steps per jitted call")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument(
        "--lead",
        type=int,
        default=30,
        help="env steps before each divergence also replayed in C, open loop (at most --chunk)",
    )
    args = parser.parse_args()
    if not 0 <= args.lead <= args.chunk:
        parser.error(f"--lead must be between 0 and --chunk ({args.chunk}), got {args.lead}")

    env = mwjax.make([args.task], envs_per_task=args.envs, seed=args.seed)
    act = stress_actions(env)
    policy = jnp.int32(POLICIES.index(args.policy))
    keys = jax.random.split(jax.random.key(args.seed + 1), 5)

    @jax.jit
    def chunk(state: mwjax.State, t0: jax.Array) -> tuple[mwjax.State, tuple]:
        def body(state: mwjax.State, t: jax.Array) -> tuple[mwjax.State, tuple]:
            action = act(policy, state.obs, t, keys)
            # What the physics steps from: the state with the action written in.
            applied = env.apply_action(state.physics, action)[0]
            state = env.step(state, action)
            return state, ({f: getattr(applied, f) for f in FIELDS}, state.info["physics_reset"])

        return jax.lax.scan(body, state, t0 + jnp.arange(args.chunk))

    t_start = time.perf_counter()
    state = jax.jit(env.reset)(jax.random.key(args.seed))
    found = []
    model = env.physics.groups[0].model
    substeps = env.physics.config.substeps
    previous = None
    for t0 in range(0, args.steps, args.chunk):
        state, (before, reset) = chunk(state, jnp.int32(t0))
        reset = np.asarray(reset)
        for i, row in zip(*np.nonzero(reset), strict=True):
            window = run_up(previous, before, int(i), int(row), args.lead)
            start = window[-1]
            found.append(
                {
                    "step": t0 + int(i) + 1,
                    "env": int(row),
                    "qvel_max_before": float(np.abs(start["qvel"]).max()),
                    "qvel_argmax_before": int(np.abs(start["qvel"]).argmax()),
                    **replay_in_c(model, start, substeps),
                    # mwjax's fastest joint before each env step of the window, C's after each.
                    "mwjax_run_up_qvel_max": [float(np.abs(s["qvel"]).max()) for s in window],
                    **replay_run_up_in_c(model, window, substeps),
                }
            )
            print(found[-1], flush=True)
        previous = before
        seconds = time.perf_counter() - t_start
        print(f"steps {t0 + args.chunk}: {len(found)} divergences ({seconds:.0f} s)", flush=True)

    result = {**provenance(), **vars(args), "divergences": found}
    out = result_path(
        "fidelity",
        f"divergence-{args.task}-{args.policy}-{args.envs}-seed{args.seed}-lead{args.lead}",
        ".json",
    )
    out.write_text(json.dumps(result, indent=1))
    c_too = sum(bool(d["c_warnings"]) for d in found)
    c_run_up = sum(d["c_run_up_first_warning"] is not None for d in found)
    print(
        f"{len(found)} env steps diverged in mwjax; MuJoCo C from the same states: {c_too}; "
        f"from {args.lead} env steps earlier with mwjax's controls: {c_run_up} -> {out}"
    )


if __name__ == "__main__":
    main()
