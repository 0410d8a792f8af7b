"""`mwjax.stored_results`: a computation `mwjax.make` runs on the device is stored, and a later
process reads the same bits, so that its programs carry the same constants (and JAX's
persistent cache hits)."""

from __future__ import annotations

import os

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import mwjax
from mwjax import placement, stored_results


@pytest.fixture
def cache_home(tmp_path, monkeypatch):
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path))
    monkeypatch.delenv("MWJAX_NO_CACHE", raising=False)
    return tmp_path / "mwjax" / "results"


def _stored(directory):
    stored_results.wait()
    return sorted(directory.glob("*.npz")) if directory.exists() else []


def _program(scale):
    return jax.jit(lambda x: {"a": jnp.sin(x) * scale, "b": [jnp.cumsum(x), x.astype(jnp.int32)]})


def test_a_result_is_stored_then_read_back_bit_for_bit(cache_home, monkeypatch):
    x = jnp.linspace(0.0, 3.0, 7)
    computed = stored_results.run(_program(2.0), x)
    files = _stored(cache_home)
    assert len(files) == 1

    def not_compiled(*args, **kwargs):
        raise AssertionError("a stored result was computed again")

    # A second process: nothing in memory, the program lowered again, its result read from disk.
    lowered_type = type(_program(2.0).lower(x))
    monkeypatch.setattr(lowered_type, "compile", not_compiled)
    read = stored_results.run(_program(2.0), x)
    assert jax.tree.structure(read) == jax.tree.structure(computed)
    for got, want in zip(jax.tree.leaves(read), jax.tree.leaves(computed), strict=True):
        assert got.dtype == want.dtype
        np.testing.assert_array_equal(np.asarray(got), np.asarray(want))


def test_another_program_or_input_is_another_entry(cache_home):
    x = jnp.arange(4.0)
    stored_results.run(_program(2.0), x)
    stored_results.run(_program(3.0), x)  # a constant the program closes over
    stored_results.run(_program(2.0), x + 1)  # another input
    assert len(_stored(cache_home)) == 3
    np.testing.assert_array_equal(stored_results.run(_program(3.0), x)["a"], _program(3.0)(x)["a"])


def test_a_damaged_entry_is_computed_again(cache_home):
    x = jnp.arange(5.0)
    stored_results.run(_program(2.0), x)
    (path,) = _stored(cache_home)
    path.write_bytes(b"not an archive")
    np.testing.assert_array_equal(stored_results.run(_program(2.0), x)["b"][0], np.cumsum(np.arange(5.0)))
    stored_results.wait()
    with np.load(path) as archive:  # written again, whole
        assert len(archive.files) == 3


def test_mwjax_no_cache_stores_nothing(cache_home, monkeypatch):
    monkeypatch.setenv("MWJAX_NO_CACHE", "1")
    result = stored_results.run(_program(2.0), jnp.arange(3.0))
    np.testing.assert_array_equal(result["b"][1], [0, 1, 2])
    assert _stored(cache_home) == []


def test_an_env_reads_its_per_goal_settled_states_back(cache_home, monkeypatch):
    """An env whose task settles per goal stores those states when it is made, and an env made
    later (its process's memory emptied) reads them back bit for bit."""
    monkeypatch.setattr(placement, "_SETTLED_PER_VARIANT", {})
    first = mwjax.make(["door-lock-v3"], envs_per_task=2, seed=1)
    assert len(_stored(cache_home)) == 1
    monkeypatch.setattr(placement, "_SETTLED_PER_VARIANT", {})
    again = mwjax.make(["door-lock-v3"], envs_per_task=2, seed=1)
    (rows_first,) = [r for r in first._rows if r.spec.settle_per_goal]
    (rows_again,) = [r for r in again._rows if r.spec.settle_per_goal]
    assert rows_again.settled_per_variant is not rows_first.settled_per_variant
    got_leaves = jax.tree.leaves(rows_again.settled_per_variant)
    for got, want in zip(got_leaves, jax.tree.leaves(rows_first.settled_per_variant), strict=True):
        np.testing.assert_array_equal(np.asarray(got), np.asarray(want))
    assert len(_stored(cache_home)) == 1


def test_a_cache_that_cannot_be_written_is_no_error(tmp_path, monkeypatch):
    blocked = tmp_path / "not-a-directory"
    blocked.write_text("")
    monkeypatch.setenv("XDG_CACHE_HOME", str(blocked))
    monkeypatch.delenv("MWJAX_NO_CACHE", raising=False)
    x = jnp.arange(3.0)
    np.testing.assert_array_equal(stored_results.run(_program(2.0), x)["b"][0], _program(2.0)(x)["b"][0])
    stored_results.wait()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["not-a-directory"]


def test_the_least_recently_used_entries_go_when_the_directory_is_full(cache_home, monkeypatch):
    x = jnp.arange(64.0)
    stored_results.run(_program(1.0), x)
    (oldest,) = _stored(cache_home)
    stored_results.run(_program(2.0), x)
    (second,) = set(_stored(cache_home)) - {oldest}
    os.utime(oldest, (1, 1))
    os.utime(second, (2, 2))
    stored_results.run(_program(1.0), x)  # read back: used now
    entry = oldest.stat().st_size
    monkeypatch.setattr(stored_results, "LIMIT_BYTES", 2 * entry)
    stored_results.run(_program(3.0), x)  # a third entry: the one least recently used goes
    assert oldest in _stored(cache_home) and second not in _stored(cache_home)
    assert len(_stored(cache_home)) == 2


def test_a_described_result_is_read_back_without_tracing_its_program(cache_home):
    traced = []

    def program(scale):
        def f(x):
            traced.append(scale)
            return {"a": jnp.sin(x) * scale, "b": [jnp.cumsum(x), x.astype(jnp.int32)]}

        return jax.jit(f)

    x = jnp.linspace(0.0, 3.0, 7)
    tree = jax.tree.structure({"a": 0, "b": [0, 0]})
    computed = stored_results.run(program(2.0), x, described_by="scale 2", out_tree=tree)
    assert traced == [2.0] and len(_stored(cache_home)) == 1
    read = stored_results.run(program(2.0), x, described_by="scale 2", out_tree=tree)
    assert traced == [2.0]  # read from disk: not traced again
    for got, want in zip(jax.tree.leaves(read), jax.tree.leaves(computed), strict=True):
        assert got.dtype == want.dtype
        np.testing.assert_array_equal(np.asarray(got), np.asarray(want))
    # Another description or input is another entry; the description, not the program, is the key.
    stored_results.run(program(3.0), x, described_by="scale 3", out_tree=tree)
    stored_results.run(program(2.0), x + 1, described_by="scale 2", out_tree=tree)
    assert traced == [2.0, 3.0, 2.0] and len(_stored(cache_home)) == 3


def test_a_description_must_come_with_the_results_structure(cache_home):
    x = jnp.arange(3.0)
    with pytest.raises(ValueError, match="needs out_tree"):
        stored_results.run(_program(2.0), x, described_by="scale 2")
    with pytest.raises(ValueError, match="does not describe the result"):
        stored_results.run(_program(2.0), x, described_by="scale 2", out_tree=jax.tree.structure([0, 0]))
