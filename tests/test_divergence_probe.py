"""`tools/divergence_probe.py`'s replay in MuJoCo C: it reports C's own divergence checks."""

from __future__ import annotations

import numpy as np
from tool_scripts import load_tool

from mwjax.models import load_scene

probe = load_tool("divergence_probe")


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


def test_the_run_up_replay_finds_the_step_at_which_c_diverges(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    model = load_scene("sawyer_reach_v3.xml")
    data = probe.mujoco.MjData(model)
    probe.mujoco.mj_forward(model, data)
    calm = {f: np.array(getattr(data, f), np.float64) for f in probe.FIELDS}
    states = [{f: v.copy() for f, v in calm.items()} for _ in range(4)]
    replayed = probe.replay_run_up_in_c(model, states, 5)
    assert replayed["c_run_up_first_warning"] is None
    assert len(replayed["c_run_up_qvel_max"]) == 4
    states[2]["mocap_pos"][0] = 1e12  # a hand target that flings the arm, written in before the third step
    replayed = probe.replay_run_up_in_c(model, states, 5)
    assert replayed["c_run_up_first_warning"] == 2


def test_the_run_up_reaches_back_into_the_previous_chunk():
    # Each state's qpos holds (chunk, step in chunk, env), so the window names its own origin.
    def chunk(c: int) -> dict[str, np.ndarray]:
        steps, envs = np.meshgrid(np.arange(5), np.arange(3), indexing="ij")
        qpos = np.stack([np.full((5, 3), c), steps, envs], axis=-1)
        return {f: qpos for f in probe.FIELDS}

    window = probe.run_up(chunk(0), chunk(1), 1, 2, 3)
    assert [tuple(s["qpos"]) for s in window] == [(0, 3, 2), (0, 4, 2), (1, 0, 2), (1, 1, 2)]
    assert len(probe.run_up(None, chunk(0), 1, 2, 3)) == 2  # the first chunk has nothing before it
