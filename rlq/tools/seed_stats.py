"""Statistics over seeds as the RL literature reports them (Agarwal et al. 2021, computed by their ``rliable``):
the interquartile mean with a 95 % stratified-bootstrap interval, beside the median, mean ± std and the
fraction of seeds that reach a threshold. One score per seed (its final evaluation)."""

from __future__ import annotations

import warnings
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from rlq.errors import UsageError

#: bootstrap resamples of the interval, and the resampling's seed (the same scores give the same interval)
REPS = 2000
BOOTSTRAP_SEED = 0


@dataclass(frozen=True)
class SeedStats:
    """Figures over one group's seeds; ``over`` counts the seeds at or above ``threshold`` (None without one)."""

    n: int
    mean: float
    std: float
    median: float
    iqm: float
    iqm_low: float
    iqm_high: float
    threshold: float | None = None
    over: int | None = None

    @property
    def fraction_over(self) -> float | None:
        return None if self.over is None else self.over / self.n


def iqm_interval(
    scores: Sequence[float] | np.ndarray, reps: int = REPS, seed: int = BOOTSTRAP_SEED
) -> tuple[float, float, float]:
    """The interquartile mean of ``scores`` and its 95 % percentile-bootstrap interval (rliable's)."""
    from rliable import library, metrics

    runs = np.asarray(scores, np.float64).reshape(-1, 1)  # rliable's (runs, tasks) layout: one task
    if len(runs) == 1:  # one seed: nothing to resample
        value = float(runs[0, 0])
        return value, value, value

    def aggregate(x: np.ndarray) -> np.ndarray:
        return np.array([metrics.aggregate_iqm(x)])

    # rliable's StratifiedBootstrap resamples with numpy's global generator (np.random.choice), whatever
    # random_state it is given: seed that generator for the call and give the caller's state back after it
    saved = np.random.get_state()
    np.random.seed(seed)
    try:
        with warnings.catch_warnings():  # rliable hands arch a RandomState, which arch 7 warns will change
            warnings.filterwarnings("ignore", "random_state is deprecated", FutureWarning)
            points, intervals = library.get_interval_estimates(
                {"scores": runs}, aggregate, reps=reps, random_state=np.random.RandomState(seed)
            )
    finally:
        np.random.set_state(saved)
    return float(points["scores"][0]), float(intervals["scores"][0, 0]), float(intervals["scores"][1, 0])


def seed_stats(scores: Sequence[float] | np.ndarray, threshold: float | None = None) -> SeedStats:
    """The figures of one group's final scores (at least one)."""
    values = np.asarray(scores, np.float64)
    if values.size == 0:
        raise UsageError("seed statistics need at least one score")
    iqm, low, high = iqm_interval(values)
    over = None if threshold is None else int(np.sum(values >= threshold))
    return SeedStats(
        n=int(values.size),
        mean=float(values.mean()),
        std=float(values.std()),
        median=float(np.median(values)),
        iqm=iqm,
        iqm_low=low,
        iqm_high=high,
        threshold=threshold,
        over=over,
    )
