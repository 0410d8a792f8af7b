"""tools/loop_atomics.py finds the loop atomics `mwjax.determinism` is known to bound."""

from __future__ import annotations

import linecache
from pathlib import Path

import pytest
import warp as wp
from tool_scripts import load_tool

import mwjax
from mwjax import determinism, kernels

loop_atomics = load_tool("loop_atomics")


@pytest.fixture(scope="module")
def reach_kernels():
    (scene,) = kernels.scenes(["reach-v3"])
    return {kernel.key: kernel for kernel in loop_atomics.launched_kernels(*scene, mwjax.PhysicsConfig())}


def test_the_known_loop_atomics_are_found_and_reported_covered(reach_kernels):
    mass_matrix = reach_kernels["_M"]  # `smooth.crb`'s mass matrix: one add per ancestor dof
    assert mass_matrix.module.name in determinism.LOOP_RECORDS
    (site,) = loop_atomics.loop_sites(mass_matrix)
    assert "dynamic" in site["loops"] and site["site"].startswith("add into")
    name, line = site["at"].split(":")
    assert name == Path(mass_matrix.adj.filename).name
    assert "+=" in linecache.getline(mass_matrix.adj.filename, int(line))
    assert loop_atomics.covered(mass_matrix).startswith("deterministic_max_records=")
    cone_hessian = reach_kernels[determinism.CONE_HESSIAN]
    assert loop_atomics.loop_sites(cone_hessian) and loop_atomics.covered(cone_hessian)


BEYOND_UNROLL = 40  # more iterations than Warp's default `max_unroll` (16)


@wp.func
def _add_twice(out: wp.array(dtype=float), value: float):
    wp.atomic_add(out, 0, value)
    out[1] += value


@wp.kernel(module="unique")
def _sample(out: wp.array(dtype=float), n: int):
    wp.atomic_add(out, 0, 1.0)  # once per thread
    for _ in range(3):  # unrolled
        wp.atomic_add(out, 1, 1.0)
    for _ in range(wp.static(BEYOND_UNROLL)):  # Warp folds the bound to a constant: too long too
        wp.atomic_max(out, 2, 1.0)
    for _ in range(BEYOND_UNROLL):  # too long to unroll
        wp.atomic_min(out, 3, 1.0)
    for _ in range(n):  # a runtime bound
        out[4] += 1.0
        _add_twice(out, 1.0)
    local = wp.vec3()
    for i in range(n):
        local[0] += float(i)  # not an array: no atomic


def test_only_the_atomics_of_dynamic_loops_are_listed():
    sites = [(site["site"], site["loops"], len(site["through"])) for site in loop_atomics.loop_sites(_sample)]
    assert sites == [
        ("atomic_max", ["dynamic"], 0),
        ("atomic_min", ["dynamic"], 0),
        ("add into an array element", ["dynamic"], 0),
        (f"calls {_add_twice.key}", ["dynamic"], 2),
    ]
