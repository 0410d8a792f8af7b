"""The functional API: shapes, autoreset, truncation, determinism and bad input."""

from __future__ import annotations

import dataclasses
import functools
import json
import re
import warnings
from pathlib import Path

import jax
import jax.numpy as jnp
import mujoco
import numpy as np
import pytest
from mujoco import mjx
from mujoco.mjx.third_party.mujoco_warp import OverflowType
from states import assert_same_state

import mwjax
from mwjax import benchmarks, policies
from mwjax.benchmarks import MT10
from mwjax.env import staggered
from mwjax.models import MODELS_DIR, SCENES_DIR, constraint_rows, load_scene, scene_names
from mwjax.physics import DROPPED, PhysicsInstabilityWarning, PhysicsOverflowWarning, convex_candidates
from mwjax.tasks import TASKS as TASKS_REGISTRY

TASKS = ["reach-v3", "drawer-open-v3", "drawer-close-v3"]  # two share a scene
HORIZON = 3


@pytest.fixture(scope="module")
def env():
    return mwjax.make(TASKS, envs_per_task=2, seed=3, max_episode_steps=HORIZON)


@pytest.fixture(scope="module")
def compiled(env):
    return jax.jit(env.reset), jax.jit(env.step)


def rollout(env, compiled, key, steps):
    reset, step = compiled
    state = reset(key)
    states = [state]
    for i in range(steps):
        action = jax.random.uniform(jax.random.fold_in(key, i), (env.num_envs, 4), minval=-1.0, maxval=1.0)
        state = step(state, action)
        states.append(state)
    return states


@pytest.fixture(scope="module")
def episode(env, compiled):
    return rollout(env, compiled, jax.random.key(7), HORIZON + 1)


def test_layout(env):
    assert env.num_envs == 6
    assert env.task_names == ("reach-v3",) * 2 + ("drawer-open-v3",) * 2 + ("drawer-close-v3",) * 2
    assert [g.scene for g in env.physics.groups] == ["sawyer_reach_v3.xml", "sawyer_drawer.xml"]
    assert [g.size for g in env.physics.groups] == [2, 4]


def test_shapes_and_dtypes(env, episode):
    state = episode[1]
    assert state.obs.shape == (env.num_envs, 39) and state.obs.dtype == jnp.float32
    assert state.reward.shape == (env.num_envs,) and state.reward.dtype == jnp.float32
    assert state.terminated.dtype == jnp.bool_ and state.truncated.dtype == jnp.bool_
    assert state.info["success"].shape == (env.num_envs,) and state.info["success"].dtype == jnp.bool_
    for s in episode:
        assert np.isfinite(np.asarray(s.obs)).all() and np.isfinite(np.asarray(s.reward)).all()


def test_frame_stacking_and_goal(env, episode):
    reset, first = episode[0], episode[1]
    np.testing.assert_array_equal(reset.obs[:, 18:36], reset.obs[:, :18])
    np.testing.assert_allclose(first.obs[:, 18:36], reset.obs[:, :18], atol=1e-7)
    np.testing.assert_allclose(first.obs[:, 36:], np.clip(reset.target_pos, *goal_bounds(env)), atol=1e-7)


def goal_bounds(env):
    return np.asarray(env.sawyer.goal_low), np.asarray(env.sawyer.goal_high)


def test_truncation_and_autoreset(env, episode):
    before, at_horizon, after = episode[HORIZON - 1], episode[HORIZON], episode[HORIZON + 1]
    assert not np.asarray(before.truncated).any()
    assert np.asarray(at_horizon.truncated).all() and not np.asarray(at_horizon.terminated).any()
    # SAME_STEP autoreset: the returned obs starts the next episode, the last one is kept aside.
    np.testing.assert_array_equal(at_horizon.obs[:, :18], at_horizon.obs[:, 18:36])
    assert not np.allclose(at_horizon.info["final_obs"], at_horizon.obs)
    np.testing.assert_array_equal(at_horizon.steps, 0)
    assert not np.asarray(after.truncated).any()
    np.testing.assert_allclose(after.obs[:, 18:36], at_horizon.obs[:, :18], atol=1e-7)


def test_step_under_an_outer_vmap_is_each_instance_stepped_alone(env, compiled):
    """`jax.vmap(env.step)` (over seeds, say), in a step where one instance's episodes end and the
    other's go on: each instance is bit for bit the plain step of its own state."""
    reset, step = compiled
    # Stacking and indexing the states leaf by leaf in one program each (eagerly, each leaf's
    # shape would compile its own small program: about 4 s on a 2-core CPU).
    stack = jax.jit(lambda *trees: jax.tree.map(lambda *x: jnp.stack(x), *trees))
    take = jax.jit(lambda tree, i: jax.tree.map(lambda x: x[i], tree))
    states = stack(*(reset(jax.random.key(k)) for k in (5, 6)))
    states = dataclasses.replace(states, steps=states.steps.at[0].set(HORIZON - 1))
    actions = jax.random.uniform(jax.random.key(6), (2, env.num_envs, 4), minval=-1, maxval=1)
    stepped = jax.jit(jax.vmap(env.step))(states, actions)
    assert np.asarray(stepped.truncated[0]).all() and not np.asarray(stepped.truncated[1]).any()
    for i in range(2):
        alone = step(take(states, i), actions[i])
        assert_same_state(alone, take(stepped, i), f"instance {i}")


def test_default_horizon_is_reference():
    assert mwjax.config.MAX_EPISODE_STEPS == 500


def test_same_seed_same_rollout(env, compiled, episode):
    again = rollout(env, compiled, jax.random.key(7), HORIZON + 1)
    for a, b in zip(episode, again, strict=True):
        np.testing.assert_array_equal(a.obs, b.obs)
        np.testing.assert_array_equal(a.reward, b.reward)


def test_carried_state_steps_as_whole_data(env, episode):
    """The state carries each scene's `PhysicsState`, not its whole `mjx.Data`: stepping it must
    give what stepping the whole data on gives, bit for bit. A field that Warp's step reads
    before recomputing it, and that `PhysicsState` lacks, breaks this."""
    _assert_carried_state_steps_as_whole_data(env, episode[0], steps=4)


@pytest.mark.slow
def test_carried_state_steps_as_whole_data_in_every_mt50_scene():
    """The same over all 36 of MT50's scenes and 40 random steps: contacts, grasps and the
    colliders of every scene (~4 minutes on 2 cores)."""
    mt50 = mwjax.make(benchmarks.parse_tasks("MT50"), envs_per_task=2, seed=5)
    start = jax.jit(mt50.reset)(jax.random.key(3))
    _assert_carried_state_steps_as_whole_data(mt50, start, steps=40)


def _assert_carried_state_steps_as_whole_data(env, start, steps: int):
    physics = env.physics
    scene_steps = [jax.vmap(functools.partial(mjx.step, g.device_model)) for g in physics.groups]
    poses = [jax.vmap(functools.partial(mjx.kinematics, g.device_model)) for g in physics.groups]
    fields = ("qpos", "qvel", "qacc_warmstart", "xpos", "geom_xmat")

    def compared(group_states):
        return [{f: getattr(x, f) for f in fields} for x in group_states]

    @jax.jit
    def whole(state, actions):
        def one(datas, action):
            datas = list(env.apply_action(datas, action))
            for g, step in enumerate(scene_steps):
                n = physics.config.substeps
                datas[g] = poses[g](jax.lax.fori_loop(0, n, lambda _, d, step=step: step(d), datas[g]))
            return tuple(datas), compared(datas)

        datas = tuple(physics.data(g, s) for g, s in enumerate(state.physics))
        return jax.lax.scan(one, datas, actions)[1]

    @jax.jit
    def carried(state, actions):
        def one(states, action):
            states = physics.step(env.apply_action(states, action))
            return states, compared(states)

        return jax.lax.scan(one, state.physics, actions)[1]

    actions = jax.random.uniform(jax.random.key(11), (steps, env.num_envs, 4), minval=-1.0, maxval=1.0)
    expected, got = whole(start, actions), carried(start, actions)
    for group, data, state in zip(physics.groups, expected, got, strict=True):
        for field in fields:
            np.testing.assert_array_equal(data[field], state[field], err_msg=f"{group.scene} {field}")
    assert np.abs(np.asarray(expected[0]["qvel"][-1])).max() > 0  # the physics did move


def test_different_keys_draw_different_goals(env, compiled):
    reset, _ = compiled
    a, b = reset(jax.random.key(0)), reset(jax.random.key(1))
    assert not np.allclose(a.target_pos, b.target_pos)
    # every env draws its own variant: the two envs of a task differ
    assert not np.allclose(a.target_pos[0], a.target_pos[1])


def test_goal_hidden_when_partially_observable():
    env = mwjax.make(["reach-v3"], envs_per_task=2, partially_observable=True)
    state = jax.jit(env.reset)(jax.random.key(0))
    np.testing.assert_array_equal(state.obs[:, 36:], 0.0)


def test_unknown_task():
    with pytest.raises(ValueError, match="unknown task 'reach-v9'"):
        mwjax.make(["reach-v9"])
    with pytest.raises(ValueError, match="unknown benchmark"):
        mwjax.make("MT11")


def test_bad_arguments():
    with pytest.raises(ValueError, match="envs_per_task"):
        mwjax.make("MT10", envs_per_task=0)
    with pytest.raises(ValueError, match="reward_version"):
        mwjax.make("MT10", reward_version="v3")
    with pytest.raises(ValueError, match="duplicate"):
        mwjax.make(["reach-v3", "reach-v3"])
    with pytest.raises(ValueError, match="not a positive multiple of the 10 tasks"):
        mwjax.make("MT10", num_envs=25)
    with pytest.raises(ValueError, match="box_box_collider"):
        mwjax.PhysicsConfig(box_box_collider="gjk")
    with pytest.raises(ValueError, match="unknown graph_mode 'cuda'"):
        mwjax.PhysicsConfig(graph_mode="cuda")
    if jax.default_backend() == "cpu":
        with pytest.raises(ValueError, match="'warp_staged_ex' captures CUDA graphs and needs a GPU"):
            mwjax.make("MT1:reach-v3", physics=mwjax.PhysicsConfig(graph_mode="warp_staged_ex"))
    for rows in (0, "per_env"):
        with pytest.raises(ValueError, match="constraints_per_env"):
            mwjax.PhysicsConfig(constraints_per_env=rows)
    with pytest.raises(ValueError, match="no recorded constraint rows"):
        constraint_rows("sawyer_unknown.xml")
    for pairs in (0, 65, "per_env"):
        with pytest.raises(ValueError, match="ccd_pairs_per_env"):
            mwjax.PhysicsConfig(ccd_pairs_per_env=pairs)
    for name, value in [("contacts_per_env", 0), ("substeps", 0), ("iterations", -1), ("ls_iterations", 2.5)]:
        with pytest.raises(ValueError, match=f"{name} must be a positive int"):
            mwjax.PhysicsConfig(**{name: value})
    assert mwjax.PhysicsConfig(iterations=10, ls_iterations=None).iterations == 10


def test_constraint_buffers_hold_twice_what_mujoco_c_reaches_in_each_scene(env):
    table = json.loads((MODELS_DIR / "constraint_rows.json").read_text())["scenes"]
    by_scene: dict[str, set[str]] = {}
    for name, spec in TASKS_REGISTRY.items():
        by_scene.setdefault(spec.scene, set()).add(name)
    assert {scene: set(entry["tasks"]) for scene, entry in table.items()} == by_scene
    for scene, entry in table.items():
        rows = constraint_rows(scene)
        assert rows >= 2 * entry["max_rows"] and rows >= 128 and rows % 32 == 0
    for group in env.physics.groups:
        assert env.physics.constraint_rows(group.scene) == constraint_rows(group.scene)
    fixed = env.replace(physics=mwjax.PhysicsConfig(constraints_per_env=512))
    assert {fixed.physics.constraint_rows(g.scene) for g in fixed.physics.groups} == {512}


def test_staggered_episodes_end_where_their_counters_put_them(env, compiled, episode):
    start = episode[0]
    state = staggered(start, HORIZON, jax.random.key(5))
    counters = np.asarray(state.steps)
    assert state.steps.dtype == start.steps.dtype and ((counters >= 0) & (counters < HORIZON)).all()
    assert len(set(counters.tolist())) > 1  # spread, not one shared offset
    np.testing.assert_array_equal(np.asarray(state.obs), np.asarray(start.obs))  # nothing else moves
    stepped = compiled[1](state, jnp.zeros((env.num_envs, 4)))
    np.testing.assert_array_equal(np.asarray(stepped.truncated), counters == HORIZON - 1)


def test_replace_reuses_the_built_physics_only_for_settings_read_at_trace_time(env):
    """`replace(reward_version=...)` (and episode length, autoreset, termination) shares the
    built physics and goals and leaves the original as it was; test_parity's V1 rewards, computed
    by such a replaced env, check that it steps by its own settings."""
    v1 = env.replace(reward_version="v1", max_episode_steps=HORIZON + 1)
    assert v1.physics is env.physics and v1.goals is env.goals
    assert (v1.reward_version, v1.max_episode_steps, v1.config.reward_version) == ("v1", HORIZON + 1, "v1")
    assert (env.reward_version, env.max_episode_steps, env.config.reward_version) == ("v2", HORIZON, "v2")
    assert env.replace(envs_per_task=1).physics is not env.physics


def test_convex_collider_slots_hold_every_candidate_pair_and_a_shortfall_is_reported():
    """Each env gets a slot for every geom pair of its scene's busiest convex type pair (so no env
    can run out), never fewer than twice what MuJoCo C had in contact; one slot overflows."""
    table = json.loads((MODELS_DIR / "constraint_rows.json").read_text())["scenes"]
    busiest = max(table, key=lambda scene: table[scene]["max_ccd_pairs"])
    task = "button-press-topdown-v3"
    assert TASKS_REGISTRY[task].scene == busiest
    env = mwjax.make([task], envs_per_task=1)
    (group,) = env.physics.groups
    candidates = convex_candidates(group.device_model, "box_box")
    assert env.physics.ccd_pairs(busiest) == min(candidates, 64)
    assert candidates >= 2 * table[busiest]["max_ccd_pairs"]
    expert = jax.vmap(policies.expert(task))
    for slots, overflows in (("per_scene", False), (1, True)):
        env = mwjax.make(
            [task], envs_per_task=2, seed=0, physics=mwjax.PhysicsConfig(ccd_pairs_per_env=slots)
        )
        step = jax.jit(lambda state, env=env: env.step(state, jnp.clip(expert(state.obs), -1.0, 1.0)))
        # Jitted: eagerly, each of the reset's operations would compile a program of its own.
        state = jax.jit(env.reset)(jax.random.key(0))
        flags = np.zeros(env.num_envs, np.int32)
        for _ in range(80):  # the expert reaches the button and presses it down
            state = step(state)
            flags |= np.asarray(state.info["physics_overflow"])
        assert bool(state.info["success"].any())
        np.testing.assert_array_equal(flags, np.asarray(env.physics.overflow(state.physics)) | flags)
        assert bool((flags & int(OverflowType.CCD)).any()) == overflows, (slots, flags)
        assert not (flags & int(DROPPED & ~OverflowType.CCD)).any(), (slots, flags)


def test_an_outer_vmap_gives_every_instance_its_own_contact_buffers():
    """Rollouts vmapped over keys (as over seeds) step every instance in one Warp batch whose
    buffers hold all of them: with one contact slot per env (all pick-place's resting object
    needs), no instance overflows and each is the rollout it would be alone."""
    env = mwjax.make(["pick-place-v3"], envs_per_task=2, physics=mwjax.PhysicsConfig(contacts_per_env=1))

    def rollout(key: jax.Array) -> tuple[jax.Array, jax.Array]:
        def step(state: mwjax.State, key: jax.Array) -> tuple[mwjax.State, jax.Array]:
            state = env.step(state, jax.random.uniform(key, (env.num_envs, 4), minval=-1.0, maxval=1.0))
            return state, state.info["physics_overflow"]

        state, flags = jax.lax.scan(step, env.reset(key), jax.random.split(key, 20))
        return state.obs, flags

    keys = jax.random.split(jax.random.key(1), 3)
    obs, flags = jax.jit(jax.vmap(rollout))(keys)
    assert not np.asarray(flags).any()
    for i, key in enumerate(keys):
        obs_alone, flags_alone = jax.jit(rollout)(key)
        assert not np.asarray(flags_alone).any()
        np.testing.assert_allclose(obs[i], obs_alone, atol=1e-5)


def test_physics_overflow_is_reported_per_env_and_step(capfd):
    """A constraint buffer too small for the hand's weld (6 rows) raises NEFC in every env at every
    step, counts the rows it needed, and warns once in Python (Warp's in-kernel printing is off);
    the default buffers raise nothing and need fewer rows than they have."""
    for rows, expected in ((4, int(OverflowType.NEFC)), ("per_scene", 0)):
        env = mwjax.make(["reach-v3"], envs_per_task=2, physics=mwjax.PhysicsConfig(constraints_per_env=rows))
        state = jax.jit(env.reset)(jax.random.key(0))
        assert state.info["physics_overflow"].dtype == jnp.int32
        step = jax.jit(env.step)
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            for _ in range(2):
                state = step(state, jnp.zeros((env.num_envs, 4)))
                flags = np.asarray(state.info["physics_overflow"])
                np.testing.assert_array_equal(flags & int(DROPPED), expected)
            jax.effects_barrier()
        overflow = [w for w in caught if issubclass(w.category, PhysicsOverflowWarning)]
        needed = np.asarray(env.physics.constraint_rows_needed(state.physics))
        allocated = env.physics.constraint_rows(env.physics.groups[0].scene)
        if expected:
            assert len(overflow) == 1, [str(w.message) for w in caught]
            assert "constraints_per_env" in str(overflow[0].message)
            assert np.all(needed > allocated)
        else:
            assert not overflow
            assert np.all((needed >= 6) & (needed <= allocated))
    assert "overflow" not in capfd.readouterr().out


def test_diverged_physics_is_reset_as_mujoco_c_resets_it(env, compiled, episode, tmp_path, monkeypatch):
    """An env whose qvel holds a NaN, and one whose qpos holds a value past `mjMAXVAL`, are reset
    to the model's defaults as MuJoCo C's `mj_step` resets them (its automatic reset, counted
    in `mjWARN_BADQVEL`/`mjWARN_BADQPOS`), flagged in `info["physics_reset"]` with one
    `PhysicsInstabilityWarning`; no NaN comes out, and the other envs step as if nothing happened."""
    _, step = compiled
    start = episode[1]
    physics = list(start.physics)
    nan_row, huge_row = 1, 0  # reach's second env (group 0), drawer-open's first (group 1)
    physics[0] = physics[0].replace(qvel=physics[0].qvel.at[nan_row, 2].set(jnp.nan))
    physics[1] = physics[1].replace(qpos=physics[1].qpos.at[huge_row, 0].set(1e11))
    broken = dataclasses.replace(start, physics=tuple(physics))
    action = jax.random.uniform(jax.random.key(5), (env.num_envs, 4), minval=-1.0, maxval=1.0)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        stepped = step(broken, action)
        jax.effects_barrier()
    assert [w for w in caught if issubclass(w.category, PhysicsInstabilityWarning)]
    expected_reset = np.zeros(env.num_envs, bool)
    expected_reset[[nan_row, 2 + huge_row]] = True
    np.testing.assert_array_equal(stepped.info["physics_reset"], expected_reset)
    assert np.isfinite(np.asarray(stepped.obs)).all() and np.isfinite(np.asarray(stepped.reward)).all()

    healthy = step(start, action)
    for row in np.flatnonzero(~expected_reset):
        np.testing.assert_array_equal(stepped.obs[row], healthy.obs[row])

    # MuJoCo C from the broken state: it resets (and counts it), then steps from its reset data.
    monkeypatch.chdir(tmp_path)  # where C's warning writes its MUJOCO_LOG.TXT
    applied = env.apply_action(broken.physics, action)
    rows = {0: (nan_row, mujoco.mjtWarning.mjWARN_BADQVEL), 1: (huge_row, mujoco.mjtWarning.mjWARN_BADQPOS)}
    reset_by_c = list(applied)
    for g, (row, warning) in rows.items():
        model = env.physics.groups[g].model
        data, fresh = mujoco.MjData(model), mujoco.MjData(model)
        for name in ("qpos", "qvel", "ctrl", "mocap_pos", "mocap_quat"):
            getattr(data, name)[:] = np.asarray(getattr(applied[g], name)[row], np.float64)
        mujoco.mj_step(model, data, nstep=env.physics.config.substeps)
        assert data.warning[warning].number == 1
        mujoco.mj_step(model, fresh, nstep=env.physics.config.substeps)
        np.testing.assert_array_equal(data.qpos, fresh.qpos)  # C stepped on from mj_resetData's data
        # mwjax's other mocap bodies are the reference's fixed bodies that its reset moved by
        # editing the model, which `mj_resetData` keeps: only the hand's mocap (0) comes from C.
        defaults = mujoco.MjData(model)
        fields = {name: (row,) for name in ("qpos", "qvel", "ctrl", "qacc_warmstart", "time")}
        fields.update(mocap_pos=(row, 0), mocap_quat=(row, 0))
        reset_by_c[g] = reset_by_c[g].replace(
            **{
                name: getattr(reset_by_c[g], name).at[at].set(np.asarray(getattr(defaults, name))[at[1:]])
                for name, at in fields.items()
            }
        )
    # mwjax's reset row steps exactly as mwjax stepping C's reset data.
    expected = jax.jit(env.physics.step)(tuple(reset_by_c))
    for g, (row, _) in rows.items():
        for name in ("qpos", "qvel", "xpos"):
            got, want = getattr(stepped.physics[g], name)[row], getattr(expected[g], name)[row]
            np.testing.assert_array_equal(got, want, err_msg=name)


def test_an_eagerly_reset_state_feeds_a_jitted_step_that_compiles_once():
    """Eagerly, the Warp calls' outputs come back committed to the device and the rest not; a
    jitted step would compile for that mix and again for its own output. The state is placed as
    one, so the step compiles once."""
    env = mwjax.make(["reach-v3"], envs_per_task=1)
    state = env.reset(jax.random.key(0))
    assert {x.committed for x in jax.tree.leaves(state)} == {True}
    step = jax.jit(env.step)
    for _ in range(2):
        state = step(state, jnp.zeros((1, 4)))
    assert step._cache_size() == 1


def test_the_step_program_holds_no_python_callback_so_jax_can_cache_it():
    """JAX writes no program with a Python host callback to its persistent cache, so each process
    would compile such a step afresh; the overflow warning goes through a named FFI target."""
    env = mwjax.make(["reach-v3"], envs_per_task=1)
    state = jax.jit(env.reset)(jax.random.key(0))
    lowered = jax.jit(env.step).lower(state, jnp.zeros((1, 4)))
    text = lowered.as_text()
    assert "mwjax_physics_overflow" in text
    # The target this platform lowers a Python host callback to (its name differs between the
    # CPU and CUDA), read off a program that holds one, so that the check can fail.
    probe = jax.jit(lambda x: jax.debug.callback(print, x)).lower(1.0).as_text()
    callbacks = {t for t in re.findall(r"custom_call @([\w.]+)", probe) if "callback" in t}
    assert callbacks, probe
    assert not any(target in text for target in callbacks), callbacks


@pytest.mark.parametrize("scene", scene_names())
def test_the_device_scene_without_visual_meshes_steps_exactly_as_the_full_scene(scene):
    full, physics_only = load_scene(scene), load_scene(scene, visual_meshes=False)
    assert physics_only.nmeshvert < full.nmeshvert
    rng = np.random.default_rng(0)
    runs = [(model, mujoco.MjData(model)) for model in (full, physics_only)]
    for _ in range(60):
        hand, grip = rng.uniform(-0.01, 0.01, 3), rng.uniform(-1.0, 1.0)
        for model, data in runs:
            data.mocap_pos[0] += hand
            data.ctrl[:] = [grip, -grip]
            mujoco.mj_step(model, data, nstep=5)
        (_, a), (_, b) = runs
        assert a.ncon == b.ncon
        np.testing.assert_array_equal(a.qpos, b.qpos)
        np.testing.assert_array_equal(a.xpos, b.xpos)


@pytest.mark.parametrize("scene", scene_names())
def test_a_scene_names_its_asset_files_relative_to_itself_and_loads_them_as_mujoco_does(scene):
    """MJX-Warp embeds the model's sizes in every program, among them the length of its asset
    paths: absolute paths would make each install path's programs miss JAX's persistent cache."""
    ours = load_scene(scene)
    paths = [p.decode() for p in bytes(ours.paths).split(b"\0") if p]
    assert paths and not any(Path(p).is_absolute() for p in paths), paths
    theirs = mujoco.MjModel.from_xml_path(str(SCENES_DIR / scene))
    for field in ("mesh_vert", "mesh_face", "mesh_graph", "tex_data"):
        np.testing.assert_array_equal(getattr(ours, field), getattr(theirs, field))


def test_bad_actions(env, compiled, episode):
    _, step = compiled
    state = episode[0]
    with pytest.raises(ValueError, match="shape"):
        step(state, jnp.zeros((env.num_envs, 3)))
    with pytest.raises(ValueError, match="shape"):
        step(state, jnp.zeros((env.num_envs + 1, 4)))
    with pytest.raises(ValueError, match="floating"):
        step(state, jnp.zeros((env.num_envs, 4), jnp.int32))
    with pytest.raises(ValueError, match="NaN or inf"):
        env.step(state, jnp.full((env.num_envs, 4), jnp.nan))


def test_actions_as_nested_lists(env):
    """Lists work like arrays, also under jit (traced here, nothing compiled or run): a jitted
    call sees a list as a pytree of scalars, which used to fail as "shape None"."""
    state = jax.eval_shape(env.reset, jax.random.key(0))
    stepped = jax.eval_shape(env.step, state, [[0.5, 0.0, -0.5, 1.0]] * env.num_envs)
    assert stepped.obs.shape == (env.num_envs, 39)
    with pytest.raises(ValueError, match="floating"):
        jax.eval_shape(env.step, state, [[0, 0, 0, 1]] * env.num_envs)
    with pytest.raises(ValueError, match=r"shape \(6, 4\), got \(\)"):
        jax.eval_shape(env.step, state, 0.5)
    with pytest.raises(ValueError, match=r"a \(6, 4\) array, got str"):
        env.step(state, "left")


def test_nan_action_under_jit_is_a_flagged_noop(env, compiled, episode):
    _, step = compiled
    state = episode[0]
    action = jnp.zeros((env.num_envs, 4)).at[0, 1].set(jnp.nan)
    nan_state = step(state, action)
    zero_state = step(state, jnp.zeros((env.num_envs, 4)))
    assert np.asarray(nan_state.info["invalid_action"]).tolist() == [True] + [False] * (env.num_envs - 1)
    np.testing.assert_array_equal(nan_state.obs, zero_state.obs)
    assert np.isfinite(np.asarray(nan_state.obs)).all()


def test_mt10_task_order():
    assert mwjax.benchmarks.task_names("MT10") == MT10


def test_mt50_is_every_task():
    names = mwjax.benchmarks.task_names("MT50")
    assert len(names) == 50 and set(names) == set(TASKS_REGISTRY)


def test_given_goal_variants_replace_the_sets():
    tasks = ["reach-v3", "push-v3"]
    given = benchmarks.mt1_goal_variants(tasks, 7)
    env = mwjax.make(tasks, envs_per_task=2, seed=0, goal_variants=given)
    for task in tasks:
        np.testing.assert_array_equal(env.goal_variants[task], given[task])
    assert not np.array_equal(env.goal_variants["push-v3"], benchmarks.goal_variants(tasks, 0)["push-v3"])
    # The reset places each env's goal from its variant's rand_vec.
    state = jax.jit(env.reset_with_variants)(jnp.array([0, 1, 0, 1]))
    default = mwjax.make(tasks, envs_per_task=2, seed=0)
    other = jax.jit(default.reset_with_variants)(jnp.array([0, 1, 0, 1]))
    assert not np.allclose(state.obs[:, 36:], other.obs[:, 36:])
    with pytest.raises(ValueError, match="exactly the tasks"):
        mwjax.make(tasks, goal_variants={"reach-v3": given["reach-v3"]})
    with pytest.raises(ValueError, match="shape"):
        mwjax.make(tasks, goal_variants={t: v[:, :2] for t, v in given.items()})
    with pytest.raises(ValueError, match="random box"):
        mwjax.make(tasks, goal_variants={t: v + 10.0 for t, v in given.items()})
    with pytest.raises(ValueError, match="variants_per_task"):
        mwjax.make(tasks, goal_variants={t: v[:3] for t, v in given.items()}, variants_per_task=4)
