"""tools/scene_streams_compile.py reads XLA's own pass timing log."""

from __future__ import annotations

import os
import subprocess
import sys

from tool_scripts import load_tool

scene_streams_compile = load_tool("scene_streams_compile")

# A program with an elementwise chain for XLA's fusion pass, compiled in a fresh process whose
# XLA logs its passes (the log level is read when jaxlib loads).
CHILD = """
import jax, jax.numpy as jnp
jax.config.update("jax_enable_compilation_cache", False)
def step(x):
    return jnp.tanh(x * 2.0 + 1.0).sum()
jax.jit(step).lower(jnp.ones(64)).compile()
"""


def test_the_slowest_passes_of_the_step_module_come_from_xlas_log():
    env = dict(os.environ, JAX_PLATFORMS="cpu", **scene_streams_compile.PASS_LOG_ENV)
    child = subprocess.run([sys.executable, "-c", CHILD], env=env, capture_output=True, text=True, check=True)
    log = child.stderr
    passes = scene_streams_compile.slowest_passes(log, module="jit_step", top=50)
    names = [name for name, _ in passes]
    assert "fusion" in names and len(names) == len(set(names))
    seconds = [s for _, s in passes]
    assert seconds == sorted(seconds, reverse=True) and all(s >= 0 for s in seconds)
    assert scene_streams_compile.slowest_passes(log, module="jit_no_such_module") == []
