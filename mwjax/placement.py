"""Reset placement: where each task's rows sit in the batch, and how a reset writes a fresh
episode into them (objects and fixed bodies placed from the settled hand state, the fixtures'
reset steps, the settling of goal-dependent hand states).

The reference resets in two parts: `_reset_hand` settles the arm at `hand_init_pos` (50 env
steps), then `reset_model` places the objects. The settled state is recorded per task
(`mwjax/tasks/settled_states.npz`), or, for the few tasks whose settling touches a body the goal
moves (`TaskSpec.settle_per_goal`), computed here per goal variant.
"""

from __future__ import annotations

import dataclasses
import functools
from collections.abc import Mapping, Sequence
from importlib import resources
from typing import Any, NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from mwjax import stored_results
from mwjax.contracts import Frame, Kinematics, Placement
from mwjax.physics import Physics, PhysicsState
from mwjax.tasks.spec import TaskSpec

Array = jax.Array

# SawyerXYZEnv._reset_hand: 50 env steps of physics driving the hand to `hand_init_pos`.
_SETTLE_ENV_STEPS = 50


class Settled(NamedTuple):
    """The state a reset places objects into: the reference's data right after `_reset_hand`
    (poses as its last `mj_step` left them), one env or a batch."""

    kin: Kinematics
    qacc_warmstart: Array


@dataclasses.dataclass(frozen=True, eq=False)
class TaskRows:
    """One task's rows: where they sit in the env batch and in their scene's physics group, and
    the settled state its resets start from."""

    spec: TaskSpec
    group: int
    start: int  # first row in the env batch
    local_start: int  # first row in its physics group
    size: int
    # The recorded settled state (the same for every goal unless `spec.settle_per_goal`).
    settled: Settled
    # The hand's part of it, the same in every task: mocap_pos, mocap_quat, ctrl.
    settled_data: dict[str, np.ndarray]
    # With `spec.settle_per_goal`: the settled state of each of the env's goal variants.
    settled_per_variant: Settled | None = None

    @property
    def rows(self) -> slice:
        """The task's rows in the env batch."""
        return slice(self.start, self.start + self.size)

    @property
    def local_rows(self) -> slice:
        """The task's rows in its physics group."""
        return slice(self.local_start, self.local_start + self.size)


def scene_groups(specs: Sequence[TaskSpec]) -> list[list[TaskSpec]]:
    """The tasks grouped by scene, scenes in order of first appearance: one physics batch each."""
    scenes = list(dict.fromkeys(spec.scene for spec in specs))
    groups = [[s for s in specs if s.scene == scene] for scene in scenes]
    for members in groups:
        if len({s.reset_env_steps for s in members if s.reset_env_steps}) > 1:
            raise ValueError(f"tasks of scene {members[0].scene} step different counts at reset")
    return groups


def mocap_bodies(members: Sequence[TaskSpec]) -> tuple[str, ...]:
    """The bodies a scene group's physics moves as mocap bodies: every member task's, sorted."""
    return tuple(sorted({body for spec in members for body in spec.moved_bodies}))


def task_rows(physics: Physics, groups: Sequence[Sequence[TaskSpec]], envs_per_task: int) -> list[TaskRows]:
    """Every task's rows, task by task within each scene group (`scene_groups`)."""
    rows = []
    for g, members in enumerate(groups):
        for k, spec in enumerate(members):
            settled, raw = _load_settled(spec.name)
            rows.append(
                TaskRows(
                    spec=spec,
                    group=g,
                    start=physics.groups[g].start + k * envs_per_task,
                    local_start=k * envs_per_task,
                    size=envs_per_task,
                    settled=settled,
                    settled_data=raw,
                )
            )
    return rows


@functools.cache
def _recorded_settled_states() -> dict[str, dict[str, np.ndarray]]:
    """`tasks/settled_states.npz` by task and field, read once per process rather than once per
    task (50 reads of the archive: ~0.3 s of MT50's `mwjax.make` on a 2-core CPU)."""
    path = resources.files("mwjax.tasks") / "settled_states.npz"
    states: dict[str, dict[str, np.ndarray]] = {}
    with resources.as_file(path) as file, np.load(file) as archive:
        for key in archive.files:
            if "/" in key:  # "<task>/<field>"; the rest is the recording's provenance
                task, field = key.split("/", 1)
                states.setdefault(task, {})[field] = archive[key].astype(np.float32)
    return states


def _load_settled(name: str) -> tuple[Settled, dict[str, np.ndarray]]:
    fields = dict(_recorded_settled_states().get(name, {}))
    if not fields:
        raise ValueError(f"no settled state recorded for {name!r}")
    kin = Kinematics(*(jnp.asarray(fields[f]) for f in Kinematics._fields))
    return Settled(kin, jnp.asarray(fields["qacc_warmstart"])), fields


# Settled states per goal variant, by (scene, its mocap bodies, physics config, task, variants):
# every env of a process with the same tasks and goals shares them.
_SETTLED_PER_VARIANT: dict[tuple[Any, ...], Settled] = {}


def with_settled_variants(
    physics: Physics, rows: list[TaskRows], variants: Mapping[str, np.ndarray], n_variants: int
) -> list[TaskRows]:
    """`rows` with the settled state of each goal variant of every `settle_per_goal` task."""
    rows = list(rows)
    for g, group in enumerate(physics.groups):
        members = [i for i, r in enumerate(rows) if r.group == g and r.spec.settle_per_goal]
        if not members:
            continue
        vecs = [np.asarray(variants[rows[i].spec.name][:n_variants], np.float32) for i in members]
        # The settling steps one scene alone (`Physics.step_group`), the same with the scenes
        # side by side or not: envs of both kinds share the states.
        key = (
            group.scene,
            group.mocap_bodies,
            physics.config.physics_only(),
            tuple((rows[i].spec.name, v.tobytes()) for i, v in zip(members, vecs, strict=True)),
        )
        if key not in _SETTLED_PER_VARIANT:
            parts = [rows[i] for i in members]
            settle = jax.jit(
                lambda vs, g=g, parts=parts: _settle(physics, g, list(zip(parts, vs, strict=True)))
            )
            # Keyed by what `settle` closes over beyond mwjax's files: scene, bodies, settings and
            # tasks (the goal vectors are its argument), so a stored read traces nothing.
            described = f"placement._settle {key[:3]!r} tasks {[rows[i].spec.name for i in members]}"
            template = Settled(Kinematics(*(0,) * len(Kinematics._fields)), 0)
            _SETTLED_PER_VARIANT[key] = stored_results.run(
                settle,
                [jnp.asarray(v) for v in vecs],
                described_by=described,
                out_tree=jax.tree.structure([template] * len(members)),
            )
        for i, settled in zip(members, _SETTLED_PER_VARIANT[key], strict=True):
            rows[i] = dataclasses.replace(rows[i], settled_per_variant=settled)
    return rows


def reset_group(
    physics: Physics,
    all_rows: Sequence[TaskRows],
    g: int,
    data: PhysicsState,
    rand_vecs: Array,
    variant: Array | None,
    done: Array,
) -> tuple[PhysicsState, list[Placement], list[Settled]]:
    """Group `g`'s data with its `done` rows placed (`rand_vecs` / `variant` and `done` over the
    whole batch), and each member task's placements and settled states."""
    group = physics.groups[g]
    members = [r for r in all_rows if r.group == g]
    group_done = done[group.start : group.start + group.size]
    vecs = [rand_vecs[r.rows, : len(r.spec.random_low)] for r in members]
    settled = _settled(physics, g, members, vecs, variant)
    placements = [
        _place(r.spec, group.model, v, s.kin) for r, v, s in zip(members, vecs, settled, strict=True)
    ]
    steps = max(r.spec.reset_env_steps for r in members)
    if steps == 0:
        placed = _placed_data(data, group, list(zip(members, placements, settled, strict=True)), group_done)
        return placed, placements, settled

    # The reference steps the physics after moving fixed bodies but before writing joints:
    # move the bodies only, step, then place again on the stepped state.
    stepping = [r.spec.reset_env_steps > 0 for r in members]
    bodies_only = [
        dataclasses.replace(p, qpos=s.kin.qpos, qvel=s.kin.qvel) if st else p
        for p, s, st in zip(placements, settled, stepping, strict=True)
    ]
    pre = _placed_data(data, group, list(zip(members, bodies_only, settled, strict=True)), group_done)
    for _ in range(steps):
        pre = physics.step_group(g, pre)
    stepped = Kinematics.of(pre)
    placements = [
        _place(r.spec, group.model, v, stepped.rows(r.local_start, r.local_start + r.size)) if st else p
        for r, v, p, st in zip(members, vecs, placements, stepping, strict=True)
    ]
    placed = _placed_data(data, group, list(zip(members, placements, settled, strict=True)), group_done)
    stepped_rows = group_done & jnp.asarray(np.repeat(stepping, [r.size for r in members]))
    placed = placed.replace(
        qacc_warmstart=select_rows(stepped_rows, pre.qacc_warmstart, placed.qacc_warmstart)
    )
    return placed, placements, settled


def select_rows(mask: Array, new: Array, old: Array) -> Array:
    """Row-wise `where` for arrays with a leading batch axis."""
    return jnp.where(mask.reshape(mask.shape + (1,) * (old.ndim - 1)), new, old)


def _settled(
    physics: Physics, g: int, members: list[TaskRows], vecs: list[Array], variant: Array | None
) -> list[Settled]:
    """Each member task's settled state for its rows' goals, `(rows, ...)`: the recorded one,
    the one of the row's goal variant, or, for goals given as vectors, settled here."""
    settled: list[Settled | None] = []
    unsettled = []
    for i, rows in enumerate(members):
        if not rows.spec.settle_per_goal:
            settled.append(_broadcast(rows.settled, rows.size))
        elif variant is not None:
            rows_variant = variant[rows.rows]
            settled.append(jax.tree.map(lambda x, v=rows_variant: x[v], rows.settled_per_variant))
        else:
            settled.append(None)
            unsettled.append(i)
    if unsettled:
        computed = _settle(physics, g, [(members[i], vecs[i]) for i in unsettled])
        for i, s in zip(unsettled, computed, strict=True):
            settled[i] = s
    return settled


def _settle(physics: Physics, g: int, parts: list[tuple[TaskRows, Array]]) -> list[Settled]:
    """The reference's `_reset_hand` as a reset's second `reset_model` call runs it: from a
    fresh state (`mj_resetData`), with the fixed bodies already where the first call moved
    them for the goal, 50 env steps drive the hand to `hand_init_pos` with the fingers
    closing. `parts` are member tasks of group `g` with goal vectors `(rows, d)`; one settled
    batch per part, poses as the last `mj_step` leaves them."""
    group = physics.groups[g]
    sizes = [len(vecs) for _, vecs in parts]
    # Where the fixed bodies stand is set by the goal alone, so any settled state places them.
    poses = [
        _mocap_poses(group.model, rows, _place(rows.spec, group.model, vecs, _broadcast(rows.settled.kin, n)))
        for (rows, vecs), n in zip(parts, sizes, strict=True)
    ]
    data = physics.fresh(g, sum(sizes)).replace(
        mocap_pos=jnp.concatenate([pos for pos, _ in poses]),
        mocap_quat=jnp.concatenate([quat for _, quat in poses]),
        ctrl=_broadcast(parts[0][0].settled_data["ctrl"], sum(sizes)),
    )
    data = jax.lax.fori_loop(
        0, _SETTLE_ENV_STEPS, lambda _, d: physics.step_group(g, d, fresh_poses=False), data
    )
    kin, bounds = Kinematics.of(data), np.cumsum([0, *sizes])
    return [
        Settled(kin.rows(a, b), data.qacc_warmstart[a:b])
        for a, b in zip(bounds[:-1], bounds[1:], strict=True)
    ]


def _placed_data(
    data: PhysicsState, group: Any, parts: list[tuple[TaskRows, Placement, Settled]], done: Array
) -> PhysicsState:
    model = group.model
    mocap_pos, mocap_quat, qpos, qvel, warm, ctrl = [], [], [], [], [], []
    for rows, placement, settled in parts:
        pos, quat = _mocap_poses(model, rows, placement)
        mocap_pos.append(pos)
        mocap_quat.append(quat)
        qpos.append(placement.qpos)
        qvel.append(placement.qvel)
        warm.append(settled.qacc_warmstart)
        ctrl.append(_broadcast(rows.settled_data["ctrl"], len(placement.qpos)))
    fresh = {
        "qpos": qpos,
        "qvel": qvel,
        "mocap_pos": mocap_pos,
        "mocap_quat": mocap_quat,
        "qacc_warmstart": warm,
        "ctrl": ctrl,
    }
    # These fields are the whole dynamic state; everything else is derived from them.
    fields = {
        name: select_rows(done, jnp.concatenate(parts).astype(jnp.float32), getattr(data, name))
        for name, parts in fresh.items()
    }
    return data.replace(time=jnp.where(done, 0.0, data.time), **fields)


def _place(spec: TaskSpec, model: Any, rand_vecs: Array, settled: Kinematics) -> Placement:
    """`spec.place` over a task's rows, each from its own settled (or stepped) state."""
    return jax.vmap(lambda v, k: spec.place(v, Frame(model, k)))(rand_vecs, settled)


def _broadcast(tree: Any, n: int) -> Any:
    """One env's arrays repeated over `n` rows."""
    return jax.tree.map(lambda x: jnp.broadcast_to(jnp.asarray(x), (n, *jnp.shape(x))), tree)


def _mocap_poses(model: Any, rows: TaskRows, placement: Placement) -> tuple[Array, Array]:
    """Every mocap body's pose over a task's rows, `(rows, nmocap, 3 / 4)`: the hand's settled
    target, the fixed bodies the task moves where `placement` puts them, the rest as compiled."""
    n = len(placement.qpos)
    is_mocap = model.body_mocapid >= 0  # body order is mocap index order
    pos = jnp.asarray(np.broadcast_to(model.body_pos[is_mocap], (n, model.nmocap, 3)), jnp.float32)
    quat = jnp.asarray(np.broadcast_to(model.body_quat[is_mocap], (n, model.nmocap, 4)), jnp.float32)
    pos = pos.at[:, 0].set(rows.settled_data["mocap_pos"][0])
    quat = quat.at[:, 0].set(rows.settled_data["mocap_quat"][0])
    for name, value in placement.moved_bodies.items():
        pos = pos.at[:, int(model.body_mocapid[model.body(name).id])].set(value)
    return pos, quat
