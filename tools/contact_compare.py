"""MJX-Warp against MuJoCo C, substep by substep, from the same state: contacts per geom pair.

    python tools/contact_compare.py coffee-pull-v3 --goal 3 --step 21

Runs the jax expert on one goal variant in mwjax (MJX-Warp, one env) for `--step` env steps,
then steps that env step's substeps in both engines, copying Warp's state into MuJoCo C before
each substep, and prints per geom pair the number of contacts, the deepest one and the summed
normal force, plus the free bodies' velocity after the substep. A diagnostic: it reads Warp's
contact list from MJX's private `Data._impl`, which no library code does. It found coffee-pull's
phantom table contact (docs/fidelity.md, coffee-pull).
"""

from __future__ import annotations

import argparse
import functools

import jax
import jax.numpy as jnp
import mujoco
import numpy as np
from mujoco import mjx

import mwjax
from mwjax import policies

STATE_FIELDS = ("qpos", "qvel", "mocap_pos", "mocap_quat", "qacc_warmstart", "ctrl")


def _pair(model: mujoco.MjModel, g1: int, g2: int) -> str:
    names = sorted(model.body(model.geom_bodyid[g]).name or "world" for g in (g1, g2))
    return "/".join(names)


def c_contacts(model: mujoco.MjModel, data: mujoco.MjData) -> list[tuple[str, float, float]]:
    out = []
    force = np.zeros(6)
    for i in range(data.ncon):
        contact = data.contact[i]
        mujoco.mj_contactForce(model, data, i, force)
        out.append((_pair(model, contact.geom1, contact.geom2), float(contact.dist), float(force[0])))
    return out


def warp_contacts(model: mujoco.MjModel, data: mjx.Data) -> list[tuple[str, float, float]]:
    impl = data._impl
    n = int(np.asarray(impl.nacon).ravel()[0])
    geom, dist = np.asarray(impl.contact__geom)[:n], np.asarray(impl.contact__dist)[:n]
    address, force = np.asarray(impl.contact__efc_address)[:n], np.asarray(impl.efc__force)[0]
    # Elliptic cones: a contact's first constraint row carries its normal force.
    return [
        (
            _pair(model, *geom[i]),
            float(dist[i]),
            float(force[address[i, 0]]) if address[i, 0] >= 0 else np.nan,
        )
        for i in range(n)
    ]


def _by_pair(contacts: list[tuple[str, float, float]]) -> dict[str, tuple[int, float, float]]:
    out: dict[str, tuple[int, float, float]] = {}
    for pair, dist, force in contacts:
        n, deepest, total = out.get(pair, (0, np.inf, 0.0))
        out[pair] = (n + 1, min(deepest, dist), total + force)
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("task")
    parser.add_argument("--goal", type=int, default=0, help="goal variant (MT1, seed 42)")
    parser.add_argument("--step", type=int, default=0, help="env steps of the expert before comparing")
    args = parser.parse_args()

    env = mwjax.make("MT1", task=args.task, seed=42, autoreset="disabled")
    expert, step = jax.jit(policies.expert_policy(env)), jax.jit(env.step)
    state = jax.jit(env.reset_with_variants)(jnp.array([args.goal]))
    for _ in range(args.step):
        state = step(state, jnp.clip(expert(None, state.obs, None), -1.0, 1.0))
    action = jnp.clip(expert(None, state.obs, None), -1.0, 1.0)
    group = env.physics.groups[0]
    model = group.model
    substep = jax.jit(jax.vmap(functools.partial(mjx.step, group.device_model)))
    warp = jax.jit(lambda s, a: env.physics.data(0, env.apply_action(s, a)[0]))(state.physics, action)
    c = mujoco.MjData(model)
    free = np.flatnonzero(model.jnt_type == mujoco.mjtJoint.mjJNT_FREE)
    dofs = np.concatenate([np.arange(model.jnt_dofadr[j], model.jnt_dofadr[j] + 6) for j in free])
    print(f"{args.task}, goal {args.goal}, env step {args.step}; action {np.asarray(action[0]).round(3)}")
    for k in range(env.physics.config.substeps):
        for field in STATE_FIELDS:
            getattr(c, field)[:] = np.asarray(getattr(warp, field)[0], np.float64)
        mujoco.mj_step(model, c)
        warp = substep(warp)
        speed = np.abs(c.qvel[dofs] - np.asarray(warp.qvel[0], np.float64)[dofs]).max(initial=0.0)
        print(
            f"substep {k}: constraint rows C {c.nefc}, Warp {int(np.asarray(warp._impl.nefc).ravel()[0])}; "
            f"largest free-body velocity difference {speed:.4f}"
        )
        ours, theirs = _by_pair(c_contacts(model, c)), _by_pair(warp_contacts(model, warp))
        for pair in sorted(set(ours) | set(theirs)):
            (nc, dc, fc), (nw, dw, fw) = ours.get(pair, (0, np.nan, 0.0)), theirs.get(pair, (0, np.nan, 0.0))
            flag = "  <-- differs" if nc != nw or abs(dc - dw) > 1e-3 else ""
            print(
                f"  {pair:40s} contacts C {nc} / Warp {nw}  deepest {dc:+.5f} / {dw:+.5f}  "
                f"normal force {fc:8.2f} / {fw:8.2f}{flag}"
            )


if __name__ == "__main__":
    main()
