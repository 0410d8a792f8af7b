"""Where does an env step's time go with its scenes on separate CUDA streams? Times one seeded
random-action rollout (ms per env step, best of `--repeats` after a warm-up) with the scenes' Warp
calls in turn, then together (`mwjax.scene_streams`) on one stream each, together on a single
stream (no overlap possible: what the streams alone cost or save), and together on streams made
non-blocking (Warp's own streams block on CUDA's legacy default stream), and together with the
scenes' graphs not launched at all (`no_physics`: the state stands still; what the rest of the step
costs). After the timed rollouts, one more rollout records a CUDA event before and after every graph
launch: the graphs' summed GPU time and the time at least one ran (their union) per env step,
against the step's wall time, say whether the GPU idles (host-bound) and whether graphs overlap;
the host's time inside Warp's FFI callbacks and mwjax's combined call, per env step, is timed too.

    XLA_PYTHON_CLIENT_MEM_FRACTION=0.45 python tools/scene_streams_probe.py --set MT10 --envs-per-task 64
"""

from __future__ import annotations

import argparse
import ctypes
import functools
import json
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import jax
import warp as wp
from warp._src.jax import ffi

sys.path.insert(0, str(Path(__file__).parents[1]))
import mwjax  # noqa: E402
import mwjax.physics  # noqa: E402, F401  (installs its patches of Warp's callback before HostTimer's)
from benchmarks.common import add_set_argument, provenance, tasks_arg  # noqa: E402
from mwjax import scene_streams  # noqa: E402


def nonblocking_streams(own: scene_streams._Streams, count: int) -> list[wp.Stream]:
    cuda = ctypes.CDLL("libcuda.so.1")
    while len(own.streams) < count:
        handle = ctypes.c_void_p()
        with own.device.context_guard:
            if cuda.cuStreamCreate(ctypes.byref(handle), 1):  # CU_STREAM_NON_BLOCKING
                raise RuntimeError("cuStreamCreate failed")
        own.streams.append(wp.Stream(own.device, cuda_stream=handle.value))
        own.done.append(wp.Event(own.device))
    return own.streams


def one_stream(own: scene_streams._Streams, count: int) -> list[wp.Stream]:
    if not own.streams:
        own.streams.append(wp.Stream(own.device))
    while len(own.done) < count:
        own.done.append(wp.Event(own.device))
    return [own.streams[0]] * count


def no_physics(*_: object) -> None:
    """Stands in for `scene_streams._run_on_streams`: launches nothing (outputs alias inputs)."""


class GraphTimeline:
    """Times every CUDA graph launch (Warp's own and `mwjax.scene_streams`') while `active`."""

    def __init__(self) -> None:
        self.active = False
        self.pairs: list[tuple[wp.Event, wp.Event]] = []
        wp.init()
        if not wp.is_cuda_available():
            return  # the CPU launches no CUDA graphs
        core = wp._src.context.runtime.core
        launch = core.wp_cuda_graph_launch

        def timed(graph_exec: object, stream: object) -> bool:
            if not self.active:
                return launch(graph_exec, stream)
            device = wp.get_cuda_device(0)
            start, end = wp.Event(device, enable_timing=True), wp.Event(device, enable_timing=True)
            core.wp_cuda_event_record(start.cuda_event, stream, True)
            ok = launch(graph_exec, stream)
            core.wp_cuda_event_record(end.cuda_event, stream, True)
            self.pairs.append((start, end))
            return ok

        core.wp_cuda_graph_launch = timed

    def summary(self, steps: int) -> dict:
        """Per env step: the graphs' summed time and their union (ms), and the launches."""
        if not self.pairs:
            return {"graph_launches": 0}
        origin = self.pairs[0][0]
        since = functools.partial(wp.get_event_elapsed_time, origin)
        spans = sorted((since(a), since(b)) for a, b in self.pairs)
        union, (low, high) = 0.0, spans[0]
        for a, b in spans[1:]:
            if a > high:
                union, low, high = union + high - low, a, b
            else:
                high = max(high, b)
        union += high - low
        self.pairs.clear()
        return {
            "graph_launches": len(spans),
            "graphs_sum_ms_per_step": sum(b - a for a, b in spans) / steps,
            "graphs_union_ms_per_step": union / steps,
        }


class HostTimer:
    """Host seconds spent inside the physics FFI callbacks while `active`."""

    def __init__(self) -> None:
        self.active = False
        self.seconds = 0.0
        callback = ffi.FfiCallable.ffi_callback
        ffi.FfiCallable.ffi_callback = self.wrap(callback)

    def wrap(self, fn: Callable[..., Any]) -> Callable[..., Any]:
        def timed(*args: Any) -> Any:
            if not self.active:
                return fn(*args)
            t0 = time.perf_counter()
            try:
                return fn(*args)
            finally:
                self.seconds += time.perf_counter() - t0

        return timed

    def summary(self, steps: int) -> dict:
        seconds, self.seconds = self.seconds, 0.0
        return {"host_callback_ms_per_step": 1000 * seconds / steps}


def time_variant(
    tasks: object,
    envs_per_task: int,
    steps: int,
    repeats: int,
    concurrent: bool,
    timeline: GraphTimeline,
    host: HostTimer,
) -> dict:
    env = mwjax.make(
        tasks, envs_per_task=envs_per_task, seed=0, physics=mwjax.PhysicsConfig(concurrent_scenes=concurrent)
    )

    def body(state: mwjax.State, key: jax.Array) -> tuple[mwjax.State, None]:
        action = jax.random.uniform(key, (env.num_envs, 4), minval=-1.0, maxval=1.0)
        return env.step(state, action), None

    run = jax.jit(lambda s, k: jax.lax.scan(body, s, jax.random.split(k, steps))[0])
    state = jax.jit(env.reset)(jax.random.key(0))
    compiled = run.lower(state, jax.random.key(1)).compile()
    state = jax.block_until_ready(compiled(state, jax.random.key(1)))
    times = []
    for i in range(repeats):
        t0 = time.perf_counter()
        state = jax.block_until_ready(compiled(state, jax.random.key(2 + i)))
        times.append(time.perf_counter() - t0)
    timeline.active = host.active = True
    state = jax.block_until_ready(compiled(state, jax.random.key(2 + repeats)))
    timeline.active = host.active = False
    row = {"ms_per_step": 1000 * min(times) / steps, "env_steps_per_s": env.num_envs * steps / min(times)}
    return row | timeline.summary(steps) | host.summary(steps)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    add_set_argument(parser, default="MT10")
    parser.add_argument("--envs-per-task", type=int, default=64)
    parser.add_argument("--steps", type=int, default=100)
    parser.add_argument("--repeats", type=int, default=2)
    parser.add_argument(
        "--variants", nargs="+", default=["in_turn", "streams", "one_stream", "nonblocking", "no_physics"]
    )
    parser.add_argument("--out", default=None, help="JSON path")
    args = parser.parse_args()
    tasks = tasks_arg(args.set)
    default_get = scene_streams._Streams.get
    default_run = scene_streams._run_on_streams
    rows = {}
    timeline = GraphTimeline()
    host = HostTimer()
    scene_streams._run_in_order = host.wrap(scene_streams._run_in_order)  # the CPU's combined call
    for variant in args.variants:
        scene_streams._streams.clear()
        getter = {"one_stream": one_stream, "nonblocking": nonblocking_streams}.get(variant, default_get)
        scene_streams._Streams.get = getter
        scene_streams._run_on_streams = host.wrap(no_physics if variant == "no_physics" else default_run)
        together = variant != "in_turn"
        rows[variant] = time_variant(
            tasks, args.envs_per_task, args.steps, args.repeats, together, timeline, host
        )
        print(variant, json.dumps(rows[variant]), flush=True)
    row = {"set": args.set, "envs_per_task": args.envs_per_task, "steps": args.steps, "variants": rows}
    row |= provenance()
    print(json.dumps(row), flush=True)
    if args.out:
        Path(args.out).write_text(json.dumps(row, indent=1) + "\n")


if __name__ == "__main__":
    main()
