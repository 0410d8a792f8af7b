"""Which goal variant each env runs: the variants of a set's tasks, each env's pool of them, and
the draws (a uniform pick at every reset for MT sets, a shuffled cycle for ML sets).

The variants themselves (the reference's `rand_vec`s) are sampled on the host by
`mwjax.benchmarks`; here the env only draws indices into them, on the device.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping, Sequence
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np

from mwjax import benchmarks
from mwjax.config import EnvConfig
from mwjax.tasks import get_task

Array = jax.Array


def set_variants(config: EnvConfig, bench: benchmarks.Benchmark) -> dict[str, np.ndarray]:
    """Every task's goal variants, `{task: (n, d)}`: the caller's, checked, or the set's own."""
    names = bench.tasks(config.split)
    if config.goal_variants is None:
        return benchmarks.goal_variants(bench, config.seed, config.split)
    return _given_variants(config.goal_variants, names)


def variant_count(config: EnvConfig, variants: Mapping[str, np.ndarray]) -> int:
    """How many of each task's variants the env visits (`variants_per_task`, checked)."""
    available = len(next(iter(variants.values())))
    n_variants = available if config.variants_per_task is None else config.variants_per_task
    if not isinstance(n_variants, int) or not 1 <= n_variants <= available:
        raise ValueError(f"variants_per_task must be an int in [1, {available}], got {n_variants!r}")
    return n_variants


def goal_pools(goal_sampling: str, envs_per_task: int, n_variants: int, n_tasks: int) -> tuple[Array, Array]:
    """Which goal variants each env may visit, `(num_envs, P)` padded, and how many.

    MT envs (`"on_reset"`) may draw any of their task's variants. ML envs (`"on_request"`) split
    them like the reference's ML envs: env i of a task owns variants i, i + E, i + 2E, ... (E
    envs per task); with more envs than variants, env i owns variant i mod the variant count."""
    if goal_sampling == "on_reset" or envs_per_task == 1:
        pools = [list(range(n_variants))] * envs_per_task
    else:
        pools = [list(range(i % n_variants, n_variants, envs_per_task)) for i in range(envs_per_task)]
    width = max(len(p) for p in pools)
    padded = np.array([p + [p[0]] * (width - len(p)) for p in pools], np.int32)
    sizes = np.array([len(p) for p in pools], np.int32)
    return jnp.asarray(np.tile(padded, (n_tasks, 1))), jnp.asarray(np.tile(sizes, n_tasks))


@dataclasses.dataclass(frozen=True, eq=False)
class GoalDraws:
    """The device side of goal sampling for one batch: every task's variants and every env's pool.

    `variants` is `(tasks, n, d)`, each task's `rand_vec`s zero-padded to the widest task's `d`;
    `pools` / `pool_sizes` are `goal_pools`'s (a sharded env gives each device its rows' pools)."""

    variants: Array
    task_ids: np.ndarray
    pools: Array
    pool_sizes: Array

    @classmethod
    def build(
        cls,
        variants: Mapping[str, np.ndarray],
        task_list: Sequence[str],
        task_ids: np.ndarray,
        goal_sampling: str,
        envs_per_task: int,
        n_variants: int,
    ) -> GoalDraws:
        width = max(v.shape[1] for v in variants.values())
        padded = [np.pad(variants[n], ((0, 0), (0, width - variants[n].shape[1]))) for n in task_list]
        pools, sizes = goal_pools(goal_sampling, envs_per_task, n_variants, len(task_list))
        return cls(jnp.asarray(np.stack(padded), jnp.float32), task_ids, pools, sizes)

    @property
    def count(self) -> int:
        """How many variants each task has (indices run over all of them, whatever the pools)."""
        return int(self.variants.shape[1])

    @property
    def width(self) -> int:
        """The length of a (padded) goal vector."""
        return int(self.variants.shape[2])

    def shuffled_pools(self, keys: Array) -> tuple[Array, Array]:
        """Each env's pool of goal variants in a fresh random order (padding last), and next keys."""
        split = jax.vmap(jax.random.split)(keys)
        size = self.pools.shape[1]
        noise = jax.vmap(lambda k: jax.random.uniform(k, (size,)))(split[:, 0])
        noise = jnp.where(jnp.arange(size) < self.pool_sizes[:, None], noise, 2.0)
        order = jnp.take_along_axis(self.pools, jnp.argsort(noise, axis=1), axis=1)
        return order, split[:, 1]

    def draw_cursor(self, keys: Array) -> tuple[Array, Array]:
        """A uniform position in each env's pool (the reference's MT `RandomTaskSelectWrapper`)."""
        split = jax.vmap(jax.random.split)(keys)
        cursor = jax.vmap(lambda k, n: jax.random.randint(k, (), 0, n))(split[:, 0], self.pool_sizes)
        return cursor.astype(jnp.int32), split[:, 1]

    def at(self, order: Array, cursor: Array) -> tuple[Array, Array]:
        """Each env's goal variant at `cursor` in its `order`, and that variant's vector."""
        variant = jnp.take_along_axis(order, cursor[:, None], axis=1)[:, 0]
        return variant, self.variants[jnp.asarray(self.task_ids), variant]


def _given_variants(given: Mapping[str, Any], names: Sequence[str]) -> dict[str, np.ndarray]:
    """Caller-chosen goal variants (`rand_vec`s), checked: one `(n, d)` array per task of the
    split, the same n for all, each row inside the task's random box."""
    if set(given) != set(names):
        raise ValueError(f"goal_variants must have exactly the tasks {sorted(names)}, got {sorted(given)}")
    variants = {}
    for name in names:
        spec = get_task(name)
        low, high = np.asarray(spec.random_low), np.asarray(spec.random_high)
        vecs = np.asarray(given[name], np.float64)
        if vecs.ndim != 2 or vecs.shape[1] != low.size or len(vecs) < 1:
            raise ValueError(f"goal_variants[{name!r}] must have shape (n, {low.size}), got {vecs.shape}")
        if not np.all(np.isfinite(vecs)) or np.any(vecs < low) or np.any(vecs > high):
            raise ValueError(f"goal_variants[{name!r}] has values outside the task's random box")
        variants[name] = vecs
    if len({len(v) for v in variants.values()}) > 1:
        raise ValueError("goal_variants must give every task the same number of variants")
    return variants
