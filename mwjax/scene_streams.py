"""Runs the MJX-Warp calls of several scenes side by side, each scene on its own CUDA stream.

XLA runs a program's FFI calls one after another on one stream, and a scene's MJX-Warp step is a
chain of small kernels that fills a GPU only at tens of thousands of worlds: with one call per
scene, MT50's 36 scenes at 1,024 envs per task leave the GPU mostly idle (docs/performance.md).
XLA's own ways to run calls side by side fail here: recording Warp's kernels into XLA's command
buffers cannot take Warp's conditional graph nodes (the solver's loop), and stream annotations
find no stream inside a loop body.

`concurrently(fns, args)` traces each function (one scene's vmapped `mjx.step` or
`mjx.kinematics`) to a jaxpr, then evaluates the jaxprs side by side in the caller's trace,
inlining the calls that hold Warp calls (MJX-Warp's `custom_vmap`, jits), until each reaches a Warp
call. That round of calls becomes two FFI calls per scene, to mwjax's own target:

- a *launch* with the Warp call's operands and outputs (and aliases), which on a GPU captures the
  call into a CUDA graph on the scene's own stream, as Warp's "warp" graph mode does on XLA's
  stream (keyed by the addresses of the call's buffers, up to `_GRAPHS_PER_SCENE` per call), and
  replays it there after the work XLA's stream has queued, and returns at once;
- a *join*, which makes XLA's stream wait for the scene's stream. It takes the launch's outputs
  (aliased through, so that everything that reads them comes after it), the call's read-only
  inputs (so that XLA does not reuse their memory while the scene's stream reads them), and
  every launch's token output (so that all of the round's launches are issued before any join
  waits: the graphs run side by side).

The evaluation then goes on to the next round of Warp calls or the end. (One FFI call for a whole
round would do the same with fewer host calls, but XLA's compile time grows faster than linearly
with the aliased operands of one call: MT10's step compiled ~8x slower; docs/performance.md.)
On the CPU a launch runs its scene's Warp call to the end and a join does nothing, so a rollout is
bit for bit that of one Warp call per scene. `PhysicsConfig.concurrent_scenes` selects this; by
default an env on one GPU uses it (`physics.runs_scenes_together`; docs/performance.md has the
measurements).
"""

from __future__ import annotations

import collections
import ctypes
import dataclasses
import functools
import hashlib
import threading
from collections.abc import Callable, Generator, Sequence
from typing import Any

import jax
import jax.extend as jex
import numpy as np
import warp as wp
from jax._src import ffi as jffi
from warp._src.jax import ffi, xla_ffi

from mwjax import host_call

_TARGET = "mwjax_scene_streams"
# Graphs kept per call and scene (Warp's "warp" mode keeps 32 per callable).
_GRAPHS_PER_SCENE = 32


@dataclasses.dataclass
class _Call:
    """One Warp call of the trace: its callable and call id, operands and result types."""

    callable: ffi.FfiCallable
    call_id: int
    operands: list[Any]
    out_types: list[jax.ShapeDtypeStruct]
    aliases: dict[int, int]


@dataclasses.dataclass
class _Site:
    """One scene's part of a round: its Warp call, launched on the scene's stream (`call` set), or
    the wait for it on XLA's stream (`call` None). `slot` is the scene's place in the round (its
    stream and event); `inputs`/`outputs` count the Warp call's buffers."""

    call: tuple[ffi.FfiCallable, int] | None
    slot: int
    inputs: int = 0
    outputs: int = 0
    # The call's captured graphs by buffer addresses, least recently used first.
    graphs: collections.OrderedDict = dataclasses.field(default_factory=collections.OrderedDict)


_lock = threading.Lock()
_sites: dict[int, _Site] = {}
_callables: dict[str, ffi.FfiCallable] = {}


def concurrently(fns: Sequence[Callable[[Any], Any]], args: Sequence[Any]) -> list[Any]:
    """`[fn(arg) for fn, arg in zip(fns, args)]`, with the Warp calls the functions make issued
    together: each round of calls (every function's first, then every second, ...) launched on
    the scenes' streams, then joined (see the module's docstring). Warp calls inside loops or
    conditionals of a function are not supported (an error says so)."""
    _register_target()
    runs, trees = [], []
    for fn, arg in zip(fns, args, strict=True):
        closed, shape = jax.make_jaxpr(fn, return_shape=True)(arg)
        trees.append(jax.tree.structure(shape))
        runs.append(_interpret(closed.jaxpr, closed.consts, jax.tree.leaves(arg)))
    results: list[Any] = [None] * len(runs)
    pending = {i: _next_call(run, None, results, i) for i, run in enumerate(runs)}
    while pending := {i: call for i, call in pending.items() if call is not None}:
        order = sorted(pending)
        outputs = _issue_round([pending[i] for i in order])
        pending = {i: _next_call(runs[i], out, results, i) for i, out in zip(order, outputs, strict=True)}
    return [jax.tree.unflatten(tree, leaves) for tree, leaves in zip(trees, results, strict=True)]


def _next_call(run: Generator, sent: Any, results: list[Any], i: int) -> _Call | None:
    """Runs `run` to its next Warp call (returned) or to its end (its result goes to `results`)."""
    try:
        return run.send(sent)
    except StopIteration as end:
        results[i] = end.value
        return None


def _interpret(jaxpr: jex.core.Jaxpr, consts: Sequence[Any], args: Sequence[Any]) -> Generator:
    """Evaluates `jaxpr` in the current trace, inlining the calls that contain Warp calls, and
    yields at each Warp call for its outputs."""
    env: dict[Any, Any] = {}

    def read(var: Any) -> Any:
        return var.val if isinstance(var, jex.core.Literal) else env[var]

    env.update(zip(jaxpr.constvars, consts, strict=True))
    env.update(zip(jaxpr.invars, args, strict=True))
    for eqn in jaxpr.eqns:
        invals = [read(v) for v in eqn.invars]
        if _is_warp_call(eqn):
            outvals = yield _warp_call(eqn, invals)
        elif (inner := _inner_jaxpr(eqn)) is not None:
            outvals = yield from _interpret(inner.jaxpr, inner.consts, invals)
        else:
            bound = eqn.primitive.get_bind_params(eqn.params)
            # JAX 0.10 returns the parameters; earlier versions (subfuns, parameters).
            subfuns, params = bound if isinstance(bound, tuple) else ((), bound)
            outvals = eqn.primitive.bind(*subfuns, *invals, **params)
            outvals = outvals if eqn.primitive.multiple_results else [outvals]
        env.update(
            (v, x) for v, x in zip(eqn.outvars, outvals, strict=True) if not isinstance(v, jex.core.DropVar)
        )
    return [read(v) for v in jaxpr.outvars]


# Calls a trace may inline: their parameter holding the called jaxpr.
_CALLED = {"custom_vmap_call": "call", "pjit": "jaxpr", "jit": "jaxpr", "closed_call": "call_jaxpr"}


def _inner_jaxpr(eqn: Any) -> jex.core.ClosedJaxpr | None:
    """The jaxpr of a call to inline (it contains a Warp call), else None. A Warp call elsewhere
    (a loop's or a conditional's body) cannot join the others: an error."""
    if not any(_has_warp_call(jaxpr) for jaxpr in _held_jaxprs(eqn)):
        return None
    called = eqn.params.get(_CALLED.get(eqn.primitive.name, ""))
    if not isinstance(called, jex.core.ClosedJaxpr):
        raise NotImplementedError(f"mwjax.scene_streams: a Warp call inside {eqn.primitive.name}")
    return called


def _held_jaxprs(eqn: Any) -> list[jex.core.Jaxpr]:
    """The jaxprs among an equation's parameters (a call's, a loop's or a conditional's bodies)."""
    values = eqn.params.values()
    return [v.jaxpr if isinstance(v, jex.core.ClosedJaxpr) else v for v in values if _is_jaxpr(v)]


def _is_jaxpr(value: Any) -> bool:
    return isinstance(value, jex.core.ClosedJaxpr | jex.core.Jaxpr)


def _has_warp_call(jaxpr: jex.core.Jaxpr) -> bool:
    return any(_is_warp_call(eqn) or any(map(_has_warp_call, _held_jaxprs(eqn))) for eqn in jaxpr.eqns)


def _is_warp_call(eqn: Any) -> bool:
    return eqn.primitive is jffi.ffi_call_p and _warp_callable(eqn.params["target_name"]) is not None


def _warp_callable(name: str) -> ffi.FfiCallable | None:
    if name not in _callables:
        _callables.update({c.name: c for c in list(ffi._FFI_CALLABLE_REGISTRY.values())})
    return _callables.get(name)


def _warp_call(eqn: Any, operands: list[Any]) -> _Call:
    params = eqn.params
    call_id = dict(params["attributes"])["call_id"]
    out_types = [jax.ShapeDtypeStruct(a.shape, a.dtype) for a in params["result_avals"]]
    aliases = dict(params["input_output_aliases"])
    return _Call(_warp_callable(params["target_name"]), int(call_id), operands, out_types, aliases)


def _issue_round(calls: list[_Call]) -> list[list[Any]]:
    """One round: a launch per scene, then a join per scene (see the module's docstring)."""
    token = jax.ShapeDtypeStruct((), np.int32)
    launched, tokens = [], []
    for slot, call in enumerate(calls):
        site = _site(
            call, slot, _Site((call.callable, call.call_id), slot, len(call.operands), len(call.out_types))
        )
        flat = jax.ffi.ffi_call(_TARGET, [*call.out_types, token], input_output_aliases=call.aliases)(
            *call.operands, site=np.int64(site)
        )
        launched.append(flat[:-1])
        tokens.append(flat[-1])
    joined = []
    for slot, (call, outputs) in enumerate(zip(calls, launched, strict=True)):
        # The join takes the launch's outputs (aliased through: their consumers wait for it), the
        # inputs the call does not write (XLA may not reuse their memory while the scene's stream
        # reads them) and every launch's token (all launches are issued before any join waits).
        read_only = [
            x for i, x in enumerate(call.operands) if i not in call.aliases and isinstance(x, jax.Array)
        ]
        site = _site(call, slot, _Site(None, slot))
        aliases = {i: i for i in range(len(outputs))}
        joined.append(
            list(
                jax.ffi.ffi_call(_TARGET, call.out_types, input_output_aliases=aliases)(
                    *outputs, *read_only, *tokens, site=np.int64(site)
                )
            )
        )
    return joined


def _site(call: _Call, slot: int, site: _Site) -> int:
    """`site`'s id, registered. Named after its Warp call, whose id is stable across processes
    (`mwjax.warp_call_ids`), so that the program stays in JAX's persistent cache."""
    described = repr((call.callable.name, call.call_id, slot, site.call is None))
    key = int.from_bytes(hashlib.blake2b(described.encode(), digest_size=8).digest(), "little") >> 1
    with _lock:
        _sites.setdefault(key, site)
    return key


def _register_target() -> None:
    def handler_for(platform: str) -> Callable[[Any], Any]:
        return functools.partial(_callback, is_gpu=platform != "cpu")

    host_call.register_target(_TARGET, handler_for)


def _callback(call_frame: Any, is_gpu: bool) -> Any:
    try:
        frame = call_frame.contents
        if host_call.version_query(frame):
            return None
        attr = ctypes.cast(frame.attrs.attrs[0], ctypes.POINTER(xla_ffi.XLA_FFI_Scalar)).contents
        site = _sites[ctypes.cast(attr.value, ctypes.POINTER(ctypes.c_int64)).contents.value]
        inputs = ctypes.cast(frame.args.args, ctypes.c_void_p).value
        outputs = ctypes.cast(frame.rets.rets, ctypes.c_void_p).value
        if site.call is None:  # a join: on the CPU the launch ran the call to its end
            if is_gpu:
                _join(site, frame)
            return None
        with ffi._FFI_CALLBACK_LOCK:
            if is_gpu:
                _run_on_streams(site, frame, inputs, outputs)
            else:
                _run(site, inputs, outputs)
    except Exception as error:  # noqa: BLE001 - reported to XLA, which raises it in Python
        return xla_ffi.create_ffi_error(
            call_frame.contents.api,
            xla_ffi.XLA_FFI_Error_Code.UNKNOWN,
            f"mwjax.scene_streams: {type(error).__name__}: {error}",
        )
    return None


_BUFFER_PTR = ctypes.POINTER(xla_ffi.XLA_FFI_Buffer)


def _buffers(base: int, start: int, stop: int) -> Any:
    """The FFI buffer pointers [start, stop) of the array at address `base`."""
    return (_BUFFER_PTR * (stop - start)).from_address(base + start * ctypes.sizeof(ctypes.c_void_p))


def _arguments(site: _Site, inputs: int, outputs: int, device: wp.Device) -> list[Any]:
    callable_, call_id = site.call
    args, outs = _buffers(inputs, 0, site.inputs), _buffers(outputs, 0, site.outputs)
    return callable_._build_arg_list(args, outs, callable_.call_descriptors[call_id], device)


def _run(site: _Site, inputs: int, outputs: int) -> None:
    device = wp.get_device("cpu")
    args = _arguments(site, inputs, outputs, device)
    with wp.ScopedDevice(device):
        site.call[0].func(*args)


_DATA_OFFSET = xla_ffi.XLA_FFI_Buffer.data.offset
_BUFFER_SIZE = ctypes.sizeof(xla_ffi.XLA_FFI_Buffer)


def _data_pointers(base: int, count: int) -> np.ndarray:
    """The device addresses of the `count` FFI buffers whose descriptors' addresses start at
    `base`. Read one by one through ctypes they cost ~0.5 us each, milliseconds per call for
    thousands of buffers; XLA keeps a call's descriptors at a fixed stride (88 bytes in JAX
    0.10-0.11), so they are read as one strided block when the addresses show one."""
    if count == 0:
        return np.zeros(0, np.uint64)
    structs = np.ctypeslib.as_array((ctypes.c_uint64 * count).from_address(base)).copy()
    strides = np.diff(structs.astype(np.int64))
    stride = int(strides[0]) if count > 1 else _BUFFER_SIZE
    if np.all(strides == stride) and stride >= _BUFFER_SIZE and stride % 8 == 0:
        words, first = stride // 8, _DATA_OFFSET // 8
        block = (ctypes.c_uint64 * ((count - 1) * words + first + 1)).from_address(int(structs[0]))
        return np.ctypeslib.as_array(block)[first::words].copy()
    return np.array([ctypes.c_uint64.from_address(int(s) + _DATA_OFFSET).value for s in structs], np.uint64)


class _Streams:
    """Per device: a stream and an event for each scene, and the event XLA's stream records."""

    def __init__(self, device: wp.Device) -> None:
        self.device = device
        self.streams: list[wp.Stream] = []
        self.done: list[wp.Event] = []
        self.start = wp.Event(device)

    def get(self, count: int) -> list[wp.Stream]:
        while len(self.streams) < count:
            self.streams.append(wp.Stream(self.device))
            self.done.append(wp.Event(self.device))
        return self.streams


_streams: dict[int, _Streams] = {}


def _run_on_streams(site: _Site, frame: Any, inputs: int, outputs: int) -> None:
    """Launches the site's call on its scene's stream, after the work XLA's stream has queued."""
    core = wp._src.context.runtime.core
    xla_stream = xla_ffi.get_stream_from_callframe(frame)
    device, own = _device_streams(frame)
    stream = own.get(site.slot + 1)[site.slot]
    in_ptrs, out_ptrs = _data_pointers(inputs, site.inputs), _data_pointers(outputs, site.outputs)
    key = (device.ordinal, in_ptrs.tobytes(), out_ptrs.tobytes())
    core.wp_cuda_event_record(own.start.cuda_event, xla_stream, False)
    core.wp_cuda_stream_wait_event(stream.cuda_stream, own.start.cuda_event, False)
    capture = site.graphs.get(key)
    if capture is None:
        args = _arguments(site, inputs, outputs, device)
        ffi._load_ffi_module(wp.get_module(site.call[0].func.__module__), device)
        with wp.ScopedDevice(device), wp.ScopedStream(stream, sync_enter=False):
            with wp.ScopedCapture(stream=stream) as capture:
                site.call[0].func(*args)
        wp.capture_launch(capture.graph, stream=stream)
        site.graphs[key] = capture
        if len(site.graphs) > _GRAPHS_PER_SCENE:
            site.graphs.popitem(last=False)
    else:
        site.graphs.move_to_end(key)
        if not core.wp_cuda_graph_launch(capture.graph.graph_exec, stream.cuda_stream):
            raise RuntimeError(f"graph launch failed: {wp._src.context.runtime.get_error_string()}")
    core.wp_cuda_event_record(own.done[site.slot].cuda_event, stream.cuda_stream, False)


def _join(site: _Site, frame: Any) -> None:
    """XLA's stream waits for the work queued on the site's scene stream so far."""
    core = wp._src.context.runtime.core
    _, own = _device_streams(frame)
    own.get(site.slot + 1)
    core.wp_cuda_stream_wait_event(
        xla_ffi.get_stream_from_callframe(frame), own.done[site.slot].cuda_event, False
    )


def _device_streams(frame: Any) -> tuple[wp.Device, _Streams]:
    ordinal = xla_ffi.get_device_ordinal_from_callframe(frame)
    if ordinal not in _streams:
        _streams[ordinal] = _Streams(wp.get_cuda_device(ordinal))
    return _streams[ordinal].device, _streams[ordinal]
