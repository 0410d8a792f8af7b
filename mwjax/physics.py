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
from collections.abc import Callable, Sequence
from typing import Literal

import jax
import jax.numpy as jnp
import mujoco
import warp
from mujoco import mjx
from mujoco.mjx.third_party.mujoco_warp import OverflowType

from mwjax import caches, progress, warp_equality, warp_streams
from mwjax.models import ccd_pairs, constraint_rows, load_scene

warp_streams.install()
warp_equality.install()
progress.install()
caches.configure()

# The `Physics.overflow` flags of buffers whose excess Warp drops (convex-collider pairs,
# constraint rows, contacts); the other flags are limits reached (solver, EPA horizon).
DROPPED = OverflowType.CCD | OverflowType.NEFC | OverflowType.BROADPHASE | OverflowType.NARROWPHASE


@dataclasses.dataclass(frozen=True)
class PhysicsConfig:
    """Engine settings. The defaults are the reference's (from the scene XML): dt 0.0025 s,
    Newton, 50 iterations, tolerance 1e-10, elliptic cones, 5 substeps per env step."""

    substeps: int = 5
    iterations: int | None = None
    ls_iterations: int | None = None
    # Contact and constraint buffers. Warp preallocates them and drops what overflows (flagged
    # in `Physics.overflow`). Contacts are pooled over the batch; constraint rows are per env.
    # Warp's cost grows with the rows allocated (benchmarks/results/throughput-buffers-9a338f8-…
    # md) and every step refills them (`PhysicsState`): "per_scene" gives each scene twice the
    # rows MuJoCo C reaches in it (`mwjax.models.constraint_rows`, 128-448 instead of 512).
    contacts_per_env: int = 64
    constraints_per_env: int | Literal["per_scene"] = "per_scene"
    # Slots of scratch for Warp's convex collider (GJK/EPA), pooled over a scene's batch for each
    # pair of geom types: one per geom pair that it finds in contact (`naccdmax`); a pair past
    # the last slot is dropped (`Physics.overflow` says so). Warp allocates ~7.5 KB per slot in
    # every collision call, outside JAX's memory. MJX's default is one slot per contact (64 per
    # env, ~480 KB per env); "per_scene" gives each scene twice the most such pairs MuJoCo C had
    # in contact at once (`mwjax.models.ccd_pairs`): 4 to 32.
    ccd_pairs_per_env: int | Literal["per_scene"] = "per_scene"
    # Who captures the CUDA graphs of a Warp step: None is MJX's choice ("warp" on GPU: Warp
    # captures each call and replays it for the same buffer addresses), "jax" lets XLA record the
    # kernels into its own command buffers, "none" launches them one by one. A name of
    # `warp.JaxCallableGraphMode`, lower case.
    graph_mode: str | None = None
    # "box_box": Warp's port of MuJoCo C's `mjc_BoxBox` (C's collider, see `warp_model`);
    # "convex": Warp's general convex collider (GJK/EPA), MJX-Warp's own default.
    box_box_collider: str = "box_box"
    # False runs each scene's substeps as a device loop, so the step program holds one traced
    # physics call per scene instead of `substeps`: a shorter lowering and a faster compile on
    # the CPU, none on the GPU.
    unroll_substeps: bool = True
    # True traces each scene's `mjx.step` and `mjx.kinematics` once (a jitted function per scene,
    # called at every site: substeps, the autoreset branch, resets that step), so the step
    # program is traced and lowered with 72 physics calls for MT50 instead of 264. The calls
    # then share Warp call ids, and Warp keys its captured CUDA graphs by call id and buffers:
    # with 64 CCD slots per env this ran out of GPU memory inside Warp. With the per-scene slots
    # it ran, lowering in half the time, but the step's compile is the cache read's (README).
    share_traces: bool = False

    def __post_init__(self) -> None:
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

    @classmethod
    def fast(cls) -> PhysicsConfig:
        """Opt-in speed preset (not the reference's physics): fewer solver iterations."""
        return cls(iterations=10, ls_iterations=10)


@jax.tree_util.register_dataclass
@dataclasses.dataclass(frozen=True)
class PhysicsState:
    """What one scene batch carries from an env step to the next, rather than a whole `mjx.Data`.

    MJX-Warp's `mjx.Data` has ~185 arrays, and a state that carries one per scene makes every
    program that loops over it (a rollout's scan, autoreset's `cond`) pay in compile time for
    each array squared: loading MT50's step from JAX's cache spent ~45 of its ~52 s printing the
    loop's tuple shape once per element, to fingerprint it (README, Compile). The next step reads
    only MuJoCo's integration state (`mjSTATE_INTEGRATION`) and recomputes everything else, so the
    rest is rebuilt from `mjx.make_data` at each step. Batched: a leading axis of the scene's rows.
    """

    # mjSTATE_INTEGRATION: with the model, all that the next step reads.
    time: jax.Array
    qpos: jax.Array
    qvel: jax.Array
    act: jax.Array
    history: jax.Array
    qacc_warmstart: jax.Array
    plugin_state: jax.Array
    ctrl: jax.Array
    qfrc_applied: jax.Array
    xfrc_applied: jax.Array
    eq_active: jax.Array
    mocap_pos: jax.Array
    mocap_quat: jax.Array
    userdata: jax.Array
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

    def replace(self, **changes: jax.Array) -> PhysicsState:
        return dataclasses.replace(self, **changes)


_FIELDS = tuple(f.name for f in dataclasses.fields(PhysicsState) if f.name != "overflow")


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
        self.config = config
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
                    device_model=mjx.put_model(
                        warp_model(scene, mocap_bodies, config),
                        impl="warp",
                        graph_mode=_graph_mode(config.graph_mode),
                    ),
                )
            )
            start += size
        self.groups: tuple[SceneGroup, ...] = tuple(groups)
        # The model is closed over, not a vmap argument: as an argument, every call hashes all
        # of its NumPy fields (meshes included) while tracing.
        share = jax.jit if config.share_traces else _as_is
        self._substep = tuple(share(jax.vmap(functools.partial(mjx.step, g.device_model))) for g in groups)
        self._kinematics = tuple(
            share(jax.vmap(functools.partial(mjx.kinematics, g.device_model))) for g in groups
        )
        # Every step rebuilds each scene's whole data from `mjx.make_data`; traced afresh at each
        # of MT50's ~100 sites that took 40 s of the step's lowering on the H200. Jitted, it is
        # traced once per scene. (It makes no Warp call, so none of `share_traces`' concerns.)
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
        data = self._maker(g, state.qpos.shape[0])().replace(
            **{name: getattr(state, name) for name in _FIELDS}
        )
        return data.replace(_impl=data._impl.replace(overflow=state.overflow))

    def _maker(self, g: int, rows: int) -> Callable[[], mjx.Data]:
        if (g, rows) not in self._made:
            self._made[g, rows] = jax.jit(functools.partial(self._make_data, g, rows))
        return self._made[g, rows]

    def _make_data(self, g: int, rows: int) -> mjx.Data:
        group = self.groups[g]
        make = functools.partial(
            mjx.make_data,
            group.model,
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
            return min(ccd_pairs(scene), self.config.contacts_per_env)
        return pairs

    def step(self, states: tuple[PhysicsState, ...]) -> tuple[PhysicsState, ...]:
        """`substeps` physics steps, then kinematics so positions describe the new state. The
        overflow flags of the result are those this step raised."""
        return tuple(
            self.step_group(g, state.replace(overflow=jnp.zeros_like(state.overflow)))
            for g, state in enumerate(states)
        )

    def step_group(self, g: int, state: PhysicsState, fresh_poses: bool = True) -> PhysicsState:
        """`step` for group `g` alone (a batch of any size). `fresh_poses=False` leaves the poses
        as MuJoCo C's `mj_step` does, computed before the last substep's integration."""
        step = self._substep[g]
        data = self.data(g, state)
        # Unrolled by default. The loop (`unroll_substeps=False`) halves MT50's warm compile on
        # the CPU but not on the H200: 74 s there, and 1.04-1.05M env steps/s against 1.08-1.11M
        # unrolled (README, Compile).
        if self.config.unroll_substeps:
            for _ in range(self.config.substeps):
                data = step(data)
        else:
            data = jax.lax.fori_loop(0, self.config.substeps, lambda _, d: step(d), data)
        return _carried(self._kinematics[g](data) if fresh_poses else data)

    def overflow(self, states: tuple[PhysicsState, ...]) -> jax.Array:
        """Per env (rows in batch order), the `OverflowType` flags Warp raised in the last `step`
        (or, for stepping by `step_group` alone, since the data was made): buffers that overflowed
        (`DROPPED`: Warp drops what does not fit, so that env's physics left the reference's) and
        limits reached (solver iterations, EPA horizon)."""
        return jnp.concatenate([state.overflow for state in states])

    def kinematics(self, states: tuple[PhysicsState, ...]) -> tuple[PhysicsState, ...]:
        """The poses of `states` computed from their qpos (and mocap bodies)."""
        return tuple(_carried(self._kinematics[g](self.data(g, state))) for g, state in enumerate(states))


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


def _carried(data: mjx.Data) -> PhysicsState:
    # MJX has no public accessor for Warp's overflow flags, hence the private field.
    return PhysicsState(**{name: getattr(data, name) for name in _FIELDS}, overflow=data._impl.overflow)


def _as_is(fn: Callable) -> Callable:
    return fn


def _graph_mode(name: str | None) -> warp.JaxCallableGraphMode | None:
    if name is None:
        return None
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
