"""Warp call ids that do not depend on what was traced before (`mwjax.warp_call_ids`)."""

import re

import jax
import jax.numpy as jnp

import mwjax


def _step_program(env: mwjax.Env) -> str:
    """The env's step, traced afresh (a new function) and lowered: what JAX's cache keys on."""
    state = jax.eval_shape(env.reset, jax.random.key(0))
    return jax.jit(lambda s, a: env.step(s, a)).lower(state, jnp.zeros((env.num_envs, 4))).as_text()


def _call_ids(program: str) -> list[str]:
    return re.findall(r"call_id = (\d+)", program)


def test_a_program_is_the_same_whatever_was_traced_before_it(monkeypatch):
    """The same step lowered before and after another scene's step: the same program, hence the
    same key in JAX's persistent cache. With Warp's counter the ids, and the program, differ."""
    reach = mwjax.make("MT1:reach-v3", envs_per_task=1)
    push = mwjax.make("MT1:push-v3", envs_per_task=1)
    first = _step_program(reach)
    _step_program(push)
    again = _step_program(reach)
    assert _call_ids(first)
    assert again == first

    monkeypatch.setenv("MWJAX_STABLE_CALL_IDS", "0")
    counted = _step_program(reach)
    assert _call_ids(counted) != _call_ids(first)


def test_the_calls_of_one_program_keep_distinct_ids():
    """Two steps in one program: the second step's calls get ids of their own, as with Warp's
    counter, where JAX traces them again."""
    env = mwjax.make("MT1:reach-v3", envs_per_task=1)
    state = jax.eval_shape(env.reset, jax.random.key(0))
    actions = jnp.zeros((1, 4))
    one = set(_call_ids(_step_program(env)))
    two = jax.jit(lambda s, a: env.step(env.step(s, a), a)).lower(state, actions).as_text()
    assert len(set(_call_ids(two)) - one) > 0
