"""Aggregate statistics for success rates across seeds, as Meta-World+ reports them (Agarwal et
al. 2021, "Deep RL at the edge of the statistical precipice"): the interquartile mean (IQM) over
runs x tasks and a stratified-bootstrap confidence interval (resampling runs within each task).

`rliable` (the paper's library) installs but does not import with current pandas (its `arch`
dependency fails), so these few lines are ours, following its definitions.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np


class Estimate(NamedTuple):
    value: float
    low: float
    high: float


def iqm(scores: np.ndarray) -> float:
    """The mean of the middle 50% of all scores (25% trimmed from each end), like
    `scipy.stats.trim_mean(scores.ravel(), 0.25)` and rliable's `aggregate_iqm`."""
    flat = np.sort(np.asarray(scores, np.float64).ravel())
    cut = int(0.25 * flat.size)
    return float(flat[cut : flat.size - cut].mean())


def stratified_bootstrap_ci(
    scores: np.ndarray,
    statistic: str = "iqm",
    confidence: float = 0.95,
    reps: int = 2000,
    seed: int = 0,
) -> Estimate:
    """Point estimate and percentile CI of `statistic` ("iqm" or "mean") over `scores`
    `(runs, tasks)`, resampling runs with replacement independently within each task."""
    scores = np.asarray(scores, np.float64)
    if scores.ndim != 2 or scores.size == 0:
        raise ValueError(f"scores must be a non-empty (runs, tasks) array, got shape {scores.shape}")
    if not 0 < confidence < 1:
        raise ValueError(f"confidence must lie in (0, 1), got {confidence}")
    if statistic not in ("iqm", "mean"):
        raise ValueError(f"statistic must be 'iqm' or 'mean', got {statistic!r}")
    fn = iqm if statistic == "iqm" else (lambda s: float(np.mean(s)))
    runs, tasks = scores.shape
    rng = np.random.default_rng(seed)
    picks = rng.integers(0, runs, size=(reps, runs, tasks))
    samples = np.array([fn(np.take_along_axis(scores, p, axis=0)) for p in picks])
    tail = 100 * (1 - confidence) / 2
    low, high = np.percentile(samples, [tail, 100 - tail])
    return Estimate(fn(scores), float(low), float(high))
