"""Where MJX-Warp's physics time goes inside one scene's env step, function by function (GPU only).

    python benchmarks/profile_physics.py pick-place-v3 --batch 65536 --steps 100

`profile_step.py` splits an env step into env layer and physics; this splits the physics. It
builds the task's scene exactly as `mwjax.Physics` does (same model, same Warp flags, same
buffers), starts every world from an mwjax reset, and then drives the worlds like
`throughput.py` does: each env step moves the hand's mocap by a uniform random action (clipped
to the task's mocap box) and sets a random gripper command, then runs the 5 substeps and the
kinematics as one captured CUDA graph. MuJoCo-Warp's own event scopes (`forward`,
`collision`, `make_constraint`, `solve`, ...) time each function on the GPU; the table gives
milliseconds per env step and the share of the step, as a tree.

It calls MuJoCo-Warp directly (the copy MJX vendors) because MJX's jax API has no such hook;
it reads nothing back into mwjax.
"""

from __future__ import annotations

import argparse
import datetime
import json
import time
from pathlib import Path

import jax
import mujoco.mjx.third_party.mujoco_warp as mjw
import numpy as np
import warp as wp
from common import commit, rows_arg
from mujoco.mjx.third_party.mujoco_warp._src import smooth, warp_util

import mwjax
from mwjax.physics import warp_model

RESULTS = Path(__file__).parent / "results" / "profile"


@wp.kernel
def _random_action(
    seed: int,
    low: wp.vec3,
    high: wp.vec3,
    mocap_pos: wp.array2d(dtype=wp.vec3),
    ctrl: wp.array2d(dtype=float),
):
    world = wp.tid()
    rng = wp.rand_init(seed, world)
    delta = wp.vec3(wp.randf(rng, -1.0, 1.0), wp.randf(rng, -1.0, 1.0), wp.randf(rng, -1.0, 1.0))
    mocap_pos[world, 0] = wp.min(wp.max(mocap_pos[world, 0] + 0.01 * delta, low), high)
    grip = wp.randf(rng, -1.0, 1.0)
    ctrl[world, 0] = grip
    ctrl[world, 1] = -grip


def _totals(trace: dict, into: dict, path: tuple[str, ...] = ()) -> None:
    for name, (events, sub) in trace.items():
        key = (*path, name)
        into[key] = into.get(key, 0.0) + sum(events)
        _totals(sub, into, key)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("task")
    parser.add_argument("--batch", type=int, default=65536)
    parser.add_argument("--steps", type=int, default=100, help="env steps timed (after 20 untimed)")
    parser.add_argument("--contacts", type=int, default=None, help="PhysicsConfig.contacts_per_env")
    parser.add_argument(
        "--constraints", type=rows_arg, default=None, help="constraints_per_env: rows or per_scene"
    )
    parser.add_argument("--out", default=None)
    args = parser.parse_args()
    if not wp.get_device().is_cuda:
        raise SystemExit("profile_physics.py times CUDA events: it needs a GPU")
    buffers = {"contacts_per_env": args.contacts, "constraints_per_env": args.constraints}
    config = mwjax.PhysicsConfig(**{k: v for k, v in buffers.items() if v is not None})

    env = mwjax.make([args.task], envs_per_task=args.batch, physics=config)
    (group,) = env.physics.groups
    start = jax.jit(env.reset)(jax.random.key(0)).physics[0]
    spec = mwjax.tasks.TASKS[args.task]
    low, high = (wp.vec3(*np.asarray(b, np.float32)) for b in spec.mocap_bounds)

    model = mjw.put_model(warp_model(group.scene, group.mocap_bodies, config))
    rows = env.physics.constraint_rows(group.scene)
    data = mjw.make_data(
        group.model,
        nworld=args.batch,
        naconmax=args.batch * config.contacts_per_env,
        njmax=rows,
    )
    for field in ("qpos", "qvel", "mocap_pos", "mocap_quat", "qacc_warmstart", "ctrl"):
        getattr(data, field).assign(np.asarray(getattr(start, field)))

    def env_step_physics() -> None:
        for _ in range(config.substeps):
            mjw.step(model, data)
        warp_util.event_scope(smooth.kinematics, "kinematics")(model, data)

    env_step_physics()  # compiles or loads the kernels, outside the capture and the trace
    wp.synchronize()
    totals: dict[tuple[str, ...], float] = {}
    with warp_util.EventTracer() as tracer:
        with wp.ScopedCapture() as capture:
            env_step_physics()
        for step in range(20 + args.steps):
            wp.launch(
                _random_action,
                dim=args.batch,
                inputs=[step, low, high],
                outputs=[data.mocap_pos, data.ctrl],
            )
            if step == 20:
                wp.synchronize()
                t0 = time.perf_counter()
            wp.capture_launch(capture.graph)
            if step >= 20:
                _totals(tracer.trace(), totals)
        wp.synchronize()
        wall_s = time.perf_counter() - t0

    step_ms = sum(ms for key, ms in totals.items() if len(key) == 1) / args.steps
    lines = [
        f"# MJX-Warp physics profile: {args.task}, {args.batch} worlds",
        "",
        f"{args.steps} env steps (5 substeps + kinematics each) under random actions; "
        f"GPU time {step_ms:.2f} ms per env step = {args.batch / step_ms * 1e3:,.0f} env steps/s "
        f"(wall {args.batch * args.steps / wall_s:,.0f} env steps/s with tracing); "
        f"buffers {rows} rows, {config.contacts_per_env} contacts per env.",
        "",
        "| function | ms per env step | share |",
        "| --- | ---: | ---: |",
    ]
    for key, ms in sorted(totals.items()):
        per_step = ms / args.steps
        if per_step >= 0.01 * step_ms:
            name = "&nbsp;&nbsp;" * (len(key) - 1) + key[-1]
            lines.append(f"| {name} | {per_step:.3f} | {per_step / step_ms:.0%} |")
    report = "\n".join(lines)
    print(report, flush=True)
    device = wp.get_device().name
    date = datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds")
    name = f"profile-physics-{args.task}-{args.batch}-{device}-{date[:10]}".replace(" ", "_")
    out = Path(args.out) if args.out else RESULTS / f"{name}.json"
    out.write_text(
        json.dumps(
            {
                "task": args.task,
                "num_envs": args.batch,
                "device": device,
                "commit": commit(),
                "date": date,
                "steps": args.steps,
                "ms_per_env_step": {"/".join(k): v / args.steps for k, v in sorted(totals.items())},
                "report": report,
            },
            indent=2,
        )
    )


if __name__ == "__main__":
    main()
