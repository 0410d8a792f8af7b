"""Aggregate statistics for success rates across seeds, as Meta-World+ reports them (Agarwal et
al. 2021, "Deep RL at the edge of the statistical precipice"): the interquartile mean (IQM) over
runs x tasks and a stratified-bootstrap confidence interval (resampling runs within each task).

`rliable` (the paper's library) installs but does not import with current pandas (its `arch`
dependency fails), so these few lines are ours, following its definitions.
"""

from __future__ import annotations

from collections.abc import Iterator
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
    scores = _runs_by_tasks(scores, "scores")
    _check_confidence(confidence)
    if statistic not in ("iqm", "mean"):
        raise ValueError(f"statistic must be 'iqm' or 'mean', got {statistic!r}")
    fn = iqm if statistic == "iqm" else (lambda s: float(np.mean(s)))
    samples = [fn(resampled) for resampled in _resamples(scores, reps, np.random.default_rng(seed))]
    return Estimate(fn(scores), *_percentiles(samples, confidence))


def probability_of_improvement(
    x: np.ndarray, y: np.ndarray, confidence: float = 0.95, reps: int = 2000, seed: int = 0
) -> Estimate:
    """P(X > Y) (Agarwal et al. 2021, rliable's `probability_of_improvement`): on a task drawn at
    random, the probability that a run of X scores above a run of Y, ties counting half, i.e. the
    per-task Mann-Whitney U statistic over all run pairs divided by their number, averaged over
    tasks. `x` `(runs_x, tasks)` and `y` `(runs_y, tasks)` share their tasks (columns in the same
    order); the CI resamples each one's runs within each task. 0.5: neither is better."""
    x, y = _runs_by_tasks(x, "x"), _runs_by_tasks(y, "y")
    if x.shape[1] != y.shape[1]:
        raise ValueError(f"x and y must score the same tasks, got {x.shape[1]} and {y.shape[1]} columns")
    _check_confidence(confidence)
    rng = np.random.default_rng(seed)
    samples = [
        _improvement(a, b) for a, b in zip(_resamples(x, reps, rng), _resamples(y, reps, rng), strict=True)
    ]
    return Estimate(_improvement(x, y), *_percentiles(samples, confidence))


def _improvement(x: np.ndarray, y: np.ndarray) -> float:
    pairs = x[:, None, :] - y[None, :, :]  # (runs_x, runs_y, tasks)
    per_task = (pairs > 0).mean(axis=(0, 1)) + 0.5 * (pairs == 0).mean(axis=(0, 1))
    return float(per_task.mean())


def _runs_by_tasks(scores: np.ndarray, name: str) -> np.ndarray:
    scores = np.asarray(scores, np.float64)
    if scores.ndim != 2 or scores.size == 0:
        raise ValueError(f"{name} must be a non-empty (runs, tasks) array, got shape {scores.shape}")
    return scores


def _check_confidence(confidence: float) -> None:
    if not 0 < confidence < 1:
        raise ValueError(f"confidence must lie in (0, 1), got {confidence}")


def _resamples(scores: np.ndarray, reps: int, rng: np.random.Generator) -> Iterator[np.ndarray]:
    """`reps` resamplings of `scores`: each task's runs drawn with replacement, independently per
    task (stratified)."""
    runs, tasks = scores.shape
    for picks in rng.integers(0, runs, size=(reps, runs, tasks)):
        yield np.take_along_axis(scores, picks, axis=0)


def _percentiles(samples: list[float], confidence: float) -> tuple[float, float]:
    tail = 100 * (1 - confidence) / 2
    low, high = np.percentile(samples, [tail, 100 - tail])
    return float(low), float(high)
