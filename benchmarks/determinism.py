"""Are two runs bit-identical? The same seeded rollout in separate processes, hashed step by step.

Each process builds a task set, runs `--steps` env steps of seeded uniform random actions (500:
whole episodes, autoreset included) and fingerprints every step on device: the bits of the
observations, rewards, success flags and every scene's qpos and qvel, mixed into a 32-bit integer
per step with integer arithmetic only (whose sum does not depend on reduction order). The host
hashes the per-step fingerprints (SHA-256). `--runs` processes run one after another, or with
`--parallel` side by side, one GPU each (GPUs 0, 1, ..., or those `CUDA_VISIBLE_DEVICES` lists:
the same model on one host; `0,0` puts both runs on GPU 0); the script
reports whether all hashes agree, the first step where they part, and each run's rollout time, so
that `--deterministic` (`MWJAX_DETERMINISTIC=1` in the children: `mwjax.determinism`) against the
default gives both the answer and its cost.

    XLA_PYTHON_CLIENT_MEM_FRACTION=0.45 python benchmarks/determinism.py --set MT10 --envs-per-task 1024
    XLA_PYTHON_CLIENT_MEM_FRACTION=0.45 python benchmarks/determinism.py --set MT10 --envs-per-task 1024 \
        --deterministic
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import subprocess
import sys
import time

import numpy as np

from mwjax import distributed


def fingerprint(arrays: list) -> object:
    """A 32-bit integer of the exact bits of `arrays`, independent of reduction order."""
    import jax
    import jax.numpy as jnp

    total = jnp.uint32(0)
    for k, x in enumerate(arrays):
        bits = jax.lax.bitcast_convert_type(jnp.asarray(x, jnp.float32), jnp.uint32).ravel()
        weights = jnp.arange(1, bits.size + 1, dtype=jnp.uint32) * jnp.uint32(2654435761)
        total = total + jnp.sum(bits * weights + jnp.uint32(k), dtype=jnp.uint32)
    return total


def progress(text: str) -> None:
    """A progress line on stderr (the parent keeps stdout for the result)."""
    print(f"[{os.environ.get('CUDA_VISIBLE_DEVICES', 'run')}] {text}", file=sys.stderr, flush=True)


def child(args: argparse.Namespace) -> None:
    import jax
    import jax.numpy as jnp
    from common import build_kernels, tasks_arg

    import mwjax

    if args.build_only:  # Warp's modules into its cache, side by side, before the runs load them
        seconds = build_kernels(tasks_arg(args.set))
        progress(f"physics kernels ready in {seconds or 0:.0f} s")
        return
    env = mwjax.make(tasks_arg(args.set), envs_per_task=args.envs_per_task, seed=args.seed)

    def chunk(state: mwjax.State, keys: jax.Array) -> tuple[mwjax.State, jax.Array]:
        def body(state: mwjax.State, key: jax.Array) -> tuple:
            state = env.step(state, jax.random.uniform(key, (env.num_envs, 4), minval=-1.0, maxval=1.0))
            parts = [state.obs, state.reward, state.info["success"].astype(jnp.float32)]
            parts += [p.qpos for p in state.physics] + [p.qvel for p in state.physics]
            return state, fingerprint(parts)

        return jax.lax.scan(body, state, keys)

    t0 = time.perf_counter()
    start = jax.jit(env.reset)(jax.random.key(args.seed))
    keys = jax.random.split(jax.random.key(args.seed + 1), args.steps).reshape(-1, args.chunk)
    run = jax.jit(chunk).lower(start, keys[0]).compile()
    seconds = time.perf_counter() - t0
    progress(f"{env.num_envs} envs: reset and {args.chunk}-step rollout compiled in {seconds:.0f} s")
    rollouts = []
    for r in range(args.rollouts):
        # The first rollout includes Warp's first-call work (module loads, graph captures).
        t0, state, prints, digest = time.perf_counter(), start, [], hashlib.sha256()
        for c, chunk_keys in enumerate(keys):
            state, p = run(state, chunk_keys)
            prints.append(np.asarray(jax.block_until_ready(p)))
            digest.update(prints[-1].tobytes())
            # On stderr as it goes: a run cut short still shows how far the processes agreed.
            progress(f"rollout {r}, steps 1-{(c + 1) * args.chunk}: sha256 {digest.hexdigest()[:16]}")
        seconds = time.perf_counter() - t0
        rate = env.num_envs * args.steps / seconds
        rollouts.append({"sha256": digest.hexdigest(), "seconds": seconds, "env_steps_per_s": rate})
        progress(f"rollout {r} in {seconds:.1f} s ({rate:,.0f} env steps/s), sha256 {digest.hexdigest()}")
    device = jax.devices()[0]
    print(
        json.dumps(
            {
                "device": getattr(device, "device_kind", str(device)),
                "num_envs": env.num_envs,
                "rollout_s": rollouts[-1]["seconds"],
                "env_steps_per_s": rollouts[-1]["env_steps_per_s"],
                "sha256": rollouts[-1]["sha256"],
                "rollouts": rollouts,
                "steps": np.concatenate(prints).tolist(),
            }
        )
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--set", default="MT10", help="a set name, or task names separated by commas")
    parser.add_argument("--envs-per-task", type=int, default=16)
    parser.add_argument("--steps", type=int, default=500)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument(
        "--rollouts",
        type=int,
        default=2,
        help="rollouts per process, each from the same reset (the first includes Warp's first-call work; "
        "the last is compared across processes and timed)",
    )
    parser.add_argument("--chunk", type=int, default=None, help="steps per jitted call (default: all)")
    parser.add_argument("--runs", type=int, default=2, help="processes, one after another")
    parser.add_argument("--parallel", action="store_true", help="the runs side by side, one GPU each")
    parser.add_argument("--deterministic", action="store_true", help="MWJAX_DETERMINISTIC=1 in the runs")
    parser.add_argument("--out", default=None, help="JSON path for the summary")
    parser.add_argument("--child", action="store_true", help=argparse.SUPPRESS)
    parser.add_argument("--build-only", action="store_true", help=argparse.SUPPRESS)
    args = parser.parse_args()
    args.chunk = args.chunk or args.steps
    if args.steps % args.chunk or args.rollouts < 1:
        parser.error("--chunk must divide --steps, and --rollouts be at least 1")
    if args.child:
        child(args)
        return
    environ = dict(os.environ, MWJAX_DETERMINISTIC="1" if args.deterministic else "0")
    command = [
        sys.executable,
        __file__,
        "--child",
        "--set",
        args.set,
        "--envs-per-task",
        str(args.envs_per_task),
    ]
    command += ["--steps", str(args.steps), "--seed", str(args.seed)]
    command += ["--rollouts", str(args.rollouts), "--chunk", str(args.chunk)]
    # stderr (progress, Warp's messages) passes through; stdout carries each run's result.
    visible = os.environ.get("CUDA_VISIBLE_DEVICES")
    gpus = visible.split(",") if visible else [str(i) for i in range(args.runs)]
    # One GPU for the build: a list that names a GPU twice is not one CUDA accepts.
    build_env = dict(environ, CUDA_VISIBLE_DEVICES=gpus[0]) if visible else environ
    if subprocess.run([*command, "--build-only"], env=build_env).returncode:
        sys.exit("building the physics kernels failed; its messages are above")
    runs = []
    if args.parallel:
        if len(gpus) < args.runs:
            sys.exit(f"--parallel needs a GPU per run: {args.runs} runs, CUDA_VISIBLE_DEVICES={visible}")
        procs = [
            subprocess.Popen(
                command, env=dict(environ, CUDA_VISIBLE_DEVICES=gpus[i]), stdout=subprocess.PIPE, text=True
            )
            for i in range(args.runs)
        ]
        with distributed.sigterm_as_interrupt():  # `timeout` stops the runs too, not only this parent
            try:
                outputs = [(p.communicate()[0], p.returncode) for p in procs]
            except KeyboardInterrupt:
                distributed.stop(procs)
                sys.exit("stopped: the runs were terminated before they finished")
    else:
        outputs = []
        for _ in range(args.runs):
            done = subprocess.run(command, env=environ, stdout=subprocess.PIPE, text=True)
            outputs.append((done.stdout, done.returncode))
    for i, (stdout, code) in enumerate(outputs):
        if code:
            sys.exit(f"run {i} failed (exit {code}); its messages are above")
        runs.append(json.loads(stdout.strip().splitlines()[-1]) | {"gpu": gpus[i] if args.parallel else None})
        print(
            f"run {i}: {runs[-1]['sha256'][:16]}  {runs[-1]['env_steps_per_s']:,.0f} env steps/s", flush=True
        )
    steps = np.array([r.pop("steps") for r in runs])
    parted = np.nonzero((steps != steps[0]).any(axis=0))[0]
    summary = {
        "set": args.set,
        "deterministic": args.deterministic,
        "parallel": args.parallel,
        "steps": args.steps,
        "rollouts": args.rollouts,
        "identical": bool(parted.size == 0),
        # Each process's rollouts from one reset against each other (the same program run again).
        "repeats_in_process": all(len({x["sha256"] for x in r["rollouts"]}) == 1 for r in runs),
        "first_differing_step": int(parted[0]) if parted.size else None,
        "runs": runs,
    }
    print(json.dumps({k: v for k, v in summary.items() if k != "runs"}))
    if args.out:
        from common import provenance

        with open(args.out, "w") as f:
            json.dump({**provenance(), **summary}, f, indent=1)


if __name__ == "__main__":
    main()
