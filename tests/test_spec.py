"""Task-vocabulary helpers against reference behaviour."""

from __future__ import annotations

from pathlib import Path

import jax
import numpy as np

from mwjax.tasks.spec import quat_from_xmat

FIXTURE = Path(__file__).parent / "fixtures" / "reference" / "scipy_quats.npz"


def test_quat_from_xmat_matches_scipy():
    with np.load(FIXTURE) as recorded:
        matrices, quats = recorded["matrices"], recorded["quats"]
    ours = np.asarray(jax.vmap(quat_from_xmat)(matrices.astype(np.float32)))
    np.testing.assert_allclose(ours, quats, atol=2e-6)
