"""Records scipy's Rotation.from_matrix(...).as_quat() on rotations that exercise every branch.

Several reference tasks report object orientation through scipy, whose sign convention depends on
which of the trace and diagonal terms is largest. `tests/test_spec.py` checks
`mwjax.tasks.spec.quat_from_xmat` against this fixture. Run in the reference venv:
    .venv-ref/bin/python tools/record_scipy_quats.py
"""

from pathlib import Path

import numpy as np
import scipy
from scipy.spatial.transform import Rotation

OUT = Path(__file__).parents[1] / "tests" / "fixtures" / "reference" / "scipy_quats.npz"

rng = np.random.default_rng(0)
random = Rotation.random(200, random_state=1).as_matrix()
# Near-half-turns about each axis make each diagonal term the largest in turn.
half_turns = np.stack(
    [Rotation.from_rotvec(axis * np.pi * (0.98 + 0.02 * rng.random())).as_matrix() for axis in np.eye(3)]
)
identity_like = Rotation.from_rotvec(rng.normal(scale=1e-3, size=(20, 3))).as_matrix()
matrices = np.concatenate([random, half_turns, identity_like])
quats = np.stack([Rotation.from_matrix(m).as_quat() for m in matrices])
np.savez_compressed(OUT, matrices=matrices, quats=quats, scipy=np.array(scipy.__version__))
print(f"wrote {OUT}: {len(matrices)} rotations, scipy {scipy.__version__}")
