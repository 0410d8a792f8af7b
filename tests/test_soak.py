"""Random actions on every task never produce NaN or inf (observations, V1 and V2 rewards).

The full check is 10,000 random-action steps per task (20 envs x 500 steps, so every env also
autoresets) in both reward versions. Warp on a 2-core CPU runs the 50-task set at under 100 env
steps/s, so that takes hours there: it is marked slow (runs on a GPU or with MWJAX_SLOW=1). CI runs
the short version on the compiled all-task env that the parity and episode tests share (in their
child process on the CPU: `reference.all_task_runs`).
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from reference import SOAK_STEPS, all_task_runs_child, free_runs

import mwjax
from mwjax.tasks import TASKS

FULL_ENVS_PER_TASK, FULL_STEPS = 20, 500


@pytest.mark.child.with_args(all_task_runs_child)
def test_short_random_rollout_stays_finite(request):
    run = free_runs(request, "soak")  # `reference.soak_run`: SOAK_STEPS steps of every task
    for t in range(SOAK_STEPS):
        bad = sorted(task for task, arrays in run.items() if not arrays["finite"][:, t].all())
        assert not bad, f"non-finite at step {t} in {bad}"
    assert set(run) == set(TASKS)


@pytest.mark.slow
@pytest.mark.parametrize("reward_version", ["v2", "v1"])
def test_10k_random_steps_per_task_stay_finite(reward_version):
    env = mwjax.make(sorted(TASKS), envs_per_task=FULL_ENVS_PER_TASK, reward_version=reward_version)

    def rollout(key: jax.Array) -> jax.Array:
        def step(state: mwjax.State, key: jax.Array) -> tuple[mwjax.State, jax.Array]:
            action = jax.random.uniform(key, (env.num_envs, 4), minval=-1.0, maxval=1.0)
            state = env.step(state, action)
            finite = jnp.isfinite(state.obs).all(axis=1) & jnp.isfinite(state.reward)
            return state, ~finite

        reset_key, steps_key = jax.random.split(key)
        _, bad = jax.lax.scan(step, env.reset(reset_key), jax.random.split(steps_key, FULL_STEPS))
        return bad.sum(axis=0)

    bad_per_env = np.asarray(jax.jit(rollout)(jax.random.key(0)))
    bad_tasks = sorted({env.task_names[i] for i in np.flatnonzero(bad_per_env)})
    assert not bad_tasks, f"non-finite obs or reward in {bad_tasks}"
