"""Env steps per second with batched pixel observations (`mwjax.rendering.PixelObservations`:
every env rendered at every step by MJWarp's ray tracer, inside one jitted `lax.scan`).

For each set and resolution it times, at the same batch size and after a warm-up rollout:
  - `steps_per_s`: env steps with RGB pixels (physics, rewards, autoreset and rendering);
  - `physics_steps_per_s`: the same rollout without pixels;
  - `render_frames_per_s`: rendering alone (the batch's images of one state, repeated);
so the row says where the time goes. One JSON row per measurement is printed (and appended to
`--out`, default `benchmarks/results/render/render-throughput-<device>-<date>.jsonl`).

    python benchmarks/render_throughput.py                      # MT1 pick-place and MT10, 64 and 128 px
    python benchmarks/render_throughput.py --sets MT10 --batch 16384 --sizes 64
    python benchmarks/render_throughput.py --video mt10.mp4     # also a video of 10 envs (experts)
    python benchmarks/render_throughput.py --sets MT10 --sizes 32 64 128 --render-only  # rendering alone

On a GPU it sets XLA_PYTHON_CLIENT_MEM_FRACTION=0.45 (unless set) so that JAX leaves Warp room.
"""

from __future__ import annotations

import os

os.environ.setdefault("XLA_PYTHON_CLIENT_MEM_FRACTION", "0.45")

import argparse  # noqa: E402
import datetime  # noqa: E402
import json  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

import jax  # noqa: E402
import jax.numpy as jnp  # noqa: E402
from common import RESULTS, commit, set_arg  # noqa: E402

import mwjax  # noqa: E402
from mwjax import rendering  # noqa: E402
from mwjax.benchmarks import task_names  # noqa: E402


def log(*args) -> None:
    print(*args, file=sys.stderr, flush=True)


def make_env(name: str, batch: int) -> mwjax.Env:
    if name.startswith("MT1:"):
        return mwjax.make("MT1", task=name.split(":", 1)[1], num_envs=batch)
    return mwjax.make(name, num_envs=batch)


def timed(fn, *args, repeats: int):
    """Warm-up call (compile + run), then the best of `repeats` calls: (seconds, compile seconds)."""
    start = time.perf_counter()
    jax.block_until_ready(fn(*args))
    compile_s = time.perf_counter() - start
    best = float("inf")
    for _ in range(repeats):
        start = time.perf_counter()
        jax.block_until_ready(fn(*args))
        best = min(best, time.perf_counter() - start)
    return best, compile_s


def rollout(step, steps: int, num_envs: int, pixels: bool):
    """A jitted scan of `steps` env steps with uniform random actions; returns a checksum."""

    def run(state, key):
        def body(carry, _):
            state, key, total = carry
            key, sub = jax.random.split(key)
            action = jax.random.uniform(sub, (num_envs, 4), minval=-1.0, maxval=1.0)
            state = step(state, action)
            seen = state.pixels[:, 0, 0, 0].astype(jnp.float32).sum() if pixels else state.reward.sum()
            return (state, key, total + seen), None

        (state, _, total), _ = jax.lax.scan(body, (state, key, jnp.float32(0)), None, length=steps)
        return state, total

    return jax.jit(run, donate_argnums=0)


def measure(name: str, batch: int, size: int, args, device: str) -> dict:
    env = make_env(name, batch)
    n = env.num_envs
    log(f"[{name} batch {n} {size}x{size}] building the renderer ...")
    start = time.perf_counter()
    pixel_env = rendering.PixelObservations(
        env,
        camera=args.camera,
        width=size,
        height=size,
        depth=args.depth,
        shadows=args.shadows,
        graph_mode=args.graph_mode,
    )
    build_s = time.perf_counter() - start
    key = jax.random.key(0)
    reset = jax.jit(pixel_env.reset)
    state = reset(key)
    jax.block_until_ready(state.pixels)

    holder = {"state": state}

    def rate(run, slot: str) -> tuple[float, float]:
        """Env steps/s of the rollout `run` carried on from `holder[slot]`, and its compile time."""

        def call():
            holder[slot], total = run(holder[slot], key)
            return total

        seconds, compile_s = timed(call, repeats=args.repeats)
        return n * args.steps / seconds, compile_s

    steps_per_s = compile_s = None
    if not args.render_only:
        log(f"[{name} batch {n} {size}x{size}] pixels rollout: compile + warm-up ...")
        steps_per_s, compile_s = rate(rollout(pixel_env.step, args.steps, n, pixels=True), "state")
        log(f"[{name} batch {n} {size}x{size}] {steps_per_s:,.0f} env steps/s with pixels")

    physics_steps_per_s = None
    if not args.no_baseline and not args.render_only:
        log(f"[{name} batch {n}] physics-only rollout ...")
        holder["plain"] = jax.jit(env.reset)(key)
        physics_steps_per_s, _ = rate(rollout(env.step, args.steps, n, pixels=False), "plain")
        log(f"[{name} batch {n}] {physics_steps_per_s:,.0f} env steps/s without pixels")
    if not args.no_baseline:
        log(f"[{name} batch {n} {size}x{size}] render-only ...")
        renders = 10
        renderer = pixel_env.renderer
        capture = jax.jit(renderer.capture)(holder["state"].state)

        def render_many(capture):
            def body(total, i):
                # A pose that depends on i, so that XLA cannot hoist the render out of the loop.
                moved = jax.tree.map(lambda x: x + jnp.float32(i) * 1e-9, capture)
                images = renderer.draw(moved)
                return total + images.rgb[:, 0, 0, 0].astype(jnp.float32).sum(), None

            return jax.lax.scan(body, jnp.float32(0), jnp.arange(renders))[0]

        render_seconds, _ = timed(jax.jit(render_many), capture, repeats=args.repeats)
        render_frames_per_s = n * renders / render_seconds
        log(f"[{name} batch {n} {size}x{size}] {render_frames_per_s:,.0f} frames/s rendering alone")
    else:
        render_frames_per_s = None

    return {
        "benchmark": "render_throughput",
        "device": device,
        "set": name,
        "batch": n,
        "resolution": f"{size}x{size}",
        "camera": args.camera,
        "depth": args.depth,
        "shadows": args.shadows,
        "graph_mode": args.graph_mode,
        "steps_per_rollout": args.steps,
        "steps_per_s": None if steps_per_s is None else round(steps_per_s),
        "physics_steps_per_s": None if physics_steps_per_s is None else round(physics_steps_per_s),
        "render_frames_per_s": None if render_frames_per_s is None else round(render_frames_per_s),
        "renderer_build_s": round(build_s, 2),
        "pixels_compile_s": None if compile_s is None else round(compile_s, 1),
        "commit": commit(),
        "date": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds"),
        "jax": jax.__version__,
    }


def video(args) -> None:
    """A video of envs of a jitted expert rollout: captures gathered in the scan, drawn afterwards."""
    from mwjax.policies import expert_policy

    name = args.sets[-1]
    env = mwjax.make("MT1", task=name.split(":", 1)[1]) if name.startswith("MT1:") else mwjax.make(name)
    envs = list(range(min(env.num_envs, 10)))
    renderer = rendering.Renderer(
        env, camera=args.camera, width=args.video_size, height=args.video_size, envs=envs
    )
    policy = expert_policy(env)

    def run(state):
        def body(state, _):
            action = jnp.clip(policy(None, state.obs, None), -1.0, 1.0)
            state = env.step(state, action)
            return state, renderer.capture(state)

        return jax.lax.scan(body, state, None, length=args.video_steps)[1]

    log(f"video: {args.video_steps} steps of {name}, envs {envs} ...")
    captures = jax.jit(run)(jax.jit(env.reset)(jax.random.key(0)))
    path = rendering.record_video(renderer, captures, args.video, fps=args.video_fps)
    log(f"video: wrote {path}")


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--sets", type=set_arg, nargs="+", default=["MT1:pick-place-v3", "MT10"])
    p.add_argument("--batch", type=int, nargs="+", default=[8192], help="total envs (MT10: a multiple of 10)")
    p.add_argument("--sizes", type=int, nargs="+", default=[64, 128])
    p.add_argument("--steps", type=int, default=100, help="env steps per timed rollout")
    p.add_argument("--repeats", type=int, default=3)
    p.add_argument("--camera", default="corner")
    p.add_argument("--depth", action="store_true", help="render depth too")
    p.add_argument("--shadows", action="store_true", help="cast the scene's shadows (a second ray per pixel)")
    p.add_argument("--graph-mode", help="the render calls' graph capture: warp, jax or none (default: MJX's)")
    p.add_argument("--no-baseline", action="store_true", help="skip the physics-only and render-only timings")
    p.add_argument("--render-only", action="store_true", help="time rendering alone (no rollouts)")
    p.add_argument("--out", help="JSON lines file to append rows to")
    p.add_argument("--video", help="also write a video (.mp4 or .gif) of up to 10 envs of the last set")
    p.add_argument("--video-size", type=int, default=128)
    p.add_argument("--video-steps", type=int, default=200)
    p.add_argument("--video-fps", type=int, default=40)
    p.add_argument("--only-video", action="store_true", help="write the video and skip the timings")
    args = p.parse_args(argv)

    device = jax.devices()[0].device_kind
    log(f"device: {device} ({jax.default_backend()}), commit {commit()[:10]}")
    if not args.only_video:
        today = datetime.date.today().isoformat()
        out = (
            Path(args.out)
            if args.out
            else RESULTS / "render" / f"render-throughput-{device.replace(' ', '_')}-{today}.jsonl"
        )
        out.parent.mkdir(parents=True, exist_ok=True)
        for name in args.sets:
            for batch in args.batch:
                n_tasks = 1 if name.startswith("MT1:") else len(task_names(name))
                batch = max(n_tasks, batch // n_tasks * n_tasks)
                for size in args.sizes:
                    try:
                        row = measure(name, batch, size, args, device)
                    except Exception as error:  # a failed size must not lose the other rows
                        row = {
                            "set": name,
                            "batch": batch,
                            "resolution": f"{size}x{size}",
                            "error": repr(error),
                        }
                        log(f"[{name} batch {batch} {size}x{size}] FAILED: {error!r}")
                    print(json.dumps(row), flush=True)
                    with out.open("a") as f:
                        f.write(json.dumps(row) + "\n")
        log(f"rows appended to {out}")
    if args.video:
        video(args)
    return 0


if __name__ == "__main__":
    sys.exit(main())
