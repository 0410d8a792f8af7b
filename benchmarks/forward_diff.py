"""Where two runs of the same physics call part: MuJoCo's forward pass and step, each run twice on
identical data in one process, compared field by field in pipeline order (docs/determinism.md).

    python benchmarks/forward_diff.py --set MT10 --envs-per-task 1024 --steps 50
    python benchmarks/forward_diff.py --set MT10 --envs-per-task 1024 --graph-mode none
    MWJAX_DETERMINISTIC=1 python benchmarks/forward_diff.py --set MT10 --envs-per-task 1024

Steps the set `--steps` env steps with seeded random actions (so that arms touch objects and
contacts exist), then, for each scene batch, rebuilds its whole `mjx.Data` from the carried state
and runs the scene's jitted `mjx.forward` twice and its jitted `mjx.step` twice on it. Per field,
in the order MuJoCo computes them (positions, collision, constraints, velocities and forces,
solver, integration), it reports whether the two results are identical bit for bit, how far apart
they are and in how many worlds. Contacts are compared as found and also sorted by world, geom
pair and position, which tells contacts found in another order from contacts that differ. The
first field that differs is where the nondeterminism enters. On the CPU every field is identical
(Warp runs threads in order), which is what the test checks. Results: a table, and a JSON file
in `benchmarks/results/determinism/`.
"""

from __future__ import annotations

import argparse
import dataclasses
import functools
import json
import sys
from pathlib import Path

import numpy as np

# (stage, field); fields of `mjx.Data` or of its Warp part (`data._impl`).
PIPELINE = (
    [("position", f) for f in ("xpos", "xquat", "xmat", "geom_xpos", "geom_xmat", "cinert", "cdof", "M")]
    + [("collision", "nacon")]
    + [("constraint", f) for f in ("nefc", "efc__type", "efc__id", "efc__J", "efc__D", "efc__pos")]
    + [("velocity", f) for f in ("cvel", "cdof_dot", "qfrc_bias", "qfrc_passive", "qfrc_actuator")]
    + [("solver", f) for f in ("qacc_smooth", "efc__aref", "efc__force", "qfrc_constraint", "qacc")]
)
CONTACT_FIELDS = ("worldid", "geom", "dist", "pos", "frame", "friction", "solref", "solimp", "dim")
STEP_FIELDS = ("qpos", "qvel", "qacc_warmstart", "nefc")


def field(data: object, name: str) -> np.ndarray:
    """A field of `mjx.Data`, or of its Warp part where MJX keeps it there."""
    public = {f.name for f in dataclasses.fields(data)}
    return np.asarray(getattr(data if name in public else data._impl, name))


def compare(a: np.ndarray, b: np.ndarray, per_world: bool) -> dict:
    """Bit-identity, the largest difference and (for per-world arrays) the worlds that differ."""
    same = a.shape == b.shape and a.tobytes() == b.tobytes()
    out: dict = {"identical": same}
    if same or a.shape != b.shape:
        return out | {"max_abs_diff": 0.0 if same else None}
    diff = np.abs(a.astype(np.float64) - b.astype(np.float64))
    out["max_abs_diff"] = float(np.nanmax(diff)) if diff.size else 0.0
    if per_world and a.ndim:
        differs = (a != b).reshape(a.shape[0], -1).any(axis=1)
        out["worlds_differing"] = int(differs.sum())
    return out


def valid_rows(data: object) -> np.ndarray:
    """Per world, which of the `njmax` constraint rows hold a row (the rest is stale memory)."""
    nefc = field(data, "nefc")
    rows = field(data, "efc__type").shape[1]
    return np.arange(rows)[None, :] < nefc[:, None]


def contacts(data: object, order: bool) -> dict[str, np.ndarray]:
    """The contacts found (the first `nacon` of the shared buffer), in found order or sorted."""
    n = int(field(data, "nacon").reshape(-1)[0])
    found = {name: field(data, f"contact__{name}")[:n] for name in CONTACT_FIELDS}
    if order:
        pos, geom = found["pos"], found["geom"]
        keys = (pos[:, 2], pos[:, 1], pos[:, 0], geom[:, 1], geom[:, 0], found["worldid"])
        found = {name: value[np.lexsort(keys)] for name, value in found.items()}
    return found


def diff_forward(first: object, second: object) -> list[dict]:
    rows = []
    valid = valid_rows(first)
    same_rows = np.array_equal(valid, valid_rows(second))
    for stage, name in PIPELINE:
        a, b = field(first, name), field(second, name)
        if name.startswith("efc__") and a.ndim >= 2:
            if not same_rows:
                rows.append({"stage": stage, "field": name, "identical": False, "max_abs_diff": None})
                continue
            keep = _expand(valid, a)
            a, b = np.where(keep, a, 0), np.where(keep, b, 0)
        rows.append({"stage": stage, "field": name, **compare(a, b, per_world=name != "nacon")})
        if name == "nacon":
            for order in (False, True):
                ca, cb = contacts(first, order), contacts(second, order)
                label = "sorted" if order else "as found"
                for key in CONTACT_FIELDS:
                    result = compare(ca[key], cb[key], per_world=False)
                    rows.append({"stage": "collision", "field": f"contact {key} ({label})", **result})
    return rows


def _expand(mask: np.ndarray, like: np.ndarray) -> np.ndarray:
    return mask.reshape(mask.shape + (1,) * (like.ndim - mask.ndim))


def measure(args: argparse.Namespace) -> dict:
    import jax
    import jax.numpy as jnp
    from common import provenance, tasks_arg
    from mujoco import mjx

    import mwjax
    from mwjax import determinism, warp_empty_args

    physics = mwjax.PhysicsConfig(graph_mode=args.graph_mode)
    env = mwjax.make(tasks_arg(args.set), envs_per_task=args.envs_per_task, seed=args.seed, physics=physics)

    def run(state: mwjax.State, key: jax.Array) -> mwjax.State:
        def body(state: mwjax.State, key: jax.Array) -> tuple:
            action = jax.random.uniform(key, (env.num_envs, 4), minval=-1.0, maxval=1.0)
            return env.step(state, action), None

        return jax.lax.scan(body, state, jax.random.split(key, args.steps))[0]

    state = jax.jit(run)(jax.jit(env.reset)(jax.random.key(args.seed)), jax.random.key(args.seed + 1))
    scenes = []
    for g, group in enumerate(env.physics.groups):
        model = warp_empty_args.traced(group.device_model)
        forward = jax.jit(jax.vmap(functools.partial(mjx.forward, model)))
        step = jax.jit(jax.vmap(functools.partial(mjx.step, model)))
        data = jax.jit(functools.partial(env.physics.data, g))(state.physics[g])
        first, second = jax.block_until_ready(forward(data)), jax.block_until_ready(forward(data))
        rows = diff_forward(first, second)
        after = [jax.block_until_ready(step(data)) for _ in range(2)]
        for name in STEP_FIELDS:
            rows.append({"stage": "step", "field": name, **compare(*(field(d, name) for d in after), True)})
        differing = [r for r in rows if not r["identical"]]
        scenes.append(
            {
                "scene": group.scene,
                "envs": group.size,
                "contacts": int(field(first, "nacon").reshape(-1)[0]),
                "constraint_rows": int(jnp.sum(field(first, "nefc"))),
                "first_differing": f"{differing[0]['stage']}: {differing[0]['field']}" if differing else None,
                "fields": rows,
            }
        )
        print(f"{group.scene}: {scenes[-1]['first_differing'] or 'identical'}", file=sys.stderr, flush=True)
    return {
        **provenance(),
        "set": args.set,
        "envs_per_task": args.envs_per_task,
        "steps_before": args.steps,
        "seed": args.seed,
        "graph_mode": args.graph_mode,
        "deterministic_mode": determinism.enabled(),
        "identical": all(s["first_differing"] is None for s in scenes),
        "scenes": scenes,
    }


def main(argv: list[str] | None = None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--set", default="MT10", help="a set name, or task names separated by commas")
    parser.add_argument("--envs-per-task", type=int, default=1024)
    parser.add_argument("--steps", type=int, default=50, help="random-action env steps before the diff")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--graph-mode", default=None, help="PhysicsConfig.graph_mode (default: MJX's)")
    parser.add_argument("--out", default=None, help="JSON path (default: benchmarks/results/determinism/)")
    args = parser.parse_args(argv)
    from common import result_path

    result = measure(args)
    for scene in result["scenes"]:
        print(f"\n{scene['scene']} ({scene['envs']} envs, {scene['contacts']} contacts)")
        for row in scene["fields"]:
            extra = f"  {row['worlds_differing']} worlds" if "worlds_differing" in row else ""
            diff = row["max_abs_diff"]
            text = (
                "identical" if row["identical"] else f"DIFFERS by {diff if diff is None else f'{diff:.3g}'}"
            )
            print(f"  {row['stage']:>10}  {row['field']:<28} {text}{extra}")
    out = Path(args.out) if args.out else result_path("determinism", "forward-diff", ".json")
    out.write_text(json.dumps(result, indent=2))
    print(f"\nidentical: {result['identical']}; {result['device']}, commit {result['commit'][:10]} -> {out}")
    return result


if __name__ == "__main__":
    main()
