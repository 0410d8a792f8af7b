"""`PhysicsConfig(concurrent_scenes=...)`: an env step's scenes as one FFI call
(`mwjax.scene_streams`), the default on one GPU. On the CPU the call runs the scenes in turn, so a
rollout must equal the one with a call per scene bit for bit; the GPU's side-by-side streams are checked by
`tools/scene_streams_check.py` (results in benchmarks/results/profile/)."""

from __future__ import annotations

import ctypes
import functools
import gc
import inspect
import weakref
from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
import pytest
import warp as wp
from tool_scripts import load_tool

import mwjax
from mwjax import determinism, scene_streams
from mwjax import physics as physics_module
from mwjax.benchmarks import task_names
from mwjax.physics import runs_scenes_together
from mwjax.tasks import TASKS as TASK_SPECS

TASKS = ["pick-place-v3", "reach-v3"]


@pytest.fixture(autouse=True)
def _default_unset(monkeypatch):
    """The tests see the shipped default, whatever the caller's `MWJAX_CONCURRENT_SCENES`; those
    of the variable set it themselves."""
    monkeypatch.delenv("MWJAX_CONCURRENT_SCENES", raising=False)


def _seeded(env: mwjax.Env, seeds: int | None) -> tuple[Any, Any, jax.Array, tuple[int, ...]]:
    """`env`'s reset and step, its reset keys and the batch shape of an action: one batch, or
    `seeds` instances under an outer `vmap` (the training examples' seeds)."""
    if seeds is None:
        return env.reset, env.step, jax.random.key(0), (env.num_envs,)
    keys = jax.random.split(jax.random.key(0), seeds)
    return jax.vmap(env.reset), jax.vmap(env.step), keys, (seeds, env.num_envs)


@functools.cache
def _autoreset_rollout(together: bool, seeds: int | None, per_call: int | None) -> tuple[np.ndarray, ...]:
    """The reset's and 4 steps' outputs of a 2-step-episode rollout (cached: in turn,
    `scenes_per_call` goes unused, so the cases that differ only in it share one in-turn rollout)."""
    physics = mwjax.PhysicsConfig(concurrent_scenes=together, scenes_per_call=per_call)
    env = mwjax.make(TASKS, envs_per_task=2, seed=4, physics=physics, max_episode_steps=2)
    reset, step, keys, batch = _seeded(env, seeds)
    actions = jax.random.uniform(jax.random.key(1), (4, *batch, 4), minval=-1, maxval=1)
    state, step = jax.jit(reset)(keys), jax.jit(step)
    out = [np.asarray(x) for x in (state.obs, *jax.tree.leaves(state.physics))]  # the reset's poses
    for action in actions:  # the episodes end at the second step and restart
        state = step(state, action)
        out += [np.asarray(x) for x in (state.obs, state.reward, state.info["physics_overflow"])]
        out += [np.asarray(x) for x in jax.tree.leaves(state.physics)]
    return tuple(out)


@pytest.mark.skipif(jax.default_backend() != "cpu", reason="bit-for-bit equality holds on the CPU")
@pytest.mark.parametrize(
    ("seeds", "per_call"),
    [(None, 10), (2, 10), (None, 1)],
    ids=["one-batch", "vmapped-seeds", "1-per-call"],
)
def test_together_steps_equal_separate_calls_through_an_autoreset(seeds: int | None, per_call: int | None):
    """Also under an outer `vmap` (the training examples' seeds), whose rows the physics merges,
    and with a round split into calls (`scenes_per_call`)."""
    together, in_turn = _autoreset_rollout(True, seeds, per_call), _autoreset_rollout(False, seeds, None)
    for ours, theirs in zip(together, in_turn, strict=True):
        np.testing.assert_array_equal(ours, theirs)


def test_envs_with_and_without_scenes_side_by_side_share_their_settled_states():
    """The per-goal settling steps one scene alone, so both kinds of env start their episodes
    from the same settled states; on a GPU, where that settling differs in the last bits per
    computation and is chaotic for a few tasks, `tools/scene_streams_check.py` so compares the
    steps alone."""
    configs = [
        mwjax.PhysicsConfig(concurrent_scenes=False),
        mwjax.PhysicsConfig(concurrent_scenes=True),
        mwjax.PhysicsConfig(concurrent_scenes=True, scenes_per_call=1),
    ]
    made = [mwjax.make(["disassemble-v3"], envs_per_task=1, physics=physics) for physics in configs]
    (in_turn,), (together,), (split,) = ([r for r in env._rows if r.spec.settle_per_goal] for env in made)
    assert together.settled_per_variant is in_turn.settled_per_variant
    assert split.settled_per_variant is in_turn.settled_per_variant


def _rollouts_in_turn_twice_then_together(
    tasks: list[str], envs_per_task: int, seeds: int | None, steps: int = 60
) -> tuple[np.ndarray, np.ndarray, np.ndarray, tuple[str, ...]]:
    """Seeded random-action rollouts through autoresets, `(steps, *batch, obs + reward +
    overflow)`: scenes in turn, in turn again, then side by side; and the tasks in batch order."""
    names: list[tuple[str, ...]] = []

    def rollout(together: bool) -> np.ndarray:
        physics = mwjax.PhysicsConfig(concurrent_scenes=together)
        env = mwjax.make(tasks, envs_per_task=envs_per_task, seed=4, physics=physics, max_episode_steps=20)
        assert env.physics.concurrent_scenes is together
        names.append(env.task_list)
        reset, step, keys, batch = _seeded(env, seeds)
        actions = jax.random.uniform(jax.random.key(1), (steps, *batch, 4), minval=-1, maxval=1)

        def body(state: mwjax.State, action: jax.Array) -> tuple[mwjax.State, jax.Array]:
            state = step(state, action)
            overflow = (state.info["physics_overflow"] != 0)[..., None].astype(jnp.float32)
            return state, jnp.concatenate([state.obs, state.reward[..., None], overflow], axis=-1)

        state = jax.jit(reset)(keys)
        return np.asarray(jax.jit(lambda s, a: jax.lax.scan(body, s, a)[1])(state, actions))

    return rollout(False), rollout(False), rollout(True), names[0]


@pytest.mark.gpu
@pytest.mark.parametrize("seeds", [None, 2], ids=["one-batch", "vmapped-seeds"])
def test_together_stays_as_close_to_in_turn_as_in_turn_to_itself_on_the_gpu(seeds: int | None):
    """On a GPU, Warp's atomics make two in-turn rollouts differ in their last bits, and a rollout
    amplifies that; the together rollout must stay about as close to the first as the second one
    does, with no env overflowing (`tools/scene_streams_check.py`'s comparison, smaller; also under
    the training examples' outer `vmap` of seeds). A form whose streams use buffers XLA has reused
    fails here: it crashes or departs far more."""
    first, second, together, _ = _rollouts_in_turn_twice_then_together(task_names("MT10"), 8, seeds)
    assert not first[..., -1].any() and not together[..., -1].any()  # no env overflowed
    assert np.isfinite(together).all()
    assert np.abs(together - first).max() <= 10 * max(np.abs(second - first).max(), 1e-4)


@pytest.mark.gpu
def test_staged_scene_calls_replay_with_each_calls_inputs_on_the_gpu():
    """With the scenes side by side in Warp's staged mode (the Gymnasium adapter's), each scene
    call is captured once against staging buffers and replayed with every later call's inputs
    copied in: steps from new states, at new addresses, must be those of the side-by-side step in
    Warp's own mode from the same states (to the atomics' last bits), through autoresets too (a
    staged call copies only the live state, the rest stays from its last call)."""
    tasks = ["pick-place-v3", "reach-v3", "door-open-v3"]
    modes = (None, "warp_staged_ex")
    configs = [mwjax.PhysicsConfig(concurrent_scenes=True, graph_mode=mode) for mode in modes]
    envs = [mwjax.make(tasks, envs_per_task=16, physics=physics, max_episode_steps=4) for physics in configs]
    assert all(env.physics.concurrent_scenes for env in envs)
    steps = [jax.jit(env.step) for env in envs]
    state = jax.jit(envs[0].reset)(jax.random.key(0))
    for key in jax.random.split(jax.random.key(1), 10):
        action = jax.random.uniform(key, (envs[0].num_envs, 4), minval=-1.0, maxval=1.0)
        expected, replayed = (step(state, action) for step in steps)
        np.testing.assert_allclose(np.asarray(replayed.obs), np.asarray(expected.obs), atol=1e-4)
        np.testing.assert_allclose(np.asarray(replayed.reward), np.asarray(expected.reward), atol=1e-3)
        state = expected


@pytest.mark.gpu
def test_the_adapter_steps_with_its_scenes_side_by_side_on_the_gpu():
    """The Gymnasium adapter asked for its scenes side by side (its staged mode, donated state):
    it steps through an autoreset with finite observations, keeping one staged capture per
    scene call, and a reset with the same seed starts over."""
    from mwjax.wrappers.gymnasium import make_vector

    physics = mwjax.PhysicsConfig(concurrent_scenes=True)
    envs = make_vector(["pick-place-v3", "reach-v3"], envs_per_task=4, physics=physics, max_episode_steps=5)
    assert envs.unwrapped.env.physics.concurrent_scenes
    first, _ = envs.reset(seed=0)
    rng = np.random.default_rng(0)
    for _ in range(8):
        obs, reward, *_ = envs.step(rng.uniform(-1, 1, (8, 4)).astype(np.float32))
        assert np.all(np.isfinite(obs)) and np.all(np.isfinite(reward))
    per_call = [stages for site in scene_streams._sites.values() for stages in site.stages]
    assert any(per_call) and all(len(stages) <= 1 for stages in per_call)  # one device: one capture
    assert all(stage.capture is not None for stages in per_call for stage in stages.values())
    np.testing.assert_allclose(envs.reset(seed=0)[0], first, atol=1e-5)


def _noop(
    a: wp.array(dtype=float),
    b: wp.array(dtype=float),
    e: wp.array(dtype=float),
    c: wp.array(dtype=float),
    d: wp.array(dtype=float),
) -> None:
    pass


def test_a_staged_scene_call_copies_what_warps_staged_mode_copies():
    """`_staged` moves a call's arrays onto staging buffers as Warp's staged modes do: the inputs
    named to be staged (and the in-out array) are copied in at every call, the others once; the
    outputs named to be staged are copied out at every call; an empty array stays as it is."""
    callable_ = wp.jax_callable(
        _noop,
        num_outputs=2,
        in_out_argnames=["c"],
        stage_in_argnames=["b", "c"],
        stage_out_argnames=["c"],
        graph_mode=wp.JaxCallableGraphMode.WARP_STAGED_EX,
    )
    args = [
        wp.array(np.arange(n, dtype=np.float32) + 10 * i, device="cpu") for i, n in enumerate([3, 4, 0, 5, 6])
    ]
    stage = scene_streams._staged(callable_, args)
    assert stage.args[2] is args[2]  # empty: nothing to stage
    for i in (0, 1, 3, 4):
        assert stage.args[i].ptr != args[i].ptr and stage.args[i].shape == args[i].shape
    # Copied once, here: the input not named for staging (a) and the output not named (d).
    np.testing.assert_array_equal(stage.args[0].numpy(), args[0].numpy())
    np.testing.assert_array_equal(stage.args[4].numpy(), args[4].numpy())
    assert stage.copy_in.index.tolist() == [1, 3]  # b and c, by their FFI input numbers
    assert stage.copy_in.staging.tolist() == [stage.args[1].ptr, stage.args[3].ptr]
    assert stage.copy_in.sizes.tolist() == [16, 20]
    assert stage.copy_out.index.tolist() == [0]  # c, the first FFI output
    assert stage.copy_out.staging.tolist() == [stage.args[3].ptr] and stage.copy_out.sizes.tolist() == [20]


def test_a_staged_call_with_live_arguments_copies_only_those_at_every_call():
    """With `live`, a staged call copies only the live arguments at every call, among those Warp's
    staged mode would: a named input that is not live is copied once, when staged, and a named
    output that is not live is not copied out."""
    callable_ = wp.jax_callable(
        _noop,
        num_outputs=2,
        in_out_argnames=["c"],
        stage_in_argnames=["a", "b", "c"],
        stage_out_argnames=["c", "d"],
        graph_mode=wp.JaxCallableGraphMode.WARP_STAGED_EX,
    )
    args = [wp.array(np.arange(4, dtype=np.float32) + 10 * i, device="cpu") for i in range(5)]
    stage = scene_streams._staged(callable_, args, live=frozenset({"b", "c"}))
    assert stage.copy_in.index.tolist() == [1, 3]  # b and c; a was copied once
    np.testing.assert_array_equal(stage.args[0].numpy(), args[0].numpy())
    assert stage.copy_out.index.tolist() == [0]  # c; d is not live
    everything = scene_streams._staged(callable_, args)
    assert everything.copy_in.index.tolist() == [0, 1, 3] and everything.copy_out.index.tolist() == [0, 1]


def test_the_live_fields_of_a_physics_step_are_arguments_of_mjx_warps_step():
    """A live name that MJX-Warp does not use (a field renamed in a new version) would silently
    never be copied, and the staged step would run on a stale copy of that field."""
    from mujoco.mjx.warp import forward

    source = inspect.getsource(forward._step_jax_impl)
    assert physics_module._LIVE >= set(physics_module._FIELDS)
    missing = {name for name in physics_module._LIVE if f"'{name}'" not in source}
    assert missing <= set(physics_module._EMPTY_IN_METAWORLD)  # never arrays in Meta-World's scenes


@pytest.mark.parametrize("mode", ["warp_staged_ex", "warp_staged"])
def test_scenes_side_by_side_run_in_the_staged_modes_when_asked(mode: str):
    """Asked for, the scenes run side by side with a staged graph mode too (each scene call staged
    as Warp stages a call); left to the default, they do not."""
    assert runs_scenes_together(mwjax.PhysicsConfig(concurrent_scenes=True, graph_mode=mode), "gpu")
    assert not runs_scenes_together(mwjax.PhysicsConfig(graph_mode=mode), "gpu")
    assert physics_module._streams_capture(mwjax.PhysicsConfig(graph_mode=mode))
    assert not physics_module._streams_capture(mwjax.PhysicsConfig(graph_mode="none"))


@pytest.mark.gpu
def test_together_follows_in_turn_task_by_task_for_the_tasks_that_settle_per_goal_on_the_gpu():
    """The nine tasks whose settled reset state depends on the goal (chaotically for some), with
    MT50 tasks that are not in MT10: each task's together rollout stays within 10x its own in-turn
    noise (`tools/scene_streams_check.beyond_noise`'s rule), from shared settled states."""
    settling = [name for name, spec in TASK_SPECS.items() if spec.settle_per_goal]
    tasks = [*settling, "hammer-v3", "push-wall-v3", "coffee-pull-v3"]
    envs_per_task = 8
    first, second, together, order = _rollouts_in_turn_twice_then_together(tasks, envs_per_task, None)
    assert not first[..., -1].any() and not together[..., -1].any()  # no env overflowed
    check = load_tool("scene_streams_check")
    noise = check.max_diff_per_task(first, second, order, envs_per_task)
    apart = check.max_diff_per_task(first, together, order, envs_per_task)
    assert not check.beyond_noise(noise, apart), {task: (apart[task], noise[task]) for task in order}


def test_functions_without_warp_calls_run_as_they_are():
    fns = [lambda x: x * 2, lambda x: {"y": jnp.sin(x)}]
    args = [jnp.arange(3.0), jnp.ones(2)]
    out = jax.jit(lambda a, b: scene_streams.concurrently(fns, [a, b]))(*args)
    np.testing.assert_array_equal(out[0], np.arange(3.0) * 2)
    np.testing.assert_allclose(out[1]["y"], np.sin(np.ones(2)))


def test_traced_functions_are_named_without_printing_what_they_close_over():
    """A scene's function is a vmapped partial over its MJX model: JAX would name it by `str`,
    which prints every array of the model. The wrapper is kept per function, so that JAX's trace
    cache still finds a function traced before, and does not keep the function alive."""
    printed = []

    class Model:
        def __repr__(self) -> str:
            printed.append(True)
            return "Model()"

    fn = jax.vmap(functools.partial(lambda model, x: x * 2, Model()))
    out = jax.jit(lambda a, f=fn: scene_streams.concurrently([f], [a]))(jnp.arange(3.0))
    np.testing.assert_array_equal(out[0], np.arange(3.0) * 2)
    assert not printed
    assert scene_streams._traceable(fn) is scene_streams._traceable(fn)
    alive = weakref.ref(fn)
    del fn
    gc.collect()
    assert alive() is None


def test_a_warp_call_inside_a_loop_is_refused():
    env = mwjax.make(["reach-v3"], envs_per_task=1, seed=0)
    physics = env.physics
    data = physics.data(0, physics.make_data()[0])
    looped = lambda d: jax.lax.fori_loop(0, 2, lambda _, x: physics._substep[0](x), d)  # noqa: E731
    with pytest.raises(NotImplementedError, match="a Warp call inside"):
        jax.eval_shape(lambda d: scene_streams.concurrently([looped], [d]), data)


def _warp_calls(jaxpr: Any) -> list[Any]:
    """The Warp calls of `jaxpr`, nested calls included, in order."""
    calls = []
    for eqn in jaxpr.eqns:
        if scene_streams._is_warp_call(eqn):
            calls.append(eqn)
        for inner in scene_streams._held_jaxprs(eqn):
            calls += _warp_calls(inner)
    return calls


def _kinematics_calls(tasks: list[str], per_call: int | None = None) -> tuple[list[Any], list[Any]]:
    """The Warp calls of the scenes' kinematics traced one by one, and the FFI calls that
    `concurrently` makes of them."""
    physics = mwjax.make(tasks, envs_per_task=1).physics
    datas = [physics.data(g, state) for g, state in enumerate(physics.make_data())]
    fns = list(physics._kinematics)
    in_turn = jax.make_jaxpr(lambda ds: [f(d) for f, d in zip(fns, ds, strict=True)])(datas)
    jaxpr = jax.make_jaxpr(lambda ds: scene_streams.concurrently(fns, ds, per_call))(datas).jaxpr
    return _warp_calls(in_turn.jaxpr), [e for e in jaxpr.eqns if e.primitive.name == "ffi_call"]


def test_a_round_is_one_call_with_every_scenes_operands_and_outputs():
    """On a GPU the call returns only once every scene's stream is done, so one call per round
    holds all that the streams read and write: every scene's Warp operands and outputs, with each
    scene's aliases (a split into a launch and a join per scene failed on the GPU:
    docs/performance.md)."""
    separate, (call,) = _kinematics_calls(TASKS)
    assert call.params["target_name"] == scene_streams._TARGET
    assert len(separate) == len(TASKS)
    assert len(call.invars) == sum(len(e.invars) for e in separate)
    assert len(call.outvars) == sum(len(e.outvars) for e in separate)
    expected, i0, o0 = {}, 0, 0
    for e in separate:
        expected |= {i0 + i: o0 + o for i, o in dict(e.params["input_output_aliases"]).items()}
        i0, o0 = i0 + len(e.invars), o0 + len(e.outvars)
    assert expected and dict(call.params["input_output_aliases"]) == expected


def test_scenes_per_call_splits_a_round_into_calls_of_near_equal_size():
    """Three scenes at two per call: two calls, of one and two scenes, holding the scenes'
    operands in the order of the scenes."""
    separate, calls = _kinematics_calls([*TASKS, "push-v3"], per_call=2)
    assert [len(c.invars) for c in calls] == [
        len(separate[0].invars),
        len(separate[1].invars) + len(separate[2].invars),
    ]
    assert scene_streams._parts(list(range(9)), 4) == [[0, 1, 2], [3, 4, 5], [6, 7, 8]]
    # The default, 10: MT50's 36 scenes in four calls of 9, MT10's 8 in one.
    assert scene_streams._parts(list(range(36)), 10) == [list(range(k, k + 9)) for k in (0, 9, 18, 27)]
    assert scene_streams._parts(list(range(8)), 10) == [list(range(8))]
    assert scene_streams._parts([3, 5], 2) == [[3, 5]]


@pytest.mark.parametrize("value", [0, -1, 2.0, True, "2"])
def test_scenes_per_call_takes_a_positive_int_or_none(value: object):
    with pytest.raises(ValueError, match="scenes_per_call"):
        mwjax.PhysicsConfig(scenes_per_call=value)


@pytest.mark.parametrize("value", ["yes", 0, 1])
def test_concurrent_scenes_takes_a_bool_or_none(value: object):
    with pytest.raises(ValueError, match="concurrent_scenes"):
        mwjax.PhysicsConfig(concurrent_scenes=value)


@pytest.mark.parametrize(
    ("config", "platform", "devices", "together"),
    [
        ({}, "gpu", 1, True),  # the default where it was measured faster
        ({"graph_mode": "warp"}, "gpu", 1, True),
        ({}, "cpu", 1, False),  # the call would run the scenes in turn anyway
        ({}, "gpu", 2, False),  # not measured over several devices
        ({"graph_mode": "warp_staged_ex"}, "gpu", 1, False),  # the adapter's mode captures per call
        ({"graph_mode": "none"}, "gpu", 1, False),
        ({"concurrent_scenes": True}, "cpu", 2, True),  # asked for: as asked
        ({"concurrent_scenes": False}, "gpu", 1, False),
    ],
)
def test_scenes_run_together_by_default_on_one_gpu_with_warps_own_graphs(config, platform, devices, together):
    physics = mwjax.PhysicsConfig(**config)
    assert runs_scenes_together(physics, platform, devices) is together


@pytest.mark.parametrize(("value", "together"), [("0", False), ("1", True)])
def test_the_environment_variable_turns_the_default_off(monkeypatch, value, together):
    monkeypatch.setenv("MWJAX_CONCURRENT_SCENES", value)
    assert runs_scenes_together(mwjax.PhysicsConfig(), "gpu") is together
    assert runs_scenes_together(mwjax.PhysicsConfig(concurrent_scenes=True), "gpu")  # asked for: as asked


def test_the_deterministic_mode_runs_the_scenes_in_turn(monkeypatch):
    monkeypatch.setattr(determinism, "enabled", lambda: True)
    assert not runs_scenes_together(mwjax.PhysicsConfig(), "gpu")


def test_an_env_resolves_the_default_for_its_device():
    env = mwjax.make(["reach-v3"], envs_per_task=1)
    assert env.physics.concurrent_scenes == (jax.default_backend() == "gpu")


@pytest.mark.parametrize("stride_words", [6, 11, None])
def test_buffer_addresses_read_at_a_stride_or_one_by_one(stride_words: int | None):
    """XLA's buffer descriptors lie at one stride (read as a block) or anywhere (read one by one)."""
    count = 5
    words = (stride_words or 11) * count
    memory = (ctypes.c_uint64 * words)()
    stride = (stride_words or 11) * 8
    order = [0, 3, 1, 4, 2] if stride_words is None else range(count)  # uneven gaps
    structs = [ctypes.addressof(memory) + i * stride for i in order]
    data = [1000 + 8 * k for k in range(count)]
    for address, value in zip(structs, data, strict=True):
        ctypes.c_uint64.from_address(address + scene_streams._DATA_OFFSET).value = value
    pointers = (ctypes.c_uint64 * count)(*structs)
    found = scene_streams._data_pointers(ctypes.addressof(pointers), count)
    np.testing.assert_array_equal(found, data)
