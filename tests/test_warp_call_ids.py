"""Warp call ids that do not depend on what was traced before (`mwjax.warp_call_ids`)."""

import hashlib
import os
import re
import sys
from pathlib import Path

import children
import jax
import jax.numpy as jnp
import pytest
import warp as wp

import mwjax
from mwjax import warp_call_ids


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


def _other_order(workdir: Path) -> tuple[list[str], dict[str, str]]:
    return [sys.executable, "-c", _OTHER_ORDER], dict(os.environ)


@pytest.mark.child.with_args(_other_order)
def test_a_program_is_the_same_whatever_was_traced_before_it(request, monkeypatch):
    """Reach's step, lowered here and in a process that traced push's step first: the same
    program (Warp's FFI target names and call ids included), hence the same key in JAX's
    persistent cache. With Warp's counter, tracing it again in one process already differs."""
    reach = mwjax.make("MT1:reach-v3", envs_per_task=1)
    here = _step_program(reach)
    assert _call_ids(here)
    out, _ = children.result(request.node)
    assert out.returncode == 0, out.stderr[-4000:]
    assert out.stdout.split()[-1] == hashlib.sha256(here.encode()).hexdigest()

    monkeypatch.setenv("MWJAX_STABLE_CALL_IDS", "0")
    jax.clear_caches()  # JAX may reuse traces of MJX's functions, with the ids written into them
    assert _call_ids(_step_program(reach)) != _call_ids(here)


def _copy(x: wp.array(dtype=wp.float32), y: wp.array(dtype=wp.float32)) -> None:
    wp.copy(y, x)


def test_calls_of_one_kind_are_numbered_within_their_program():
    """Two calls of one Warp callable with the same shapes in one program: two ids, as with
    Warp's counter. The same call in another program: the first id again."""
    warp_call_ids.install()  # as making any env does
    copy = wp.jax_callable(_copy, graph_mode=wp.JaxCallableGraphMode.NONE)
    x = jax.ShapeDtypeStruct((3,), jnp.float32)
    twice = _call_ids(jax.jit(lambda v: copy(copy(v)[0])[0]).lower(x).as_text())
    once = _call_ids(jax.jit(lambda v: copy(v)[0]).lower(x).as_text())
    assert len(set(twice)) == 2
    assert once == twice[:1]
