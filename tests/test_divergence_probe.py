"""`tools/divergence_probe.py`'s replay in MuJoCo C: it reports C's own divergence checks."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import numpy as np

from mwjax.models import load_scene

ROOT = Path(__file__).resolve().parents[1]
_spec = importlib.util.spec_from_file_location("divergence_probe", ROOT / "tools" / "divergence_probe.py")
probe = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(probe)


def test_the_replay_reports_mujoco_cs_divergence_checks(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)  # where C's warning writes its MUJOCO_LOG.TXT
    model = load_scene("sawyer_reach_v3.xml")
    data = probe.mujoco.MjData(model)
    probe.mujoco.mj_forward(model, data)
    start = {f: np.array(getattr(data, f), np.float64) for f in probe.FIELDS}
    assert probe.replay_in_c(model, start, 5)["c_warnings"] == []
    start["qvel"][2] = np.nan
    replayed = probe.replay_in_c(model, start, 5)
    assert replayed["c_warnings"] == ["mjWARN_BADQVEL"]
    assert np.isfinite(replayed["c_qvel_max_after"])  # C reset the state and stepped on
