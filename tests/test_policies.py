"""The jax experts against the reference experts' actions on recorded reference observations.

`tools/record_expert_actions.py` stores, per task, 450 observations from expert-driven reference
episodes (with noise, to leave the experts' own path) and the action the reference expert takes
on each. The ports must give the same actions, no physics involved."""

from __future__ import annotations

import jax
import numpy as np
import pytest
from reference import FIXTURES

from mwjax import policies
from mwjax.benchmarks import MT50

FIXTURE = FIXTURES / "expert_actions.npz"
# Branch conditions compare float32 observations against thresholds; a value within rounding of
# a threshold may take the other branch in float32 than in the reference's float64.
MIN_AGREEMENT = 0.99


@pytest.fixture(scope="module")
def recorded():
    with np.load(FIXTURE) as archive:
        return {key: archive[key] for key in archive.files}


def test_every_task_has_an_expert():
    assert sorted(policies.EXPERTS) == sorted(MT50)


@pytest.mark.parametrize("task", MT50)
def test_expert_matches_reference(task, recorded):
    obs, reference = recorded[f"{task}/obs"], recorded[f"{task}/action"]
    ours = np.asarray(jax.jit(jax.vmap(policies.expert(task)))(obs))
    assert ours.shape == reference.shape and ours.dtype == np.float32
    # The env clips actions to [-1, 1]; beyond that the experts' raw outputs do not matter.
    close = np.all(np.abs(np.clip(ours, -1, 1) - np.clip(reference, -1, 1)) <= 1e-4, axis=1)
    assert close.mean() >= MIN_AGREEMENT, (
        f"{task}: {close.mean():.1%} of actions agree; first mismatch at {np.flatnonzero(~close)[:5]}"
    )
