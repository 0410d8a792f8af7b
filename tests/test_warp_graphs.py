"""The opt-in bound on the CUDA graphs Warp keeps per MJX-Warp call site (`mwjax.warp_graphs`)."""

import collections
import os
import subprocess
import sys

import pytest

from mwjax import warp_graphs


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
    site traced by its first step is marked, a site traced outside the adapter is not."""
    import jax

    import mwjax
    from mwjax.wrappers.gymnasium import make_vector

    before = warp_graphs.bounded_sites()
    envs = make_vector("MT1", task="reach-v3", num_envs=1, array_type="jax")
    envs.reset(seed=0)
    after_reset = warp_graphs.bounded_sites()
    envs.step(jax.numpy.zeros((1, 4)))
    after_step = warp_graphs.bounded_sites()
    assert before < after_reset < after_step  # reset's kinematics, then the step's calls

    env = mwjax.make("MT1:reach-v3", envs_per_task=1)
    state = jax.jit(env.reset)(jax.random.key(0))
    jax.block_until_ready(jax.jit(env.step)(state, jax.numpy.zeros((1, 4))))
    assert warp_graphs.bounded_sites() == after_step
    with pytest.raises(ValueError, match="at least 1"):
        with warp_graphs.bounded(0):
            pass


_ADAPTER_PROBE = """
import jax
from mwjax import warp_graphs
from mwjax.wrappers.gymnasium import make_vector
envs = make_vector("MT1", task="reach-v3", num_envs=64, array_type="jax")
envs.reset(seed=0)
actions = jax.numpy.zeros((envs.num_envs, 4))
jax.block_until_ready(envs.step(actions))
after_one = warp_graphs.kept_graphs()
for _ in range(4):
    jax.block_until_ready(envs.step(actions))
print(after_one[0], warp_graphs.kept_graphs()[0], warp_graphs.bounded_sites())
"""


@pytest.mark.gpu
def test_the_adapter_keeps_one_graph_per_site_on_the_gpu():
    """Stepped from Python, the adapter's sites see new buffers at every call: the graphs Warp
    keeps must stay at one per bounded site, not grow with the calls (default process settings)."""
    env = {k: v for k, v in os.environ.items() if k != "MWJAX_WARP_GRAPHS_PER_SITE"}
    out = subprocess.run(
        [sys.executable, "-c", _ADAPTER_PROBE], env=env, capture_output=True, text=True, check=True
    )
    after_one, after_five, sites = map(int, out.stdout.split()[-3:])
    assert 0 < after_one == after_five <= sites
