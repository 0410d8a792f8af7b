"""How far a task's per-goal settled state moves when its goal moves by a hair.

For the tasks that settle per goal (`TaskSpec.settle_per_goal`: the settling arm touches a body
the goal places), `mwjax.make` runs the reference's `_reset_hand` (50 env steps) once per goal
variant. This settles each of the first `--variants` goal variants of every such task twice, the
second time with every goal coordinate moved by `--shift` (1e-6 m: float32's rounding at these
magnitudes), and prints, per task, the largest change of each settled field. A change far
larger than the shift marks a chaotic settling: on a GPU, whose atomics make each computation
differ in its last bits, such a task's episodes would start elsewhere in every process, which is
why `mwjax.stored_results` keeps the computed states. Writes a JSON row (`--out`).

    JAX_PLATFORMS=cpu python tools/settle_sensitivity.py --variants 8
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np

sys.path.insert(0, str(Path(__file__).parents[1]))
import mwjax  # noqa: E402
from benchmarks.common import provenance  # noqa: E402
from mwjax import placement  # noqa: E402
from mwjax.tasks import TASKS  # noqa: E402


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--variants", type=int, default=8, help="goal variants per task")
    parser.add_argument("--shift", type=float, default=1e-6, help="added to every goal coordinate")
    parser.add_argument("--out", type=Path, default=None, help="JSON path")
    args = parser.parse_args()
    names = [name for name, spec in TASKS.items() if spec.settle_per_goal]
    env = mwjax.make(names, envs_per_task=1, seed=0)
    rows: dict[str, dict[str, float]] = {}
    for task in env._rows:  # the env holds only the tasks that settle per goal
        settle = jax.jit(lambda v, task=task: placement._settle(env.physics, task.group, [(task, v)])[0])
        goals = jnp.asarray(np.asarray(env.goal_variants[task.spec.name][: args.variants], np.float32))
        base, shifted = settle(goals), settle(goals + args.shift)
        rows[task.spec.name] = {
            field: float(jnp.max(jnp.abs(a - b)))
            for field, a, b in zip(base.kin._fields, base.kin, shifted.kin, strict=True)
        }
        change = rows[task.spec.name]
        worst = max(change.items(), key=lambda item: item[1])
        line = f"{task.spec.name:24s} qpos {change['qpos']:.3g}, largest {worst[0]} {worst[1]:.3g}"
        print(line, flush=True)
    if args.out:
        row = {**provenance(), "variants": args.variants, "shift": args.shift, "max_change": rows}
        args.out.write_text(json.dumps(row, indent=2) + "\n")
        print(f"-> {args.out}")


if __name__ == "__main__":
    main()
