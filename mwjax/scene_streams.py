"""Runs the MJX-Warp calls of several scenes as one FFI call (or a few), each scene on its own CUDA stream.

XLA runs a program's FFI calls one after another on one stream, and a scene's MJX-Warp step is a
chain of small kernels that fills a GPU only at tens of thousands of worlds: with one call per
scene, MT50's 36 scenes at 1,024 envs per task leave the GPU mostly idle (docs/performance.md).
XLA's own ways to run calls side by side fail here: recording Warp's kernels into XLA's command
buffers cannot take Warp's conditional graph nodes (the solver's loop), and stream annotations
find no stream inside a loop body.

`concurrently(fns, args)` traces each function (one scene's vmapped `mjx.step` or
`mjx.kinematics`) to a jaxpr, then evaluates the jaxprs side by side in the caller's trace,
inlining the calls that hold Warp calls (MJX-Warp's `custom_vmap`, jits), until each reaches a Warp
call; those calls become one FFI call that takes all their operands and returns all their outputs
(or, with `per_call`, a few such calls one after another), and the evaluation goes on to the next
round of Warp calls or the end.

At run time the callback, on a GPU, captures each scene's Warp call into a CUDA graph on that
scene's own stream, as Warp's "warp" graph mode does on XLA's stream (keyed by the addresses of the
call's buffers, up to `_GRAPHS_PER_SCENE` per call and scene), and replays the graphs side by
side: every scene stream waits for XLA's stream, and XLA's stream waits for every scene stream
before the call returns. A scene whose Warp callable is in one of Warp's staged graph modes
(`PhysicsConfig.graph_mode="warp_staged_ex"` or `"warp_staged"`) is captured once instead, against
staging buffers, and each call copies its inputs in and its outputs out around the replay, as
"warp_staged_ex" does for a call of its own: a program run from Python (the Gymnasium adapter)
gets new buffers from XLA at every execution, so graphs keyed by address would never replay. On
the CPU it runs the scenes' Warp calls one after another, as the separate calls would (a check of
the plumbing). `PhysicsConfig.concurrent_scenes` selects this; by
default an env on one GPU uses it (`physics.runs_scenes_together`).

One call per round costs compile time: XLA's passes grow faster than linearly with one call's
aliased operands (the MT50 step compiled 3.3 times as long on an H200), so `per_call` splits a
round into calls of a few scenes each, run one after another (`PhysicsConfig.scenes_per_call`;
MT50 in four calls of 9: a third less compile at the same rate). Two calls per scene (a
launch that returns at once and a join that makes XLA's stream wait, tied by tokens) compiled as
fast as separate calls, but failed on the GPU with illegal memory accesses, cause not found
(docs/performance.md has both measurements).
"""

from __future__ import annotations

import collections
import ctypes
import dataclasses
import functools
import hashlib
import threading
import weakref
from collections.abc import Callable, Generator, Sequence
from typing import Any

import jax
import jax.extend as jex
import numpy as np
import warp as wp
from jax._src import ffi as jffi
from warp._src.jax import ffi, xla_ffi

from mwjax import device_memory, host_call, warp_callback_gc

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
    """One combined call: its Warp calls in order, each with its range of operands and outputs."""

    calls: list[tuple[ffi.FfiCallable, int]]
    inputs: list[tuple[int, int]]
    outputs: list[tuple[int, int]]
    # In a staged mode, the arguments copied at every call (None: those Warp's staged mode copies).
    live: frozenset[str] | None
    # Per call, its captured graphs by buffer addresses, least recently used first.
    graphs: list[collections.OrderedDict] = dataclasses.field(init=False)
    # Per call in a staged graph mode, its capture against staging buffers by device ordinal.
    stages: list[dict[int, _Stage]] = dataclasses.field(init=False)

    def __post_init__(self) -> None:
        self.graphs = [collections.OrderedDict() for _ in self.calls]
        self.stages = [{} for _ in self.calls]


@dataclasses.dataclass
class _Copies:
    """Device copies between a call's XLA buffers (`index`: its input or output numbers) and
    staging buffers, one batch per call: into the staging buffers before a replay, or out of
    them after it."""

    index: np.ndarray
    staging: np.ndarray  # staging addresses (uint64)
    sizes: np.ndarray  # bytes (uint64)
    inward: bool

    def run(self, pointers: np.ndarray, device: wp.Device, stream: wp.Stream) -> None:
        """Copies between the XLA buffers at `pointers` (the call's, by number) and the staging
        buffers, on `stream`."""
        if not len(self.index):
            return
        xla = np.ascontiguousarray(pointers[self.index], dtype=np.uint64)
        dsts, srcs = (self.staging, xla) if self.inward else (xla, self.staging)
        core = wp._src.context.runtime.core
        if not core.wp_memcpy_batch(
            device.context,
            dsts.ctypes.data,
            srcs.ctypes.data,
            self.sizes.ctypes.data,
            len(self.index),
            stream.cuda_stream,
        ):
            raise RuntimeError(f"staging copies failed: {wp._src.context.runtime.get_error_string()}")


@dataclasses.dataclass
class _Stage:
    """A scene call's arguments on staging buffers, the copies around each replay, and (once
    captured) its graph."""

    args: list[Any]
    buffers: list[wp.array]  # kept alive for the graph
    copy_in: _Copies
    copy_out: _Copies
    capture: Any = None


def _staged(callable_: ffi.FfiCallable, args: list[Any], live: frozenset[str] | None = None) -> _Stage:
    """`args` (a call's Warp arguments on XLA's buffers) moved onto staging buffers, as Warp's
    staged modes do (`FfiCallable._prepare_staging`): every non-empty array gets a staging copy;
    inputs named by the callable's `stage_in_argnames` (all if None) are copied in at every call,
    the others once, here; outputs named by `stage_out_argnames` are copied out at every call.
    With `live`, only the arguments it names among those are copied at every call: the others
    keep, between calls, what the last call left on their staging buffers, and their XLA
    outputs are left as XLA allocated them. Runs on the current device and stream."""
    staged, buffers = list(args), []
    copies: dict[bool, list[tuple[int, int, int]]] = {True: [], False: []}
    for i, arg in enumerate(args):
        if not (isinstance(arg, wp.array) and arg.size > 0):
            continue
        buffer = wp.empty_like(arg)
        staged[i] = buffer
        buffers.append(buffer)
        size = arg.size * wp.types.type_size_in_bytes(arg.dtype)
        name = callable_.args[i].name
        for inward, index, names in (
            (True, callable_.arg_input_indices[i], callable_.stage_in_argnames),
            (False, callable_.arg_output_indices[i], callable_.stage_out_argnames),
        ):
            if index is None:
                continue
            if (names is None or name in names) and (live is None or name in live):
                copies[inward].append((index, buffer.ptr, size))
            else:
                wp.copy(buffer, arg)
    return _Stage(staged, buffers, _copies(copies[True], True), _copies(copies[False], False))


def _copies(rows: list[tuple[int, int, int]], inward: bool) -> _Copies:
    """`_Copies` of (XLA buffer number, staging address, bytes) rows."""
    table = np.array(rows, np.uint64).reshape(-1, 3)
    return _Copies(table[:, 0].astype(np.int64), table[:, 1].copy(), table[:, 2].copy(), inward)


_lock = threading.Lock()
_sites: dict[int, _Site] = {}
_callables: dict[str, ffi.FfiCallable] = {}


def concurrently(
    fns: Sequence[Callable[[Any], Any]],
    args: Sequence[Any],
    per_call: int | None = None,
    live: frozenset[str] | None = None,
) -> list[Any]:
    """`[fn(arg) for fn, arg in zip(fns, args)]`, with the Warp calls the functions make issued
    together: each round of calls (every function's first, then every second, ...) as one FFI
    call that runs them side by side (see the module's docstring), or, with `per_call`, as calls
    of near-equal size of at most `per_call` functions each, one after another. Warp calls inside
    loops or conditionals of a function are not supported (an error says so). `live` names the
    Warp arguments that a staged call copies in and out at every call (`_staged`): those whose
    values the calls' results depend on and the caller reads; None copies what Warp's staged
    mode copies."""
    _register_target()
    runs, trees = [], []
    for fn, arg in zip(fns, args, strict=True):
        closed, shape = jax.make_jaxpr(_traceable(fn), return_shape=True)(arg)
        trees.append(jax.tree.structure(shape))
        runs.append(_interpret(closed.jaxpr, closed.consts, jax.tree.leaves(arg)))
    results: list[Any] = [None] * len(runs)
    pending = {i: _next_call(run, None, results, i) for i, run in enumerate(runs)}
    while pending := {i: call for i, call in pending.items() if call is not None}:
        order = sorted(pending)
        outputs = []
        for part in _parts(order, per_call or len(order)):
            outputs += _combined_call([pending[i] for i in part], live)
        pending = {i: _next_call(runs[i], out, results, i) for i, out in zip(order, outputs, strict=True)}
    return [jax.tree.unflatten(tree, leaves) for tree, leaves in zip(trees, results, strict=True)]


_traceables: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


def _traceable(fn: Callable[[Any], Any]) -> Callable[[Any], Any]:
    """`fn` for `jax.make_jaxpr`, named by code: JAX names a traced function by its code or else
    by `str(fn)`, which for a vmapped partial over an MJX model prints every array of the model
    (seconds per MT50 step). One wrapper per `fn`, so that JAX's trace cache, keyed by the
    function, still finds a function traced before; the wrapper holds `fn` weakly, or the table's
    entry would keep `fn` (and its model) alive for good."""
    if fn not in _traceables:
        _traceables[fn] = functools.partial(_apply, weakref.ref(fn))
    return _traceables[fn]


def _apply(fn: weakref.ref, arg: Any) -> Any:
    return fn()(arg)


def _parts(order: list[int], per_call: int) -> list[list[int]]:
    """`order` in consecutive parts of at most `per_call`, as few as that allows, of sizes that
    differ by at most one (9 scenes at 4 per call: 3, 3, 3, not 4, 4, 1)."""
    count = -(-len(order) // per_call)
    bounds = [len(order) * k // count for k in range(count + 1)]
    return [order[a:b] for a, b in zip(bounds[:-1], bounds[1:], strict=True)]


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


def _combined_call(calls: list[_Call], live: frozenset[str] | None) -> list[list[Any]]:
    operands: list[Any] = []
    out_types: list[jax.ShapeDtypeStruct] = []
    aliases: dict[int, int] = {}
    inputs, outputs = [], []
    for call in calls:
        aliases.update({len(operands) + i: len(out_types) + o for i, o in call.aliases.items()})
        inputs.append((len(operands), len(operands) + len(call.operands)))
        outputs.append((len(out_types), len(out_types) + len(call.out_types)))
        operands.extend(call.operands)
        out_types.extend(call.out_types)
    # The site's id names its Warp calls, whose own ids are stable across processes
    # (`mwjax.warp_call_ids`), so that the program stays in JAX's persistent cache.
    # Only a staged call copies, so only there does `live` tell sites apart.
    if not any(call.callable.graph_mode in _STAGED_MODES for call in calls):
        live = None
    described = repr([(call.callable.name, call.call_id) for call in calls])
    if live is not None:
        described += repr(sorted(live))
    site = int.from_bytes(hashlib.blake2b(described.encode(), digest_size=8).digest(), "little") >> 1
    with _lock:
        if site not in _sites:
            _sites[site] = _Site([(call.callable, call.call_id) for call in calls], inputs, outputs, live)
    flat = jax.ffi.ffi_call(_TARGET, out_types, input_output_aliases=aliases, has_side_effect=False)(
        *operands, site=np.int64(site)
    )
    return [list(flat[a:b]) for a, b in outputs]


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
        with ffi._FFI_CALLBACK_LOCK, warp_callback_gc.held():
            if is_gpu:
                _run_on_streams(site, frame, inputs, outputs)
            else:
                _run_in_order(site, inputs, outputs)
    except Exception as error:  # noqa: BLE001 - reported to XLA, which raises it in Python
        return xla_ffi.create_ffi_error(
            call_frame.contents.api,
            xla_ffi.XLA_FFI_Error_Code.UNKNOWN,
            f"mwjax.scene_streams: {type(error).__name__}: {device_memory.explained(error)}",
        )
    return None


_BUFFER_PTR = ctypes.POINTER(xla_ffi.XLA_FFI_Buffer)


def _buffers(base: int, start: int, stop: int) -> Any:
    """The FFI buffer pointers [start, stop) of the array at address `base`."""
    return (_BUFFER_PTR * (stop - start)).from_address(base + start * ctypes.sizeof(ctypes.c_void_p))


def _arguments(call: tuple[ffi.FfiCallable, int], inputs: Any, outputs: Any, device: wp.Device) -> list[Any]:
    callable_, call_id = call
    return callable_._build_arg_list(inputs, outputs, callable_.call_descriptors[call_id], device)


def _run_in_order(site: _Site, inputs: int, outputs: int) -> None:
    device = wp.get_device("cpu")
    for call, (i0, i1), (o0, o1) in zip(site.calls, site.inputs, site.outputs, strict=True):
        args = _arguments(call, _buffers(inputs, i0, i1), _buffers(outputs, o0, o1), device)
        with wp.ScopedDevice(device):
            call[0].func(*args)


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
    core = wp._src.context.runtime.core
    xla_stream = xla_ffi.get_stream_from_callframe(frame)
    ordinal = xla_ffi.get_device_ordinal_from_callframe(frame)
    device = wp.get_cuda_device(ordinal)
    if ordinal not in _streams:
        _streams[ordinal] = _Streams(device)
    own = _streams[ordinal]
    streams = own.get(len(site.calls))
    in_ptrs = _data_pointers(inputs, site.inputs[-1][1])
    out_ptrs = _data_pointers(outputs, site.outputs[-1][1])
    core.wp_cuda_event_record(own.start.cuda_event, xla_stream, False)
    for k, (call, (i0, i1), (o0, o1)) in enumerate(zip(site.calls, site.inputs, site.outputs, strict=True)):
        stream = streams[k]
        core.wp_cuda_stream_wait_event(stream.cuda_stream, own.start.cuda_event, False)
        ins, outs = in_ptrs[i0:i1], out_ptrs[o0:o1]
        if call[0].graph_mode in _STAGED_MODES:
            stage = site.stages[k].get(ordinal)
            if stage is None:
                args = _arguments(call, _buffers(inputs, i0, i1), _buffers(outputs, o0, o1), device)
                with wp.ScopedDevice(device), wp.ScopedStream(stream, sync_enter=False):
                    stage = site.stages[k][ordinal] = _staged(call[0], args, site.live)
            stage.copy_in.run(ins, device, stream)
            if stage.capture is None:  # the first call, or one whose capture failed
                stage.capture = _capture(call, stage.args, device, stream)
            else:
                _launch(stage.capture, stream)
            stage.copy_out.run(outs, device, stream)
        else:
            key = (ordinal, ins.tobytes(), outs.tobytes())
            graphs = site.graphs[k]
            capture = graphs.get(key)
            if capture is None:
                args = _arguments(call, _buffers(inputs, i0, i1), _buffers(outputs, o0, o1), device)
                graphs[key] = _capture(call, args, device, stream)
                if len(graphs) > _GRAPHS_PER_SCENE:
                    graphs.popitem(last=False)
            else:
                graphs.move_to_end(key)
                _launch(capture, stream)
        core.wp_cuda_event_record(own.done[k].cuda_event, stream.cuda_stream, False)
    for k in range(len(site.calls)):
        core.wp_cuda_stream_wait_event(xla_stream, own.done[k].cuda_event, False)


_STAGED_MODES = (ffi.JaxCallableGraphMode.WARP_STAGED, ffi.JaxCallableGraphMode.WARP_STAGED_EX)


def _capture(call: tuple[ffi.FfiCallable, int], args: list[Any], device: wp.Device, stream: wp.Stream) -> Any:
    """Captures the call with `args` into a CUDA graph on `stream`, launches it and returns it."""
    ffi._load_ffi_module(wp.get_module(call[0].func.__module__), device)
    with wp.ScopedDevice(device), wp.ScopedStream(stream, sync_enter=False):
        with wp.ScopedCapture(stream=stream) as capture:
            call[0].func(*args)
    wp.capture_launch(capture.graph, stream=stream)
    return capture


def _launch(capture: Any, stream: wp.Stream) -> None:
    if not wp._src.context.runtime.core.wp_cuda_graph_launch(capture.graph.graph_exec, stream.cuda_stream):
        raise RuntimeError(f"graph launch failed: {wp._src.context.runtime.get_error_string()}")
