"""How the env batch maps onto MJX-Warp physics calls: the one seam for that decision.

Today: one physics batch per scene. The env batch is laid out scene by scene (each scene's rows
contiguous), every scene is its own `mujoco.MjModel` put on device once, and one env step runs one
vmapped `mjx.step` chain per scene inside the same jitted call. Everything outside this module
sees only `Physics.groups` (which rows belong to which compiled scene), the step/kinematics
functions and the `PhysicsState` they carry, so another grouping (merged scenes with per-world
model fields, say) can replace this without touching tasks, rewards or the env.
"""

from __future__ import annotations

import dataclasses
import functools
import os
import warnings
from collections.abc import Callable, Sequence
from typing import Any, Literal

import jax
import jax.numpy as jnp
import mujoco
import numpy as np
import warp
from mujoco import mjx
from mujoco.mjx.third_party.mujoco_warp import GeomType, OverflowType

# Which geom-type pairs Warp collides without its convex collider; no public accessor.
from mujoco.mjx.third_party.mujoco_warp._src.collision_primitive import _PRIMITIVE_COLLISIONS

from mwjax import (
    caches,
    determinism,
    device_memory,
    host_call,
    progress,
    scene_streams,
    warp_ast,
    warp_call_ids,
    warp_callback_gc,
    warp_cpu_graphs,
    warp_empty_args,
    warp_equality,
    warp_graphs,
    warp_streams,
)
from mwjax.batching import cond_any, merge_rows
from mwjax.models import constraint_rows, load_scene

warp_streams.install()
warp_ast.install()
warp_cpu_graphs.install()
warp_graphs.install()
warp_equality.install()
warp_empty_args.install()
warp_call_ids.install()
warp_callback_gc.install()
progress.install()
caches.configure()

# The `Physics.overflow` flags of buffers whose excess Warp drops (convex-collider pairs,
# constraint rows, contacts); the other flags are limits reached (solver, EPA horizon).
DROPPED = OverflowType.CCD | OverflowType.NEFC | OverflowType.BROADPHASE | OverflowType.NARROWPHASE

# For each dropping buffer: what it holds, and the `PhysicsConfig` field that sizes it.
_BUFFERS = {
    OverflowType.NEFC: ("constraint rows", "constraints_per_env"),
    OverflowType.CCD: ("convex-collider pairs", "ccd_pairs_per_env"),
    OverflowType.BROADPHASE: ("contact candidates", "contacts_per_env"),
    OverflowType.NARROWPHASE: ("contacts", "contacts_per_env"),
}


class PhysicsOverflowWarning(RuntimeWarning):
    """Warp dropped contacts, constraint rows or collider pairs in some env: its physics left the
    reference's from that step on (`info["physics_overflow"]` says which envs and when)."""


class PhysicsInstabilityWarning(RuntimeWarning):
    """Some env's physics diverged (a NaN, or a value past MuJoCo's `mjMAXVAL`, in qpos, qvel or
    qacc) and was reset to the model's defaults, as MuJoCo C's automatic reset does
    (`info["physics_reset"]` says which envs and when)."""


_OVERFLOW_TARGET = "mwjax_physics_overflow"
_RESET_TARGET = "mwjax_physics_reset"
# (scene, buffer, size) already warned about: one warning each per process.
_warned: set[tuple[str, OverflowType, str]] = set()


def _warn_dropped(flags: np.ndarray, attrs: dict[str, str]) -> None:
    """`PhysicsOverflowWarning`s for a step's per-scene flags (`Physics._warn_on_host`)."""
    scenes = attrs["scenes"].split(",")
    # Under an outer vmap (e.g. over seeds) the flags arrive with leading batch axes.
    flags = np.bitwise_or.reduce(flags.reshape(-1, len(scenes)), axis=0)
    for g, (scene, bits) in enumerate(zip(scenes, flags, strict=True)):
        for flag, (what, setting) in _BUFFERS.items():
            size = attrs[setting].split(",")[g]
            if not bits & flag or (scene, flag, size) in _warned:
                continue
            _warned.add((scene, flag, size))
            # Raised on the host from inside a step: no user frame to point at, hence explicit.
            warnings.warn_explicit(
                f"Warp ran out of {what} in scene {scene} ({size} per env) and dropped the "
                f"excess: those envs no longer follow the reference's physics. Raise "
                f"mwjax.PhysicsConfig({setting}=...); info['physics_overflow'] flags the envs.",
                PhysicsOverflowWarning,
                filename="mwjax.physics",
                lineno=0,
            )


host_call.register(_OVERFLOW_TARGET, _warn_dropped)

_reset_warned: set[str] = set()


def _warn_reset(resets: np.ndarray, attrs: dict[str, str]) -> None:
    """`PhysicsInstabilityWarning`s for a step's per-scene reset counts, once per scene."""
    scenes = attrs["scenes"].split(",")
    resets = resets.reshape(-1, len(scenes)).sum(axis=0)
    for scene, count in zip(scenes, resets, strict=True):
        if not count or scene in _reset_warned:
            continue
        _reset_warned.add(scene)
        warnings.warn_explicit(
            f"The physics of {count} env(s) of scene {scene} diverged (NaN or |x| > 1e10 in qpos, "
            f"qvel or qacc) and was reset to the model's defaults mid-episode, as MuJoCo C does; "
            f"info['physics_reset'] flags the envs.",
            PhysicsInstabilityWarning,
            filename="mwjax.physics",
            lineno=0,
        )


host_call.register(_RESET_TARGET, _warn_reset)


@dataclasses.dataclass(frozen=True)
class PhysicsConfig:
    """Engine settings. The defaults are the reference's (from the scene XML): dt 0.0025 s,
    Newton, 50 iterations, tolerance 1e-10, elliptic cones, 5 substeps per env step."""

    substeps: int = 5
    iterations: int | None = None
    ls_iterations: int | None = None
    # Contact and constraint buffers. Warp preallocates them and drops what overflows (flagged
    # in `Physics.overflow`). Contacts are pooled over the batch; constraint rows are per env.
    # Warp assembles and solves over every allocated row, used or not, and every step refills
    # them (`PhysicsState`), so unused rows cost time: "per_scene" gives each scene twice the
    # rows MuJoCo C reaches in it (`mwjax.models.constraint_rows`, 128-448 instead of 512;
    # docs/performance.md).
    contacts_per_env: int = 64
    constraints_per_env: int | Literal["per_scene"] = "per_scene"
    # Slots of scratch for Warp's convex collider (GJK/EPA), pooled over a scene's batch for each
    # pair of geom types: Warp takes one for every geom pair of those types whose bounding boxes
    # overlap, and drops the pairs past the last slot (`Physics.overflow` says so). "per_scene"
    # gives each scene as many per env as it has candidate pairs of its busiest convex type pair
    # (`convex_candidates`), so that no env can run out whatever the others do; at most
    # `contacts_per_env`. Each slot is ~7.5 KB of Warp scratch per collision call.
    ccd_pairs_per_env: int | Literal["per_scene"] = "per_scene"
    # Who captures the CUDA graphs of a Warp step: None is MJX's choice ("warp" on GPU: Warp
    # captures each call and replays it for the same buffer addresses; under
    # `mwjax.determinism`, "none", so that Warp checks its record buffers), "jax" lets XLA record the
    # kernels into its own command buffers, "none" launches them one by one. A name of
    # `warp.JaxCallableGraphMode`, lower case. "warp" keeps a graph, with the scratch it allocated,
    # per call site and set of buffer addresses (up to 32 per Warp callable; `mwjax.warp_graphs`).
    # "warp_staged_ex" keeps one per call, captured against staging buffers (bounded memory, about
    # half the speed; docs/performance.md).
    graph_mode: str | None = None
    # "box_box": Warp's port of MuJoCo C's `mjc_BoxBox` (C's collider, see `warp_model`);
    # "convex": Warp's general convex collider (GJK/EPA), MJX-Warp's own default.
    box_box_collider: str = "box_box"
    # Whether an env step runs its scenes' Warp calls side by side, each scene's CUDA graph on its
    # own stream (`mwjax.scene_streams`; on the CPU the scenes in turn, bit for bit the same).
    # None: where it was measured faster (2.5-2.9x per env step on an H200) and checked against
    # the scenes in turn for MT10 and MT50 (docs/performance.md), that is on one GPU with Warp
    # capturing the graphs (`graph_mode` None or "warp", not under `mwjax.determinism`);
    # elsewhere one call per scene (`runs_scenes_together`). The cost: XLA compiles the step
    # longer (MT50's 1.9 times, with `scenes_per_call`; cached after the first run). True also
    # runs with the staged graph modes, each scene call captured once against staging buffers;
    # the Gymnasium adapter asks for that on one GPU unless told otherwise.
    concurrent_scenes: bool | None = None
    # With the scenes side by side, at most this many scenes' Warp calls in one combined call; a
    # round's calls, as few as that allows and of near-equal size, run one after another. XLA's
    # compile of one call grows faster than linearly with its aliased operands, while smaller
    # calls overlap fewer scenes. 10 keeps every set of up to 10 scenes (MT10's 8, ML10's 10) in
    # one call and gives MT50's 36 four calls of 9: its first step on a fresh H200 194 s instead
    # of 288 s, at the same steady-state rate (docs/performance.md). None: every scene in one
    # call. The physics is the same either way.
    scenes_per_call: int | None = 10

    def __post_init__(self) -> None:
        for name in ("substeps", "contacts_per_env", "iterations", "ls_iterations"):
            value = getattr(self, name)
            optional = name in ("iterations", "ls_iterations")
            if not (optional and value is None) and not (_is_int(value) and value >= 1):
                allowed = "a positive int" + (" or None" if optional else "")
                raise ValueError(f"{name} must be {allowed}, not {value!r}")
        rows = self.constraints_per_env
        if rows != "per_scene" and not (isinstance(rows, int) and rows >= 1):
            raise ValueError(f"constraints_per_env must be a positive int or 'per_scene', not {rows!r}")
        if self.box_box_collider not in ("box_box", "convex"):
            raise ValueError(f"box_box_collider must be 'box_box' or 'convex', not {self.box_box_collider!r}")
        pairs = self.ccd_pairs_per_env
        if pairs != "per_scene" and not (isinstance(pairs, int) and 1 <= pairs <= self.contacts_per_env):
            raise ValueError(
                f"ccd_pairs_per_env must be 'per_scene' or an int in [1, contacts_per_env="
                f"{self.contacts_per_env}], not {pairs!r}"
            )
        _graph_mode(self.graph_mode)
        if self.concurrent_scenes is not None and not isinstance(self.concurrent_scenes, bool):
            raise ValueError(f"concurrent_scenes must be True, False or None, not {self.concurrent_scenes!r}")
        per_call = self.scenes_per_call
        if per_call is not None and not (_is_int(per_call) and per_call >= 1):
            raise ValueError(f"scenes_per_call must be a positive int or None, not {per_call!r}")

    def physics_only(self) -> PhysicsConfig:
        """This config without the settings that only choose how the scenes' Warp calls are
        issued (side by side, how many per call, who captures their CUDA graphs): what kernel
        modules and settled states depend on, for their cache keys. A graph replays the kernels
        it captured, so the graph mode selects no module."""
        return dataclasses.replace(self, concurrent_scenes=None, scenes_per_call=None, graph_mode=None)


# Set to "0": `concurrent_scenes=None` resolves to off (`runs_scenes_together`).
CONCURRENT_SCENES_VARIABLE = "MWJAX_CONCURRENT_SCENES"


def runs_scenes_together(config: PhysicsConfig, platform: str, devices: int = 1) -> bool:
    """Whether an env step with `config`, on `devices` devices of `platform`, issues its scenes'
    Warp calls together (`PhysicsConfig.concurrent_scenes`; None resolved here). The default is
    on only where it was measured: one GPU, Warp capturing the graphs itself. Several GPUs are
    not measured yet; on the CPU the call would run the scenes in turn, as separate calls do.
    `MWJAX_CONCURRENT_SCENES=0` turns the default off everywhere (no code change needed to run a
    program's scenes in turn)."""
    if config.concurrent_scenes is not None:
        return config.concurrent_scenes
    if os.environ.get(CONCURRENT_SCENES_VARIABLE, "1") == "0":
        return False
    return scenes_together_by_default(config, platform, devices)


def scenes_together_by_default(config: PhysicsConfig, platform: str, devices: int = 1) -> bool:
    """What `concurrent_scenes=None` resolves to where no setting or variable chose: on one GPU
    whose CUDA graphs Warp captures itself."""
    return platform == "gpu" and devices == 1 and _warp_captures_graphs(config)


# Graph modes in which Warp captures the CUDA graphs itself: by buffer addresses, or once against
# staging buffers (the staged modes).
_OWN_GRAPH_MODES = (None, "warp")
_STAGED_GRAPH_MODES = ("warp_staged", "warp_staged_ex")


def _warp_captures_graphs(config: PhysicsConfig) -> bool:
    """Whether Warp captures the CUDA graphs itself on a GPU (its "warp" mode), as the scenes'
    streams do by default: not in the staged modes, without capture or under `mwjax.determinism`."""
    return config.graph_mode in _OWN_GRAPH_MODES and not determinism.enabled()


def _streams_capture(config: PhysicsConfig) -> bool:
    """Whether the scenes' streams can run in `config`'s graph mode: Warp's own ("warp"), or a
    staged mode, which `mwjax.scene_streams` stages per scene call as Warp does per call (the
    Gymnasium adapter's default on one GPU)."""
    return config.graph_mode in _OWN_GRAPH_MODES + _STAGED_GRAPH_MODES and not determinism.enabled()


def _is_int(value: object) -> bool:
    return isinstance(value, int) and not isinstance(value, bool)


@jax.tree_util.register_dataclass
@dataclasses.dataclass(frozen=True)
class PhysicsState:
    """What one scene batch carries from an env step to the next, rather than a whole `mjx.Data`.

    MJX-Warp's `mjx.Data` has ~185 arrays, and a state that carries one per scene makes every
    program that loops over it (a rollout's scan, autoreset's `cond`) pay in compile time for
    each array squared: XLA fingerprints a program it loads by printing it, and the print writes
    the whole carried tuple's shape at every element's use (docs/performance.md). The next step reads
    only MuJoCo's integration state (`mjSTATE_INTEGRATION`) and recomputes everything else, so the
    rest is rebuilt from `mjx.make_data` at each step. Batched: a leading axis of the scene's rows.
    """

    # mjSTATE_INTEGRATION: with the model, all that the next step reads.
    time: jax.Array
    qpos: jax.Array
    qvel: jax.Array
    act: jax.Array | None  # None where the scene has none (`_EMPTY_IN_METAWORLD`)
    history: jax.Array | None
    qacc_warmstart: jax.Array
    plugin_state: jax.Array | None
    ctrl: jax.Array
    qfrc_applied: jax.Array
    xfrc_applied: jax.Array
    eq_active: jax.Array
    mocap_pos: jax.Array
    mocap_quat: jax.Array
    userdata: jax.Array | None
    # The poses the tasks read (observations, rewards), as the last step or kinematics left them.
    xpos: jax.Array
    xquat: jax.Array
    site_xpos: jax.Array
    site_xmat: jax.Array
    geom_xpos: jax.Array
    geom_xmat: jax.Array
    # Read by Warp's next step before it recomputes them (at float rounding, ~1e-11 in qpos):
    # carried so that the batch steps bit for bit as a chain of whole `mjx.Data` does.
    cvel: jax.Array
    cdof_dot: jax.Array
    # Warp's `OverflowType` flags raised in the last `Physics.step` (`Physics.overflow`).
    overflow: jax.Array
    # Constraint rows the last step needed (the most over its substeps), allocated or not: what
    # sizing `PhysicsConfig.constraints_per_env` needs (`Physics.constraint_rows_needed`).
    rows_needed: jax.Array
    # Per env: whether the last step found its physics diverged and reset it (`Physics.step`).
    reset: jax.Array

    def replace(self, **changes: jax.Array) -> PhysicsState:
        return dataclasses.replace(self, **changes)


_FIELDS = tuple(
    f.name for f in dataclasses.fields(PhysicsState) if f.name not in ("overflow", "rows_needed", "reset")
)
# What a staged scene call copies in and out at every call (`scene_streams.concurrently`), rather
# than all of `mjx.Data` (~46 KB per env, ~5 KB of it these): the state the next call reads, the
# overflow flags (cleared before each step) and what `_step_rows` reads of a call's result (`qacc`
# for the divergence check, `nefc` for the rows needed). Warp's step recomputes the rest before
# reading it (`tests/test_env.py::test_carried_state_steps_as_whole_data*`), so what a staging
# buffer keeps from the last call serves as well as a copy.
_LIVE = frozenset(_FIELDS) | {"overflow", "qacc", "nefc"}
# Fields no Meta-World scene has entries in (no activations, delays, plugins or user data): a
# state carries None for them rather than zero-size arrays (`mwjax.warp_empty_args` says why);
# the data rebuilt from `mjx.make_data` at each step has them anyway.
_EMPTY_IN_METAWORLD = ("act", "history", "plugin_state", "userdata")


@dataclasses.dataclass(frozen=True)
class SceneGroup:
    """One physics batch: rows [start, start + size) of the env batch share `model`."""

    scene: str
    mocap_bodies: tuple[str, ...]
    start: int
    size: int
    model: mujoco.MjModel
    device_model: mjx.Model


class Physics:
    """One MJX-Warp batch per scene; the batch's state is a tuple with one `PhysicsState` per group."""

    def __init__(self, scenes: Sequence[tuple[str, tuple[str, ...], int]], config: PhysicsConfig) -> None:
        platform = local_device().platform
        if platform != "gpu" and config.graph_mode not in (None, *_CPU_GRAPH_MODES):
            # Warp would accept it here and fail at the first step, inside XLA.
            raise ValueError(
                f"graph_mode={config.graph_mode!r} captures CUDA graphs and needs a GPU; on the CPU "
                f"Warp runs {' or '.join(map(repr, _CPU_GRAPH_MODES))} (or None, MJX's choice)"
            )
        if config.concurrent_scenes and platform == "gpu" and not _streams_capture(config):
            raise ValueError(
                "concurrent_scenes=True captures each scene's CUDA graphs itself, as graph_mode 'warp' "
                "or a staged mode does; it cannot run with "
                f"graph_mode={config.graph_mode!r} or under mwjax.determinism"
            )
        self.config = config
        self.concurrent_scenes = runs_scenes_together(config, platform)
        device_memory.check_pool(local_device())
        from mwjax import kernels  # here: `mwjax.kernels` builds on this module

        kernels.prebuild(list(dict.fromkeys((scene, bodies) for scene, bodies, _ in scenes)), config)
        groups = []
        start = 0
        for scene, mocap_bodies, size in scenes:
            groups.append(
                SceneGroup(
                    scene=scene,
                    mocap_bodies=mocap_bodies,
                    start=start,
                    size=size,
                    model=_configured(load_scene(scene, mocap_bodies), config),
                    device_model=_without_console_warnings(
                        mjx.put_model(
                            warp_model(scene, mocap_bodies, config),
                            device=local_device(),
                            impl="warp",
                            graph_mode=_graph_mode(config.graph_mode),
                        )
                    ),
                )
            )
            start += size
        self.groups: tuple[SceneGroup, ...] = tuple(groups)
        # The model is closed over, not a vmap argument: as an argument, every call hashes all
        # of its NumPy fields (meshes included) while tracing.
        self._substep = tuple(jax.vmap(functools.partial(_step, g.device_model)) for g in groups)
        self._kinematics = tuple(jax.vmap(functools.partial(_kinematics, g.device_model)) for g in groups)
        self._defaults = tuple(_reset_values(g.model) for g in groups)
        # Every step rebuilds each scene's whole data from `mjx.make_data`; traced afresh at each
        # of MT50's ~100 call sites it dominated the step's lowering. Jitted, it is traced once
        # per scene (it makes no Warp call, so sharing its trace shares no captured graph).
        self._made: dict[tuple[int, int], Callable[[], mjx.Data]] = {}

    def make_data(self) -> tuple[PhysicsState, ...]:
        """Fresh batched states (the scene's qpos0, poses not yet computed), one per group."""
        return tuple(self.fresh(g, group.size) for g, group in enumerate(self.groups))

    def fresh(self, g: int, rows: int) -> PhysicsState:
        """A fresh state of `rows` envs of group `g`'s scene (any batch size: e.g. one row per
        goal variant), with buffers sized for that batch."""
        return _carried(self._maker(g, rows)())

    def data(self, g: int, state: PhysicsState) -> mjx.Data:
        """Group `g`'s full `mjx.Data` for `state`: what the next step reads, the rest as
        `mjx.make_data` leaves it until a step or kinematics computes it."""
        carried = {name: getattr(state, name) for name in _FIELDS}
        data = self._maker(g, state.qpos.shape[0])().replace(
            **{name: value for name, value in carried.items() if value is not None}
        )
        return data.replace(_impl=data._impl.replace(overflow=state.overflow))

    def _maker(self, g: int, rows: int) -> Callable[[], mjx.Data]:
        if (g, rows) not in self._made:
            self._made[g, rows] = jax.jit(functools.partial(self._make_data, g, rows))
        return self._made[g, rows]

    def _make_data(self, g: int, rows: int) -> mjx.Data:
        group = self.groups[g]
        determinism.reserve_cone_hessian(rows * self.config.contacts_per_env, group.model.nv)
        make = functools.partial(
            mjx.make_data,
            group.model,
            device=local_device(),
            impl="warp",
            naconmax=rows * self.config.contacts_per_env,
            naccdmax=rows * self.ccd_pairs(group.scene),
            njmax=self.constraint_rows(group.scene),
        )
        return jax.vmap(lambda _: make())(jnp.arange(rows))

    def constraint_rows(self, scene: str) -> int:
        """Constraint rows allocated per env of `scene`."""
        if self.config.constraints_per_env == "per_scene":
            return constraint_rows(scene)
        return self.config.constraints_per_env

    def ccd_pairs(self, scene: str) -> int:
        """Convex-collider slots allocated per env of `scene`, at most `contacts_per_env`."""
        pairs = self.config.ccd_pairs_per_env
        if pairs == "per_scene":
            group = next(g for g in self.groups if g.scene == scene)
            candidates = convex_candidates(group.device_model, self.config.box_box_collider)
            return max(1, min(candidates, self.config.contacts_per_env))
        return pairs

    def step(self, states: tuple[PhysicsState, ...]) -> tuple[PhysicsState, ...]:
        """`substeps` physics steps, then kinematics so positions describe the new state. The
        overflow flags of the result are those this step raised; a buffer that dropped something
        in a scene for the first time raises a `PhysicsOverflowWarning` on the host."""
        cleared = tuple(state.replace(overflow=jnp.zeros_like(state.overflow)) for state in states)
        if self.concurrent_scenes:
            stepped = merge_rows(self._step_all)(cleared)
        else:
            stepped = tuple(self.step_group(g, state) for g, state in enumerate(cleared))
        self._warn_on_host(stepped)
        return stepped

    def step_group(self, g: int, state: PhysicsState, fresh_poses: bool = True) -> PhysicsState:
        """`step` for group `g` alone (a batch of any size). `fresh_poses=False` leaves the poses
        as MuJoCo C's `mj_step` does, computed before the last substep's integration. Under an
        outer `jax.vmap`, one Warp batch of every instance's rows (`merge_rows` says why)."""
        step = functools.partial(self._step_rows, (g,), fresh_poses=fresh_poses, issue=_in_turn)
        return merge_rows(lambda s: step((s,))[0])(state)

    def _step_all(self, states: tuple[PhysicsState, ...]) -> tuple[PhysicsState, ...]:
        """Every group stepped with fresh poses, the groups' Warp calls issued together."""
        issue = functools.partial(
            scene_streams.concurrently, per_call=self.config.scenes_per_call, live=_LIVE
        )
        return self._step_rows(tuple(range(len(states))), states, True, issue)

    def _step_rows(
        self,
        groups: tuple[int, ...],
        states: tuple[PhysicsState, ...],
        fresh_poses: bool,
        issue: Callable[[list[Callable[[mjx.Data], mjx.Data]], list[mjx.Data]], list[mjx.Data]],
    ) -> tuple[PhysicsState, ...]:
        """`groups` stepped, one state each; `issue(fns, datas)` applies one function to each
        group's data (in turn, or with their Warp calls together: `mwjax.scene_streams`)."""

        # A device loop rather than five traced calls: the loop body hands Warp the same buffers
        # at every substep, and Warp captures a graph (with its scratch) per call site and set of
        # buffer addresses, so a site needs one graph instead of one per substep; XLA also
        # compiles one body instead of five (docs/performance.md).
        def substep(_: int, carry: tuple[tuple[mjx.Data, ...], tuple[jax.Array, ...]]) -> Any:
            datas, rows = carry
            datas = tuple(issue([self._substep[g] for g in groups], list(datas)))
            return datas, tuple(jnp.maximum(r, d._impl.nefc) for r, d in zip(rows, datas, strict=True))

        # MuJoCo C checks qpos and qvel before each step and qacc after its forward pass, and
        # resets a diverged state to the model's defaults (`mj_checkPos/Vel/Acc`, its automatic
        # reset); MJX-Warp checks nothing, and a NaN would spread through a learner's statistics.
        # Here the state is checked before the env step's substeps (as C: it steps on from the
        # reset) and after them: a divergence inside the env step resets at its end, not at the
        # substep where it happened (C then integrates the remaining substeps from the reset),
        # and never shows as a NaN (C's next `mj_step` would find it). Selects, not a `lax.cond`
        # per substep: a conditional costs the GPU a host round trip.
        datas, bad_inputs = [], []
        for g, state in zip(groups, states, strict=True):
            data = self.data(g, state)
            bad_inputs.append(_diverged(data.qpos, data.qvel))
            datas.append(_reset_rows(self._defaults[g], data, bad_inputs[-1]))
        rows = tuple(jnp.zeros_like(state.rows_needed) for state in states)
        datas, rows = jax.lax.fori_loop(0, self.config.substeps, substep, (tuple(datas), rows))
        reset, diverged = [], []
        for g, data, bad_input in zip(groups, datas, bad_inputs, strict=True):
            bad = _diverged(data.qpos, data.qvel, data.qacc)
            reset.append(_reset_rows(self._defaults[g], data, bad))
            diverged.append(bad_input | bad)
        if fresh_poses:
            reset = issue([self._kinematics[g] for g in groups], reset)
        return tuple(_carried(*parts) for parts in zip(reset, rows, diverged, strict=True))

    def constraint_rows_needed(self, states: tuple[PhysicsState, ...]) -> jax.Array:
        """Per env (rows in batch order), the constraint rows the last `step` needed at its peak,
        whether or not `PhysicsConfig.constraints_per_env` allocated that many."""
        return jnp.concatenate([state.rows_needed for state in states])

    def _warn_on_host(self, states: tuple[PhysicsState, ...]) -> None:
        # Warp's own overflow warning is a `printf` per world and substep from inside its kernels
        # (turned off in `_without_console_warnings`); these are calls to the host, made only in
        # a step where some env dropped something or was reset (one conditional for both: each
        # costs the GPU a host round trip), through named FFI targets so that the step stays in
        # JAX's persistent cache (`mwjax.host_call`).
        flags = jnp.stack([jax.lax.reduce(s.overflow, np.int32(0), jax.lax.bitwise_or, (0,)) for s in states])
        resets = jnp.stack([s.reset.sum(dtype=jnp.int32) for s in states])
        sizes = self._buffer_sizes

        def warn(fr: tuple[jax.Array, jax.Array], _: jax.Array) -> tuple[jax.Array, jax.Array]:
            host_call.call(_OVERFLOW_TARGET, fr[0], **sizes)
            host_call.call(_RESET_TARGET, fr[1], scenes=sizes["scenes"])
            return fr

        cond_any(((flags & int(DROPPED)) != 0) | (resets > 0), warn, lambda fr, _: fr, (flags, resets))

    def resets(self, states: tuple[PhysicsState, ...]) -> jax.Array:
        """Per env (rows in batch order), whether the last `step` found its physics diverged and
        reset it to the model's defaults, as MuJoCo C does (`PhysicsInstabilityWarning`)."""
        return jnp.concatenate([state.reset for state in states])

    @functools.cached_property
    def _buffer_sizes(self) -> dict[str, str]:
        """The scenes and their buffer sizes, comma-separated, as `_warn_dropped` reads them."""
        return {
            "scenes": ",".join(g.scene for g in self.groups),
            "constraints_per_env": ",".join(str(self.constraint_rows(g.scene)) for g in self.groups),
            "ccd_pairs_per_env": ",".join(str(self.ccd_pairs(g.scene)) for g in self.groups),
            "contacts_per_env": ",".join(str(self.config.contacts_per_env) for _ in self.groups),
        }

    def overflow(self, states: tuple[PhysicsState, ...]) -> jax.Array:
        """Per env (rows in batch order), the `OverflowType` flags Warp raised in the last `step`
        (or, for stepping by `step_group` alone, since the data was made): buffers that overflowed
        (`DROPPED`: Warp drops what does not fit, so that env's physics left the reference's) and
        limits reached (solver iterations, EPA horizon)."""
        return jnp.concatenate([state.overflow for state in states])

    def kinematics(self, states: tuple[PhysicsState, ...]) -> tuple[PhysicsState, ...]:
        """The poses of `states` computed from their qpos (and mocap bodies), one group after
        another: the scenes side by side (`concurrent_scenes`) are checked on a GPU in the step
        (whose last part is this) but not here."""

        def posed(states: tuple[PhysicsState, ...]) -> tuple[PhysicsState, ...]:
            datas = _in_turn(list(self._kinematics), [self.data(g, state) for g, state in enumerate(states)])
            return tuple(_carried(d, s.rows_needed, s.reset) for d, s in zip(datas, states, strict=True))

        return merge_rows(posed)(states)


def warp_model(scene: str, mocap_bodies: tuple[str, ...], config: PhysicsConfig) -> mujoco.MjModel:
    """The scene as MJX-Warp runs it: without its visual meshes (`load_scene`), and with box pairs
    sent to MuJoCo C's collider. MuJoCo C collides two boxes with `mjc_BoxBox` (a full contact
    manifold). MJX-Warp sends box pairs to its general convex collider unless native CCD is
    disabled, a flag that in Warp only selects its port of `mjc_BoxBox`; the convex path finds
    fewer contacts (6 instead of C's 10 on a hand-insert grasp), and grasps held by box pads then
    slip. The host model (`SceneGroup.model`) stays MuJoCo C's, for anything that steps it there."""
    model = _configured(load_scene(scene, mocap_bodies, visual_meshes=False), config)
    if config.box_box_collider == "box_box":
        model.opt.disableflags |= mujoco.mjtDisableBit.mjDSBL_NATIVECCD
    return model


def convex_candidates(device_model: mjx.Model, box_box_collider: str) -> int:
    """The most geom pairs of one pair of geom types that Warp can send to its convex collider in
    one env of the model: its candidate pairs (after contype/conaffinity, parent and exclude
    filtering) of each type pair that no primitive collider takes, counted by Warp itself
    (`geom_pair_type_count`, indexed like Warp's upper-triangular type-pair table)."""
    primitive = set(_PRIMITIVE_COLLISIONS)
    if box_box_collider == "convex":
        primitive.discard((GeomType.BOX, GeomType.BOX))
    counts = device_model._impl.geom_pair_type_count
    n = len(GeomType)
    convex = [t for t in GeomType if t.value < n and t not in (GeomType.PLANE, GeomType.HFIELD, GeomType.SDF)]
    return max(
        (
            int(counts[i * (2 * n - i - 1) // 2 + j])
            for a in convex
            for b in convex
            if (i := a.value) <= (j := b.value) and (a, b) not in primitive
        ),
        default=0,
    )


def _in_turn(fns: list[Callable[[mjx.Data], mjx.Data]], datas: list[mjx.Data]) -> list[mjx.Data]:
    return [fn(data) for fn, data in zip(fns, datas, strict=True)]


def _step(model: mjx.Model, data: mjx.Data) -> mjx.Data:
    return mjx.step(warp_empty_args.traced(model), data)


def _kinematics(model: mjx.Model, data: mjx.Data) -> mjx.Data:
    return mjx.kinematics(warp_empty_args.traced(model), data)


def _diverged(*arrays: jax.Array) -> jax.Array:
    """Per row, whether any entry is NaN or beyond MuJoCo's `mjMAXVAL` (C's `mju_isBad`)."""
    return jnp.any(jnp.stack([jnp.any(~(jnp.abs(a) <= mujoco.mjMAXVAL), axis=-1) for a in arrays]), axis=0)


def _reset_values(model: mujoco.MjModel) -> dict[str, np.ndarray]:
    """What `mj_resetData` sets that the next step reads: qpos0, eq_active0 and the hand's mocap
    pose (mocap 0) from its body. mwjax's other mocap bodies are the reference's fixed bodies
    that a reset moves by editing `model.body_pos`, which C's reset keeps: they stay put."""
    hand = int(np.flatnonzero(model.body_mocapid == 0)[0])
    return {
        "qpos": model.qpos0.astype(np.float32),
        "eq_active": model.eq_active0.astype(bool),
        "hand_pos": model.body_pos[hand].astype(np.float32),
        "hand_quat": model.body_quat[hand].astype(np.float32),
    }


def _reset_rows(defaults: dict[str, np.ndarray], data: mjx.Data, rows: jax.Array) -> mjx.Data:
    """`data` with the marked rows as `mj_resetData` leaves them (zero velocities, controls,
    applied forces, warm start and time)."""

    def where(value: jax.Array | np.ndarray, x: jax.Array) -> jax.Array:
        return jnp.where(rows.reshape(-1, *[1] * (x.ndim - 1)), jnp.asarray(value, x.dtype), x)

    zeroed = ("time", "qvel", "qacc_warmstart", "ctrl", "qfrc_applied", "xfrc_applied", "cvel", "cdof_dot")
    changes = {name: where(0, getattr(data, name)) for name in zeroed}
    changes["qpos"] = where(defaults["qpos"], data.qpos)
    changes["eq_active"] = where(defaults["eq_active"], data.eq_active)
    changes["mocap_pos"] = data.mocap_pos.at[:, 0].set(where(defaults["hand_pos"], data.mocap_pos[:, 0]))
    changes["mocap_quat"] = data.mocap_quat.at[:, 0].set(where(defaults["hand_quat"], data.mocap_quat[:, 0]))
    return data.replace(**changes)


def _carried(
    data: mjx.Data, rows_needed: jax.Array | None = None, reset: jax.Array | None = None
) -> PhysicsState:
    # MJX has no public accessor for Warp's overflow flags and row counts, hence the private field.
    fields = {name: getattr(data, name) for name in _FIELDS}
    for name in _EMPTY_IN_METAWORLD:
        if fields[name].size == 0:
            fields[name] = None
    return PhysicsState(
        **fields,
        overflow=data._impl.overflow,
        rows_needed=data._impl.nefc if rows_needed is None else rows_needed,
        reset=jnp.zeros(data.qpos.shape[0], bool) if reset is None else reset,
    )


def _without_console_warnings(model: mjx.Model) -> mjx.Model:
    """The model with Warp's in-kernel overflow printing off (`Physics.step` warns once instead).
    Warp still raises the flags; the setting only selects a kernel variant without `printf`."""
    opt = model.opt
    return model.replace(opt=opt.replace(_impl=opt._impl.replace(warn_overflow=0)))


def local_device() -> jax.Device:
    """Where this process's physics lives: its first local device, a GPU if it has one. MJX's
    own default, the first device of the platform, belongs to another process when one process
    drives each GPU (`mwjax.distributed`)."""
    gpus = [d for d in jax.local_devices() if d.platform == "gpu"]
    return gpus[0] if gpus else jax.local_devices(backend="cpu")[0]


# The graph modes Warp's CPU FFI calls run in (warp/_src/jax/ffi.py refuses the others there).
_CPU_GRAPH_MODES = ("none", "jax")


def _graph_mode(name: str | None) -> warp.JaxCallableGraphMode | None:
    if name is None:
        # Warp checks a deterministic kernel's record buffers only when it launches it outside
        # graph capture: captured, the records beyond the buffer are dropped silently (a wrong
        # sum, not a reordered one); launched one by one, the step raises.
        return warp.JaxCallableGraphMode.NONE if determinism.enabled() else None
    modes = {mode.name.lower(): mode for mode in warp.JaxCallableGraphMode}
    if name not in modes:
        raise ValueError(f"unknown graph_mode {name!r}; known: {', '.join(modes)}")
    return modes[name]


def _configured(model: mujoco.MjModel, config: PhysicsConfig) -> mujoco.MjModel:
    if config.iterations is None and config.ls_iterations is None:
        return model
    if config.iterations is not None:
        model.opt.iterations = config.iterations
    if config.ls_iterations is not None:
        model.opt.ls_iterations = config.ls_iterations
    return model
