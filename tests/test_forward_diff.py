"""The physics diff tool of the determinism work (`benchmarks/forward_diff.py`): its comparisons,
and a CPU run, where the two runs of each call must agree bit for bit."""

from __future__ import annotations

import dataclasses
import json
import subprocess
import sys
from pathlib import Path
from types import SimpleNamespace

import numpy as np

BENCHMARKS = Path(__file__).parents[1] / "benchmarks"
sys.path.insert(0, str(BENCHMARKS))
import forward_diff  # noqa: E402


@dataclasses.dataclass
class Data:
    qpos: np.ndarray
    _impl: SimpleNamespace


def found(order: list[int]) -> Data:
    """Three contacts in two worlds, stored in `order`, and two stale slots past `nacon`."""
    contacts = {
        "worldid": np.array([0, 1, 1, 7, 7]),
        "geom": np.array([[0, 3], [0, 3], [2, 5], [9, 9], [9, 9]]),
        "dist": np.array([-1e-3, -2e-3, 4e-4, 5.0, 6.0]),
        "pos": np.arange(15.0).reshape(5, 3),
        "frame": np.arange(45.0).reshape(5, 3, 3),
        "friction": np.ones((5, 5)),
        "solref": np.ones((5, 2)),
        "solimp": np.ones((5, 5)),
        "dim": np.array([3, 3, 3, 1, 1]),
    }
    index = np.array(order + [3, 4])
    impl = {f"contact__{k}": v[index] for k, v in contacts.items()}
    return Data(qpos=np.zeros((2, 3)), _impl=SimpleNamespace(nacon=np.array([3]), **impl))


def test_contacts_found_in_another_order_are_told_from_contacts_that_differ():
    a, b = found([0, 1, 2]), found([2, 0, 1])
    as_found = forward_diff.compare(
        forward_diff.contacts(a, False)["pos"], forward_diff.contacts(b, False)["pos"], False
    )
    assert not as_found["identical"] and as_found["max_abs_diff"] == 6.0
    for key in forward_diff.CONTACT_FIELDS:
        sorted_a, sorted_b = forward_diff.contacts(a, True)[key], forward_diff.contacts(b, True)[key]
        assert forward_diff.compare(sorted_a, sorted_b, False)["identical"], key
    b._impl.contact__dist[0] += 1e-7  # a contact that really differs stays different once sorted
    dist = forward_diff.compare(
        forward_diff.contacts(a, True)["dist"], forward_diff.contacts(b, True)["dist"], False
    )
    assert not dist["identical"]
    assert forward_diff.field(a, "qpos").shape == (2, 3) and forward_diff.field(a, "nacon")[0] == 3


def test_per_world_differences_are_counted():
    a = np.zeros((4, 2, 3), np.float32)
    b = a.copy()
    b[1, 0, 2], b[3, 1, 1] = 1e-6, -2.0
    result = forward_diff.compare(a, b, per_world=True)
    assert result == {"identical": False, "max_abs_diff": 2.0, "worlds_differing": 2}
    assert forward_diff.compare(a, a.copy(), per_world=True) == {"identical": True, "max_abs_diff": 0.0}


def test_every_field_of_both_calls_agrees_on_the_cpu(tmp_path):
    out = tmp_path / "diff.json"
    command = [sys.executable, str(BENCHMARKS / "forward_diff.py"), "--set", "push-v3"]
    command += ["--envs-per-task", "2", "--steps", "3", "--out", str(out)]
    run = subprocess.run(command, capture_output=True, text=True)
    assert run.returncode == 0, run.stdout + run.stderr
    result = json.loads(out.read_text())
    (scene,) = result["scenes"]
    assert result["identical"] and scene["first_differing"] is None
    assert scene["contacts"] > 0 and scene["constraint_rows"] > 0  # the collision stage had work
    compared = {row["field"] for row in scene["fields"]}
    assert {name for _, name in forward_diff.PIPELINE} <= compared
    assert {f"contact {key} (sorted)" for key in forward_diff.CONTACT_FIELDS} <= compared
    for key in ("device", "commit", "date", "command"):
        assert result[key]
