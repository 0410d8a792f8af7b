"""GPU memory between JAX and Warp: `import mwjax` leaves Warp room unless the user chose, a pool
too large is named, and Warp's allocation failures say what to change."""

from __future__ import annotations

import os
import subprocess
import sys
import warnings
from pathlib import Path

import pytest

from mwjax import device_memory

ROOT = Path(__file__).parents[1]


def test_import_sets_the_pool_unless_the_user_chose_or_jax_started():
    code = (
        "import os\n"
        "import mwjax\n"
        "from mwjax import device_memory as m\n"
        "print(os.environ.get('XLA_PYTHON_CLIENT_MEM_FRACTION'))\n"
        "for chosen in ('XLA_PYTHON_CLIENT_MEM_FRACTION', 'XLA_PYTHON_CLIENT_PREALLOCATE'):\n"
        "    environ = {chosen: '0.3'}\n"
        "    print(m.set_default_pool(environ), environ == {chosen: '0.3'})\n"
        "import jax\n"
        "print(m.set_default_pool({}))\n"  # imported, not started: still read when it starts
        "jax.devices()\n"
        "print(m.set_default_pool({}))\n"
    )
    env = {k: v for k, v in os.environ.items() if k not in device_memory.USER_SETTINGS}
    result = subprocess.run(
        [sys.executable, "-c", code], cwd=ROOT, env=env, capture_output=True, text=True, check=True
    )
    assert result.stdout.splitlines() == [
        device_memory.DEFAULT_FRACTION,
        "False True",
        "False True",
        "True",
        "False",
    ]


def test_a_pool_that_leaves_warp_too_little_is_named():
    gib = 2**30
    message = device_memory.pool_warning(int(0.75 * 140 * gib), 140 * gib)
    assert message is not None
    assert "75%" in message and "XLA_PYTHON_CLIENT_MEM_FRACTION" in message
    assert device_memory.pool_warning(int(0.45 * 140 * gib), 140 * gib) is None


def test_a_warp_allocation_failure_says_what_to_change():
    failure = RuntimeError("Failed to allocate 4026531840 bytes on device 'cuda:0'")
    explained = device_memory.explained(failure)
    assert explained.startswith(str(failure)) and "XLA_PYTHON_CLIENT_MEM_FRACTION" in explained
    other = RuntimeError("graph launch failed")
    assert device_memory.explained(other) == "graph launch failed"


class _FakeGpu:
    platform = "gpu"
    local_hardware_id = 0

    def memory_stats(self) -> dict[str, int]:
        return {"bytes_limit": 75 * 2**30}


@pytest.mark.parametrize("preallocate", [None, "false"])
def test_make_warns_once_about_a_preallocated_pool_too_large(preallocate, monkeypatch):
    monkeypatch.setattr(device_memory, "gpu_memory_bytes", lambda device: 100 * 2**30)
    monkeypatch.setattr(device_memory, "_warned", False)
    if preallocate is None:
        monkeypatch.delenv("XLA_PYTHON_CLIENT_PREALLOCATE", raising=False)
    else:  # JAX grows its pool as it needs: Warp has the rest until then
        monkeypatch.setenv("XLA_PYTHON_CLIENT_PREALLOCATE", preallocate)
    monkeypatch.delenv("XLA_PYTHON_CLIENT_ALLOCATOR", raising=False)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        for _ in range(2):
            device_memory.check_pool(_FakeGpu())
    expected = 1 if preallocate is None else 0
    assert [issubclass(w.category, device_memory.DeviceMemoryWarning) for w in caught] == [True] * expected
