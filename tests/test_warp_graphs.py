"""The opt-in bound on the CUDA graphs Warp keeps per MJX-Warp call site (`mwjax.warp_graphs`)."""

import collections
import os
import subprocess
import sys

import pytest

from mwjax import warp_call_ids, warp_graphs


def test_a_site_keeps_its_latest_buffer_sets():
    kept: collections.deque[int] = collections.deque()
    assert warp_graphs.admit(kept, 1, limit=1) == []
    assert warp_graphs.admit(kept, 1, limit=1) == []
    assert warp_graphs.admit(kept, 2, limit=1) == [1]
    assert list(kept) == [2]
    kept.clear()
    for key in (1, 2):
        assert warp_graphs.admit(kept, key, limit=2) == []
    assert warp_graphs.admit(kept, 1, limit=2) == []  # 1 is now the most recent
    assert warp_graphs.admit(kept, 3, limit=2) == [2]
    assert list(kept) == [1, 3]


def test_the_limit_is_read_from_the_environment(monkeypatch):
    monkeypatch.delenv("MWJAX_WARP_GRAPHS_PER_SITE", raising=False)
    assert warp_graphs.per_site() == 0  # Warp's own policy unless asked
    monkeypatch.setenv("MWJAX_WARP_GRAPHS_PER_SITE", "2")
    assert warp_graphs.per_site() == 2
    monkeypatch.setenv("MWJAX_WARP_GRAPHS_PER_SITE", "many")
    with pytest.raises(ValueError, match="MWJAX_WARP_GRAPHS_PER_SITE"):
        warp_graphs.per_site()


_PROBE = """
import jax
import mwjax
from mwjax import warp_graphs
env = mwjax.make("MT1:reach-v3", envs_per_task=64)
step = jax.jit(env.step)
state = jax.jit(env.reset)(jax.random.key(0))
action = jax.numpy.zeros((env.num_envs, 4))
state = jax.block_until_ready(step(state, action))
after_one = warp_graphs.kept_graphs()
for _ in range(4):
    state = jax.block_until_ready(step(state, action))
print(after_one[0], warp_graphs.kept_graphs()[0])
"""


@pytest.mark.gpu
def test_steps_from_states_at_new_addresses_keep_one_graph_per_site():
    """With `MWJAX_WARP_GRAPHS_PER_SITE=1` and no donation, every step's state lies at new
    addresses, so Warp captures each site again at every call; the graphs it keeps must stay at
    one set, not grow with the calls. In a child: the bound is process-wide."""
    env = dict(os.environ, MWJAX_WARP_GRAPHS_PER_SITE="1")
    out = subprocess.run([sys.executable, "-c", _PROBE], env=env, capture_output=True, text=True, check=True)
    after_one, after_five = map(int, out.stdout.split()[-2:])
    assert 0 < after_one == after_five


def test_the_adapter_bounds_the_sites_it_traces_and_only_those():
    """The Gymnasium adapter's jitted calls get one graph per Warp call site (`bounded`): every
    site its reset and step trace is marked; the same env's step traced outside it is not,
    though its calls are the same (their ids differ: `warp_call_ids.issued`)."""
    import jax

    import mwjax
    from mwjax.wrappers.gymnasium import make_vector

    def sites(issued: list) -> set[tuple[int, int]]:
        return {(id(c), call_id) for c, call_id in issued}

    with warp_call_ids.issued("") as adapter:
        envs = make_vector("MT1", task="reach-v3", num_envs=1, array_type="jax")
        envs.reset(seed=0)
        envs.step(jax.numpy.zeros((1, 4)))
    assert sites(adapter) and sites(adapter) <= warp_graphs.bounded_sites()

    with warp_call_ids.issued("") as outside:
        env = mwjax.make("MT1:reach-v3", envs_per_task=1)
        state = jax.jit(env.reset)(jax.random.key(0))
        jax.block_until_ready(jax.jit(env.step)(state, jax.numpy.zeros((1, 4))))
    assert sites(outside) and not sites(outside) & warp_graphs.bounded_sites()
    with pytest.raises(ValueError, match="at least 1"):
        with warp_graphs.bounded(0):
            pass


_ADAPTER_PROBE = """
import sys
import jax
from warp._src.jax import ffi
import mwjax
from mwjax import warp_graphs
from mwjax.wrappers.gymnasium import make_vector
mode = sys.argv[1] if len(sys.argv) > 1 else None
physics = None if mode is None else mwjax.PhysicsConfig(graph_mode=mode)
envs = make_vector("MT1", task="reach-v3", num_envs=64, array_type="jax", physics=physics)
envs.reset(seed=0)
actions = jax.numpy.zeros((envs.num_envs, 4))

def graphs():  # 'warp': the graphs Warp keeps per callable; staged: one per traced call site
    staged = [d for c in ffi._FFI_CALLABLE_REGISTRY.values() for d in c.call_descriptors.values()]
    return warp_graphs.kept_graphs()[0] + sum(getattr(d, "capture", None) is not None for d in staged)

jax.block_until_ready(envs.step(actions))
after_one = graphs()
for _ in range(4):
    jax.block_until_ready(envs.step(actions))
print(after_one, graphs(), len(warp_graphs.bounded_sites()))
"""


@pytest.mark.gpu
@pytest.mark.parametrize("mode", [None, "warp"])
def test_the_adapters_graphs_do_not_grow_with_its_steps_on_the_gpu(mode):
    """Stepped from Python, the adapter's sites see new buffers at every call. In its default
    (Warp's staged mode) each traced call site keeps one graph and replays it, so the count is
    fixed after the first step; in MJX's default ("warp") the graphs Warp keeps stay at most one
    per site the adapter bounds (a site first run in a later step, an autoreset say, adds its
    one). Neither may grow with the calls (default process settings)."""
    env = {k: v for k, v in os.environ.items() if k != "MWJAX_WARP_GRAPHS_PER_SITE"}
    out = subprocess.run(
        [sys.executable, "-c", _ADAPTER_PROBE, *([mode] if mode else [])],
        env=env,
        capture_output=True,
        text=True,
        check=True,
    )
    after_one, after_five, sites = map(int, out.stdout.split()[-3:])
    if mode == "warp":
        assert 0 < after_one <= after_five <= sites
    else:
        assert 0 < after_one == after_five


@pytest.mark.gpu
def test_the_staged_mode_replays_its_graphs_with_each_calls_inputs():
    """`graph_mode="warp_staged_ex"` captures each traced call's graph once and replays it at
    every later call, copying that call's inputs into its staging buffers. Steps and images of
    new states must then be the default mode's for the same states: the physics up to its
    atomics' last bits (GPU runs are not bit-reproducible), the ray-traced images exactly."""
    import jax
    import numpy as np

    import mwjax
    from mwjax import rendering

    staged_physics = mwjax.PhysicsConfig(graph_mode="warp_staged_ex")
    default = mwjax.make("MT1:pick-place-v3", envs_per_task=64)
    staged = mwjax.make("MT1:pick-place-v3", envs_per_task=64, physics=staged_physics)
    steps = [jax.jit(e.step) for e in (default, staged)]
    draws = [jax.jit(rendering.Renderer(e, envs=[0, 63]).render) for e in (default, staged)]
    state = jax.jit(default.reset)(jax.random.key(0))
    for key in jax.random.split(jax.random.key(1), 4):
        action = jax.random.uniform(key, (default.num_envs, 4), minval=-1.0, maxval=1.0)
        expected, replayed = (step(state, action) for step in steps)
        np.testing.assert_allclose(np.asarray(replayed.obs), np.asarray(expected.obs), atol=1e-4)
        np.testing.assert_allclose(np.asarray(replayed.reward), np.asarray(expected.reward), atol=1e-3)
        images = [np.asarray(draw(expected).rgb) for draw in draws]
        np.testing.assert_array_equal(images[1], images[0])
        state = expected


@pytest.mark.gpu
def test_the_adapter_steps_and_renders_in_the_staged_mode():
    """The Gymnasium adapter with `graph_mode="warp_staged_ex"` (its donated step and reset
    replay one graph each): observations move and stay finite, a reset with the same seed starts
    over, and `render()` draws every chosen env."""
    import numpy as np

    import mwjax
    from mwjax.wrappers.gymnasium import make_vector

    physics = mwjax.PhysicsConfig(graph_mode="warp_staged_ex")
    envs = make_vector("MT1", task="pick-place-v3", num_envs=8, physics=physics, render_mode="rgb_array")
    first, _ = envs.reset(seed=0)
    rng = np.random.default_rng(0)
    obs = first
    for _ in range(5):
        obs, reward, *_ = envs.step(rng.uniform(-1, 1, (8, 4)).astype(np.float32))
        assert np.all(np.isfinite(obs)) and np.all(np.isfinite(reward))
    assert obs.shape == envs.observation_space.shape and not np.array_equal(obs, first)
    frames = envs.render()
    assert len(frames) == 1 and all(f.shape == (480, 480, 3) and f.any() for f in frames)
    obs_again, _ = envs.reset(seed=0)
    np.testing.assert_allclose(obs_again, first, atol=1e-5)
