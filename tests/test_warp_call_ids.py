"""Warp call ids that do not depend on what was traced before (`mwjax.warp_call_ids`)."""

import hashlib
import re
import subprocess
import sys

import jax
import jax.numpy as jnp

import mwjax


def _step_program(env: mwjax.Env) -> str:
    """The env's step, traced afresh (a new function) and lowered: what JAX's cache keys on."""
    state = jax.eval_shape(env.reset, jax.random.key(0))
    return jax.jit(lambda s, a: env.step(s, a)).lower(state, jnp.zeros((env.num_envs, 4))).as_text()


def _call_ids(program: str) -> list[str]:
    return re.findall(r"call_id = (\d+)", program)


_OTHER_ORDER = """
import hashlib, jax, jax.numpy as jnp, mwjax
def program(env):
    state = jax.eval_shape(env.reset, jax.random.key(0))
    return jax.jit(lambda s, a: env.step(s, a)).lower(state, jnp.zeros((env.num_envs, 4))).as_text()
program(mwjax.make("MT1:push-v3", envs_per_task=1))
print(hashlib.sha256(program(mwjax.make("MT1:reach-v3", envs_per_task=1)).encode()).hexdigest())
"""


def test_a_program_is_the_same_whatever_was_traced_before_it(monkeypatch):
    """Reach's step, lowered here and in a process that traced push's step first: the same
    program (Warp's FFI target names and call ids included), hence the same key in JAX's
    persistent cache. With Warp's counter, a second trace in one process already differs."""
    reach = mwjax.make("MT1:reach-v3", envs_per_task=1)
    here = _step_program(reach)
    assert _call_ids(here)
    out = subprocess.run([sys.executable, "-c", _OTHER_ORDER], capture_output=True, text=True, check=True)
    assert out.stdout.split()[-1] == hashlib.sha256(here.encode()).hexdigest()

    monkeypatch.setenv("MWJAX_STABLE_CALL_IDS", "0")
    assert _call_ids(_step_program(reach)) != _call_ids(here)


def test_the_calls_of_one_program_keep_distinct_ids():
    """Two steps in one program: the second step's calls get ids of their own, as with Warp's
    counter, where JAX traces them again."""
    env = mwjax.make("MT1:reach-v3", envs_per_task=1)
    state = jax.eval_shape(env.reset, jax.random.key(0))
    actions = jnp.zeros((1, 4))
    one = set(_call_ids(_step_program(env)))
    two = jax.jit(lambda s, a: env.step(env.step(s, a), a)).lower(state, actions).as_text()
    assert len(set(_call_ids(two)) - one) > 0
