"""Where the PPO example's first chunk spends its time: build, trace and lower, XLA compile, then
each run, timed apart, on 1 or several local devices (`train_mt_ppo.py --devices`).

    python tools/ppo_chunk_probe.py --devices 4 --envs-per-task 13104 --runs 2   # 4 GPUs
    python -m mwjax.distributed --processes 4 tools/ppo_chunk_probe.py --devices 4 \\
        --envs-per-task 13104 --runs 2 --split                                   # one process each
    XLA_FLAGS=--xla_force_host_platform_device_count=4 JAX_PLATFORMS=cpu \\
        python tools/ppo_chunk_probe.py --set MT10 --devices 4 --envs-per-task 16 --unroll 4 \\
        --minibatches 2 --epochs 1 --updates 2                                   # CPU

The example itself times the first chunk as one block (compile and run together); a sharded run
that prints nothing for minutes is either compiling or stuck, and this tells which: each phase
prints its line as it ends, so a phase that never ends is the one that hangs. `--split` then
times the same updates' rollouts alone (on one device the learner too): where an update's time goes.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import jax

sys.path.insert(0, str(Path(__file__).parents[1]))
from examples import train_mt_ppo as ppo  # noqa: E402
from mwjax import distributed  # noqa: E402


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--set", default="MT10", help="a set name, or tasks separated by commas")
    parser.add_argument("--devices", type=int, default=1)
    parser.add_argument("--envs-per-task", type=int, default=ppo.Config.envs_per_task)
    parser.add_argument("--unroll", type=int, default=ppo.Config.unroll)
    parser.add_argument("--minibatches", type=int, default=ppo.Config.minibatches)
    parser.add_argument("--epochs", type=int, default=ppo.Config.epochs)
    parser.add_argument("--updates", type=int, default=10, help="updates per chunk (--log-every)")
    parser.add_argument("--runs", type=int, default=1, help="chunks run after the compile")
    parser.add_argument(
        "--split",
        action="store_true",
        help="then time the chunk's rollouts alone (and the learner, on one device)",
    )
    args = parser.parse_args()
    distributed.initialize()  # under `python -m mwjax.distributed`: one process per GPU

    def say(what: str, since: float) -> float:
        now = time.perf_counter()
        if distributed.is_main():
            print(f"{what}: {now - since:.1f} s", flush=True)
        return now

    print(f"{args.set} on {args.devices} of {jax.devices()}", flush=True)
    config = ppo.Config(
        task_set=ppo.task_set(args.set),
        envs_per_task=args.envs_per_task,
        unroll=args.unroll,
        minibatches=args.minibatches,
        epochs=args.epochs,
        devices=args.devices,
    )
    t = time.perf_counter()
    trainer = ppo.Trainer(config)
    t = say(f"build ({trainer.env.num_envs} envs)", t)
    carry = jax.block_until_ready(trainer.init(jax.random.key(0)))
    t = say("first state (reset compiled and run)", t)
    lowered = trainer.train_chunk.lower(carry, args.updates)
    t = say(f"trace and lower a chunk of {args.updates} updates", t)
    compiled = lowered.compile()
    t = say("XLA compile", t)
    for i in range(args.runs):
        carry, metrics = compiled(carry)
        jax.block_until_ready(metrics)
        t = say(f"run {i + 1} ({args.updates * trainer.steps_per_update:,} env steps)", t)
    if args.split:  # each timed without its compile
        rollouts = trainer.rollout_seconds(carry, args.updates)
        say(f"the rollouts of {args.updates} updates alone took {rollouts:.1f} s; compile and both runs", t)
        if trainer.axis is None:
            learner = trainer.learner_seconds(carry, args.updates)
            print(f"the learner of {args.updates} updates alone: {learner:.1f} s", flush=True)


if __name__ == "__main__":
    main()
