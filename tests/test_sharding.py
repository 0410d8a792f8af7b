"""A task set sharded over two devices (`mwjax.make(..., devices=...)`) against the unsharded env.

JAX fixes its device count when it starts, so `test_on_two_host_devices` runs this file's other
tests in a child pytest with `--xla_force_host_platform_device_count=2`; in a process with fewer
devices they skip. The child also caps XLA's CPU instruction set at AVX: with FMA (AVX2) XLA
fuses multiply-adds differently for different batch shapes, and a device's share of the batch
then computes a few rewards ~1 ulp away from the whole batch's (seen on drawer-close's grasp
term); the physics (Warp's own kernels) matches either way.
"""

from __future__ import annotations

import dataclasses
import os
import re
import sys
import time
from pathlib import Path

import children
import jax
import jax.numpy as jnp
import numpy as np
import pytest
from states import assert_same_state

import mwjax
from mwjax import evaluation, policies
from mwjax.wrappers.gymnasium import make_vector

CHILD = "MWJAX_SHARDING_CHILD"
# Two scenes, one of them shared by two tasks: the physics groups and the row order both matter.
TASKS = ["reach-v3", "drawer-open-v3", "drawer-close-v3"]
EPISODE = 5  # steps: the rollouts below autoreset inside

two_devices = pytest.mark.skipif(jax.device_count() < 2, reason="needs 2 devices (run by the test below)")


def _child(workdir: Path) -> tuple[list[str], dict[str, str]]:
    flags = os.environ.get("XLA_FLAGS", "")
    env = {
        **os.environ,
        CHILD: "1",
        "XLA_FLAGS": f"{flags} --xla_force_host_platform_device_count=2 --xla_cpu_max_isa=AVX".strip(),
        "JAX_PLATFORMS": "cpu",
    }
    return [sys.executable, "-m", "pytest", "-x", "-q", "-p", "no:cacheprovider", __file__], env


@pytest.mark.child.with_args(_child)
def test_on_two_host_devices(request):
    if os.environ.get(CHILD):
        pytest.skip("already the child")
    t0 = time.perf_counter()
    result, _ = children.result(request.node)
    tail = (result.stdout + result.stderr)[-6000:]
    assert result.returncode == 0, tail
    passed = re.search(r"(\d+) passed", result.stdout)
    assert passed and int(passed.group(1)) == 7, tail  # this file's other tests, none skipped
    print(f"waited for the child run: {time.perf_counter() - t0:.0f}s\n{result.stdout[-500:]}")


def _same(expected, sharded, unsharded_state):
    """Every leaf of `expected` (unsharded env) equals the sharded state's, bit for bit."""
    assert_same_state(expected, sharded.unsharded(unsharded_state))


def _split_over(array, devices, rows):
    if array.size == 0:  # e.g. a scene without a user-data field: nothing to place
        return
    shards = array.addressable_shards
    assert {s.device for s in shards} == set(devices)
    assert all(s.data.shape[0] == rows for s in shards)


@pytest.fixture(scope="module")
def pair():
    devices = jax.devices()[:2]
    kwargs = dict(envs_per_task=4, seed=3, max_episode_steps=EPISODE)
    return mwjax.make(TASKS, **kwargs), mwjax.make(TASKS, devices=devices, **kwargs)


@two_devices
def test_layout(pair):
    env, sharded = pair
    assert sharded.num_envs == env.num_envs == 12
    # Device 0 holds envs 0-1 of each task, device 1 envs 2-3.
    assert sharded.row_order.tolist() == [0, 1, 4, 5, 8, 9, 2, 3, 6, 7, 10, 11]
    assert sharded.task_names == tuple(np.asarray(env.task_names)[sharded.row_order])
    np.testing.assert_array_equal(sharded.task_one_hot(), env.task_one_hot()[sharded.row_order])
    assert sharded.task_rows("drawer-open-v3").tolist() == [2, 3, 8, 9]
    assert [g.size for g in sharded.physics.groups] == [2, 4]  # per device
    again = env.replace(devices=sharded.devices)
    assert type(again) is type(sharded) and again.row_order.tolist() == sharded.row_order.tolist()
    assert type(sharded.replace(devices=None)) is type(env)
    # A setting read at trace time shares the built env, as `Env.replace` does.
    terminating = sharded.replace(terminate_on_success=True)
    assert terminating.local.physics is sharded.local.physics and terminating.devices == sharded.devices
    assert terminating.terminate_on_success and terminating.local.terminate_on_success
    assert not sharded.terminate_on_success and not sharded.local.terminate_on_success


def _shard_map_inputs(jaxpr):
    for eqn in jaxpr.eqns:
        if eqn.primitive.name == "shard_map":
            yield from eqn.invars
        for param in eqn.params.values():
            inner = getattr(param, "jaxpr", None)
            if inner is not None:
                yield from _shard_map_inputs(getattr(inner, "jaxpr", inner))


@two_devices
def test_no_map_gets_a_zero_size_input(pair):
    """JAX 0.11's Shardy partitioner crashes compiling a `shard_map` with a zero-size input that
    its body uses (`mwjax.warp_empty_args`): the sharded step and reset must have none."""
    _, sharded = pair
    state = jax.jit(sharded.reset)(jax.random.key(0))
    for fn, args in ((sharded.reset, (jax.random.key(0),)), (sharded.step, (state, jnp.zeros((12, 4))))):
        inputs = list(_shard_map_inputs(jax.make_jaxpr(fn)(*args).jaxpr))
        assert inputs and all(np.prod(v.aval.shape) > 0 for v in inputs)


@two_devices
def test_sharded_rollout_is_the_unsharded_one_bit_for_bit(pair):
    env, sharded = pair
    devices = sharded.devices
    key = jax.random.key(11)
    expected, state = jax.jit(env.reset)(key), jax.jit(sharded.reset)(key)
    _same(expected, sharded, state)
    # The experts act on each row by its task, wherever the row lives.
    actions = np.asarray(policies.expert_policy(env)(None, expected.obs, None))
    sharded_actions = np.asarray(policies.expert_policy(sharded)(None, state.obs, None))
    np.testing.assert_array_equal(sharded_actions, actions[sharded.row_order])
    step, sharded_step = jax.jit(env.step), jax.jit(sharded.step)
    rng = np.random.default_rng(0)
    truncations = 0
    for _ in range(2 * EPISODE + 1):
        action = rng.uniform(-1.0, 1.0, (env.num_envs, 4)).astype(np.float32)
        expected = step(expected, jnp.asarray(action))
        state = sharded_step(state, jnp.asarray(action[sharded.row_order]))
        _same(expected, sharded, state)
        truncations += int(np.asarray(state.truncated).sum())
    assert truncations == 2 * env.num_envs  # two autoresets of every env
    # Every array of the state is split over both devices, half the rows each.
    for leaf in jax.tree.leaves(dataclasses.replace(state, physics=())):
        _split_over(leaf, devices, env.num_envs // 2)
    for group, data in zip(sharded.physics.groups, state.physics, strict=True):
        for leaf in jax.tree.leaves(data):
            _split_over(leaf, devices, group.size)
    for task in TASKS:
        kin, sharded_kin = env.kinematics(expected, task), sharded.kinematics(state, task)
        for a, b in zip(kin, sharded_kin, strict=True):
            np.testing.assert_array_equal(np.asarray(a), np.asarray(b))


@two_devices
def test_ml_goal_pools_follow_the_rows():
    """With per-env goal pools (ML sampling: env e of a task owns variants e, e + 4, ...), each
    row keeps its unsharded row's pool, through resets and `sample_goals`."""
    devices = jax.devices()[:2]
    kwargs = dict(envs_per_task=4, seed=5, goal_sampling="on_request", max_episode_steps=EPISODE)
    env, sharded = mwjax.make(TASKS, **kwargs), mwjax.make(TASKS, devices=devices, **kwargs)
    expected, state = jax.jit(env.reset)(jax.random.key(2)), jax.jit(sharded.reset)(jax.random.key(2))
    _same(expected, sharded, state)
    sample, sharded_sample = jax.jit(env.sample_goals), jax.jit(sharded.sample_goals)
    for _ in range(4):  # 13 or 12 goals each: enough to see different pools
        expected, state = sample(expected), sharded_sample(state)
        _same(expected, sharded, state)
    assert len(set(np.asarray(expected.variant).tolist())) > 4


@two_devices
def test_what_cannot_be_sharded_says_why():
    devices = jax.devices()[:2]
    with pytest.raises(ValueError, match="not a multiple of the 2 devices"):
        mwjax.make(["reach-v3"], envs_per_task=3, devices=devices)
    with pytest.raises(ValueError, match="distinct"):
        mwjax.make(["reach-v3"], envs_per_task=2, devices=[devices[0], devices[0]])
    staged = mwjax.PhysicsConfig(graph_mode="warp_staged")
    with pytest.raises(ValueError, match="one CUDA graph per traced Warp call"):
        mwjax.make(["reach-v3"], envs_per_task=2, devices=devices, physics=staged)


@two_devices
def test_gymnasium_adapter_and_evaluation_take_devices():
    devices = jax.devices()[:2]
    envs = make_vector("MT1", task="reach-v3", envs_per_task=4, max_episode_steps=EPISODE, devices=devices)
    obs, _ = envs.reset(seed=1)
    assert obs.shape == (4, 39)
    for _ in range(EPISODE):
        obs, reward, terminated, truncated, info = envs.step(np.zeros((4, 4), np.float32))
    assert truncated.all() and "final_obs" in info
    _split_over(envs.unwrapped.state.obs, devices, 2)

    def policy(params, obs, key):
        return jnp.clip(obs[:, :4] * params, -1.0, 1.0)

    core = envs.unwrapped.env
    # 3 episodes per task: the sharded evaluation runs 4 (a multiple of 2) and counts the first 3,
    # those of the unsharded evaluation of 4.
    result = jax.jit(evaluation.evaluator(core, policy, num_episodes=3))(0.5, jax.random.key(0))
    expected = jax.jit(evaluation.evaluator(core.replace(devices=None), policy, num_episodes=4))(
        0.5, jax.random.key(0)
    )
    assert result.returns.shape == (1, 3)
    np.testing.assert_array_equal(np.asarray(expected.success)[:, :3], np.asarray(result.success))
    np.testing.assert_array_equal(np.asarray(expected.lengths)[:, :3], np.asarray(result.lengths))
    # Not bit for bit: with autoreset off, XLA fuses the unsharded step's rewards into the
    # returns' sum and compiles them differently (the same scan with autoreset on matches).
    np.testing.assert_allclose(np.asarray(expected.returns)[:, :3], np.asarray(result.returns), rtol=1e-6)

    class Agent:
        def eval_action(self, observations):
            return np.zeros((len(observations), 4), np.float32)

        def reset(self, env_mask):
            pass

    mean_success, mean_return, rates, episodic = evaluation.evaluation(Agent(), envs, num_episodes=3)
    assert list(rates) == ["reach-v3"] and len(episodic["reach-v3"]) == 3
    assert np.isfinite(mean_return)


@two_devices
def test_data_parallel_ppo_keeps_one_policy_over_the_devices():
    """`train_mt_ppo.py --devices 2`: each device rolls out its envs, the gradients and the
    statistics are averaged over both, and the replicated parameters stay equal on each."""
    from examples import train_mt_ppo as ppo

    stats = ppo.RunningStats.zeros((3,))
    batch = jax.random.normal(jax.random.key(0), (4, 6, 3)) * jnp.arange(1.0, 4.0) + 2.0
    mesh = jax.sharding.Mesh(np.array(jax.devices()[:2]), ("d",))
    merge = jax.shard_map(
        lambda b: stats.merge(b, (0, 1), "d"),
        mesh=mesh,
        in_specs=jax.sharding.PartitionSpec(None, "d"),
        out_specs=jax.sharding.PartitionSpec(),
    )
    for a, b in zip(stats.merge(batch, (0, 1)), merge(batch), strict=True):
        np.testing.assert_allclose(np.asarray(a), np.asarray(b), rtol=1e-5)

    config = ppo.Config(
        task_set=("reach-v3", "push-v3"),
        envs_per_task=4,
        unroll=6,
        minibatches=2,
        epochs=2,
        max_episode_steps=10,
        architecture="multi-head",
        devices=2,
    )
    trainer = ppo.Trainer(config)
    carry = trainer.init(jax.random.key(0))
    carry, metrics = trainer.train_chunk(carry, 2)
    # Every env (on either device) ended one episode; the statistics saw both devices' rows.
    np.testing.assert_array_equal(metrics.episodes, [config.envs_per_task] * 2)
    assert float(carry.norm.obs.count) == 2 * config.unroll * trainer.env.num_envs
    assert np.isfinite(metrics.loss)
    for leaf in jax.tree.leaves(carry.params):
        shards = [np.asarray(s.data) for s in leaf.addressable_shards]
        assert len(shards) == 2 and np.array_equal(shards[0], shards[1])
    _split_over(carry.env_state.obs, trainer.env.devices, trainer.env.num_envs // 2)
