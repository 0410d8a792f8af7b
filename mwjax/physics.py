"""How the env batch maps onto MJX-Warp physics calls: the one seam for that decision.

Today: one physics batch per scene. The env batch is laid out scene by scene (each scene's rows
contiguous), every scene is its own `mujoco.MjModel` put on device once, and one env step runs one
vmapped `mjx.step` chain per scene inside the same jitted call. Everything outside this module
sees only `Physics.groups` (which rows belong to which compiled scene) and the step/kinematics
functions, so another grouping (merged scenes with per-world model fields, say) can replace this
without touching tasks, rewards or the env.
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

from mwjax.models import ccd_pairs, constraint_rows, load_scene

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
    # Contact and constraint buffers. Warp preallocates them and drops what overflows. Contacts
    # are pooled over the batch; constraint rows are per env. Warp's cost grows with the rows
    # allocated (benchmarks/results/throughput-buffers-9a338f8-…md): "per_scene" sizes them from
    # what MuJoCo C reaches in each scene (`mwjax.models.constraint_rows`). Not the default yet:
    # its one MT50 run on the GPU failed in Warp's graph capture (README, Performance).
    contacts_per_env: int = 64
    constraints_per_env: int | Literal["per_scene"] = 512
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
    # with 64 CCD slots per env this ran out of GPU memory inside Warp (README, Compile).
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
    """One MJX-Warp batch per scene; batched data is a tuple with one `mjx.Data` per group."""

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

    def make_data(self) -> tuple[mjx.Data, ...]:
        """Fresh batched data (the scene's qpos0), one per group."""
        datas = []
        for group in self.groups:
            make = functools.partial(
                mjx.make_data,
                group.model,
                impl="warp",
                naconmax=group.size * self.config.contacts_per_env,
                naccdmax=group.size * self.ccd_pairs(group.scene),
                njmax=self.constraint_rows(group.scene),
            )
            datas.append(jax.vmap(lambda _, make=make: make())(jnp.arange(group.size)))
        return tuple(datas)

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

    def step(self, datas: tuple[mjx.Data, ...]) -> tuple[mjx.Data, ...]:
        """`substeps` physics steps, then kinematics so positions describe the new state."""
        return tuple(self.step_group(g, data) for g, data in enumerate(datas))

    def step_group(self, g: int, data: mjx.Data) -> mjx.Data:
        """`step` for group `g` alone."""
        step = self._substep[g]
        # Unrolled by default. The loop (`unroll_substeps=False`) halves MT50's warm compile on
        # the CPU but not on the H200: 74 s there, and 1.04-1.05M env steps/s against 1.08-1.11M
        # unrolled (README, Compile).
        if self.config.unroll_substeps:
            for _ in range(self.config.substeps):
                data = step(data)
        else:
            data = jax.lax.fori_loop(0, self.config.substeps, lambda _, d: step(d), data)
        return self._kinematics[g](data)

    def overflow(self, datas: tuple[mjx.Data, ...]) -> jax.Array:
        """Per env (rows in batch order), the `OverflowType` flags Warp raised since its data was
        made: buffers that overflowed (`DROPPED`: Warp drops what does not fit, so that env's
        physics left the reference's) and limits reached (solver iterations, EPA horizon). MJX
        has no public accessor for them, hence the private field."""
        return jnp.concatenate([data._impl.overflow for data in datas])

    def kinematics(self, datas: tuple[mjx.Data, ...]) -> tuple[mjx.Data, ...]:
        return tuple(kinematics(data) for kinematics, data in zip(self._kinematics, datas, strict=True))


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
