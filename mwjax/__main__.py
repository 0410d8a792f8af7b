"""`python -m mwjax`: what mwjax is for, in about a minute.

1. The jax scripted experts (`mwjax.policies`) solve every task of a set (MT10 by default) by
   the reference's evaluation protocol (one episode per goal variant, success at any step within
   500), next to the reference experts' success on the same goals.
2. Throughput under random actions: compiled, run once to warm up (Warp's first-run kernel
   builds land there), then timed. Compile time is reported on its own, never as throughput.
   Episodes are staggered (each env's counter starts at a random point of its 500 steps), so
   the short timed window (GPU: 100 steps) sees resets at their long-run rate, as
   `benchmarks/throughput.py --stagger` does; that script is the full protocol.

On a GPU (set XLA_PYTHON_CLIENT_MEM_FRACTION=0.45 so that Warp gets memory) the experts run 50
episodes per MT10 task. On the CPU, where one env step of one scene's physics takes ~0.1 s, they
run one episode per task of MT10's three tasks that share a scene (under a minute with warm
caches). A machine's first run also builds Warp's kernels and compiles XLA's programs, which
takes minutes; both are cached for later runs (README, Set up).
"""

from __future__ import annotations

import argparse
import dataclasses
import time
from collections.abc import Callable, Sequence
from typing import Any

# The reference experts' success per task (metaworld 3.1.1, each task's MT1 seed-42 goals, one
# episode per goal, success at any step within 500; tools/record_expert_success.py): 1.0 but for
# these.
REFERENCE_SEED = 42
REFERENCE_BELOW_ONE = {
    "box-close-v3": 0.92,
    "button-press-wall-v3": 0.94,
    "disassemble-v3": 0.94,
    "door-open-v3": 0.94,
    "peg-insert-side-v3": 0.90,
    "peg-unplug-side-v3": 0.94,
    "soccer-v3": 0.90,
    "stick-pull-v3": 0.90,
    "push-back-v3": 0.98,
    "shelf-place-v3": 0.96,
    "sweep-into-v3": 0.90,
}
HORIZON = 500
# On the CPU one env step of a scene's physics takes ~0.1 s whatever the batch, and MT10 has 8
# scenes: its experts need ~90 steps to solve all ten, minutes there. By default the CPU runs
# MT10's three tasks that share one scene.
CPU_TASKS = ["reach-v3", "push-v3", "pick-place-v3"]


def reference_success(task: str) -> float:
    return REFERENCE_BELOW_ONE.get(task, 1.0)


def _task_set(value: str) -> str | list[str]:
    """`--tasks`: a set name, "MT1:<task>", or task names separated by commas."""
    from mwjax import benchmarks  # here, not at the top: `--help` must not wait for JAX

    tasks: str | list[str] = value.split(",") if "," in value else value
    try:
        bench = benchmarks.benchmark(tasks)
    except ValueError as error:
        raise argparse.ArgumentTypeError(str(error)) from None
    if bench.meta_learning:
        raise argparse.ArgumentTypeError(f"{value} is a meta-learning set; give an MT set or task names")
    return tasks


def _label(tasks: str | list[str]) -> str:
    return tasks if isinstance(tasks, str) else ", ".join(tasks)


def _positive_int(value: str) -> int:
    try:
        number = int(value)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not an integer: {value!r}") from None
    if number < 1:
        raise argparse.ArgumentTypeError(f"must be at least 1, got {number}")
    return number


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="python -m mwjax",
        description=__doc__.split("\n", 1)[1].strip() if __doc__ else None,
        formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog="Defaults marked GPU/CPU depend on whether JAX sees a GPU.",
    )
    parser.add_argument(
        "--tasks",
        type=_task_set,
        help='the tasks: an MT set ("MT10", "MT50"), "MT1:<task>", or task names separated by '
        "commas (default: GPU MT10, CPU " + ",".join(CPU_TASKS) + ")",
    )
    parser.add_argument(
        "--episodes",
        type=_positive_int,
        help="expert episodes per task, one per goal variant (default: GPU 50, CPU 1)",
    )
    parser.add_argument("--no-experts", action="store_true", help="skip the experts; throughput only")
    parser.add_argument(
        "--envs-per-task",
        type=_positive_int,
        help="batch of the throughput rollout, per task (default: GPU 1024, CPU 2)",
    )
    parser.add_argument(
        "--steps",
        type=_positive_int,
        help="env steps of the timed throughput window, episodes staggered (default: GPU 100, CPU 5)",
    )
    parser.add_argument(
        "--seed",
        type=int,
        default=REFERENCE_SEED,
        help=f"goal variants and random actions (default: {REFERENCE_SEED}, the reference figures' seed)",
    )
    return parser


def parse_args(argv: Sequence[str] | None = None) -> argparse.Namespace:
    return build_parser().parse_args(argv)


@dataclasses.dataclass(frozen=True)
class Timing:
    """A compiled program's first run (which also builds Warp's kernels on a fresh machine) and
    a second, timed run of the same program on the same inputs: the steady state."""

    first_run_s: float
    timed_run_s: float
    env_steps: int

    @property
    def steps_per_second(self) -> float:
        return self.env_steps / self.timed_run_s


def timed(run: Callable[[], Any], env_steps: int, clock: Callable[[], float] = time.perf_counter) -> Timing:
    """Run `run` (a compiled program that blocks until its results are ready) twice: a warm-up
    and the timed run. Only the second counts for the rate."""
    start = clock()
    run()
    first = clock() - start
    start = clock()
    run()
    return Timing(first_run_s=first, timed_run_s=clock() - start, env_steps=env_steps)


def main(argv: Sequence[str] | None = None) -> None:
    args = parse_args(argv)
    import jax

    run_job(args, prebuild=jax.default_backend() == "gpu")


def run_job(args: argparse.Namespace, prebuild: bool) -> None:
    """The main job; `prebuild` (the GPU's default) compiles Warp's kernel modules in processes
    (`mwjax.kernels`) while XLA compiles the programs, instead of one by one in their first run."""
    started = time.perf_counter()
    import jax

    import mwjax
    from mwjax import progress

    on_gpu = jax.default_backend() == "gpu"
    print(f"mwjax on {jax.devices()[0].device_kind}", flush=True)
    tasks = args.tasks or ("MT10" if on_gpu else CPU_TASKS)
    if tasks is CPU_TASKS:
        print(f"on the CPU: {_label(tasks)}, MT10's tasks of one scene (`--tasks MT10` takes minutes)")
    pending = None
    if prebuild:
        from mwjax import kernels

        # The worker processes compile while this one compiles XLA's programs below; nothing here
        # launches a physics kernel before `pending.result()`.
        pending = kernels.start_build(tasks)
        if not pending.done:
            workers = f"{pending.workers} processes"
            print(f"{pending.modules} physics kernel modules compile in {workers}, meanwhile:", flush=True)
    episodes = args.episodes or (50 if on_gpu else 1)
    run_experts = None if args.no_experts else experts(tasks, episodes, args.seed)
    envs_per_task = args.envs_per_task or (1024 if on_gpu else 2)
    steps = args.steps or (100 if on_gpu else 5)
    with progress.phase(f"building {_label(tasks)} with {envs_per_task} envs per task"):
        env = mwjax.make(tasks, envs_per_task=envs_per_task, seed=args.seed)
    run_throughput = throughput(env, steps, args.seed)
    prebuilt = 0
    if pending is not None and not pending.done:
        build = pending.wait(f"waiting for the {pending.modules} physics kernel modules")
        print(f"{build.built} physics kernel modules built in {build.seconds:.0f} s", flush=True)
        prebuilt = build.built
    if run_experts is not None:
        run_experts()
    run_throughput()
    builds = progress.kernel_builds()
    built = progress.modules(builds.built + prebuilt)
    print(
        f"total {time.perf_counter() - started:.0f} s; Warp built {built} "
        f"({prebuilt} of them in parallel processes) and loaded {builds.cached} from its cache",
        flush=True,
    )


def experts(tasks: str | list[str], episodes: int, seed: int) -> Callable[[], None]:
    """The experts on every task, each on its own MT1 goal variants (the reference's), one
    episode per variant; the run stops early once every episode has succeeded. Builds the env and
    compiles the rollout; the function it returns runs it and prints the table."""
    import jax
    import jax.numpy as jnp
    import numpy as np

    import mwjax
    from mwjax import benchmarks, policies, progress

    names = benchmarks.task_names(tasks)
    with progress.phase(f"building {len(names)} tasks for the experts ({episodes} episode(s) each)"):
        env = mwjax.make(
            tasks,
            envs_per_task=episodes,
            seed=seed,
            goal_variants=benchmarks.mt1_goal_variants(names, seed),
            autoreset="disabled",
        )
    # Episode j of every task on goal variant j, as `mwjax.evaluation` runs them.
    variants = np.tile(np.arange(episodes) % benchmarks.N_GOALS, len(env.task_list))
    policy = policies.expert_policy(env)

    def rollout(key: jax.Array) -> tuple[jax.Array, jax.Array]:
        def unfinished(carry: tuple) -> jax.Array:
            _, running, _, t = carry
            return jnp.any(running) & (t < HORIZON)

        def step(carry: tuple) -> tuple:
            state, running, success, t = carry
            state = env.step(state, policy(None, state.obs, key))
            success = success | (running & state.info["success"])
            return state, running & ~state.info["success"], success, t + 1

        state = env.reset_with_variants(jnp.asarray(variants), key)
        init = (state, jnp.ones(env.num_envs, bool), jnp.zeros(env.num_envs, bool), jnp.int32(0))
        _, _, success, t = jax.lax.while_loop(unfinished, step, init)
        return success, t

    key = jax.random.key(seed)
    with progress.phase("compiling the experts' rollout (XLA)"):
        compiled = jax.jit(rollout).lower(key).compile()

    def run() -> None:
        with progress.phase("running the experts"):
            start = time.perf_counter()
            success, steps = jax.block_until_ready(compiled(key))
            seconds = time.perf_counter() - start
        table = np.asarray(success).reshape(len(env.task_list), episodes)
        print(
            f"\nscripted experts, {episodes} episode(s) per task on each task's seed-{seed} MT1 goals, "
            f"stopped after {int(steps)} steps ({seconds:.1f} s):"
        )
        print(f"  {'task':<30} {'mwjax':>8}   reference experts (seed {REFERENCE_SEED}, 50 goals)")
        for task, row in zip(env.task_list, table, strict=True):
            print(f"  {task:<30} {row.mean():>8.2f}   {reference_success(task):.2f}")
        reference = np.mean([reference_success(t) for t in names])
        print(f"  {'mean':<30} {table.mean():>8.2f}   {reference:.2f}\n")

    return run


def throughput(env: Any, steps: int, seed: int) -> Callable[[], None]:
    """Env steps per second under uniform random actions (obs, rewards and autoreset included).
    Compiles the reset and the rollout (from the reset's shapes: nothing runs); the function it
    returns resets, staggers the episodes, runs the rollout twice and prints the rate."""
    import jax

    from mwjax import progress
    from mwjax.env import staggered

    def rollout(state: Any, key: jax.Array) -> Any:
        def body(state: Any, key: jax.Array) -> tuple[Any, None]:
            action = jax.random.uniform(key, (env.num_envs, 4), minval=-1.0, maxval=1.0)
            return env.step(state, action), None

        return jax.lax.scan(body, state, jax.random.split(key, steps))[0]

    key = jax.random.key(seed)
    with progress.phase("compiling the reset and the random-action rollout (XLA)"):
        start = time.perf_counter()
        reset = jax.jit(env.reset).lower(key)
        compiled = jax.jit(rollout).lower(reset.out_info, key).compile()
        reset = reset.compile()
        compile_s = time.perf_counter() - start

    def run() -> None:
        label = f"reset, then a rollout of {steps} steps x {env.num_envs} envs: warm-up run, then timed run"
        with progress.phase(label):
            state = staggered(jax.block_until_ready(reset(key)), env.max_episode_steps, key)
            timing = timed(lambda: jax.block_until_ready(compiled(state, key)), env.num_envs * steps)
        scenes = "scenes side by side" if env.physics.concurrent_scenes else "scenes in turn"
        print(
            f"throughput, random actions: {env.num_envs} envs ({len(env.task_list)} tasks, {scenes}), "
            f"{steps}-step window of staggered episodes (autoreset inside): "
            f"{timing.steps_per_second:,.0f} env steps/s (timed run {timing.timed_run_s:.2f} s; "
            f"compile {compile_s:.1f} s and warm-up run {timing.first_run_s:.2f} s not counted)",
            flush=True,
        )

    return run


if __name__ == "__main__":
    main()
