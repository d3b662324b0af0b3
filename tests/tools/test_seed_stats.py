"""rlq.tools.seed_stats: IQM (rliable's) with a 95 % bootstrap interval, median, mean ± std, seeds over a threshold."""

from __future__ import annotations

import numpy as np
import pytest

from rlq.errors import UsageError
from rlq.tools.seed_stats import iqm_interval, seed_stats

SCORES = [500.0, 500.0, 143.0, 480.0, 490.0, 500.0, 208.0, 499.0]


def test_iqm_is_the_mean_of_the_middle_half() -> None:
    stats = seed_stats(SCORES, threshold=475.0)
    middle = sorted(SCORES)[2:6]  # of 8 seeds, the 25th-75th percentile half
    assert stats.iqm == pytest.approx(np.mean(middle))
    assert stats.median == pytest.approx(np.median(SCORES))
    assert (stats.mean, stats.std) == (pytest.approx(np.mean(SCORES)), pytest.approx(np.std(SCORES)))
    assert (stats.n, stats.over, stats.fraction_over) == (8, 6, 0.75)


def test_the_interval_holds_the_iqm_and_repeats() -> None:
    iqm, low, high = iqm_interval(SCORES)
    assert min(SCORES) <= low < iqm < high <= max(SCORES)
    assert iqm_interval(SCORES) == (iqm, low, high)
    assert iqm_interval(SCORES, seed=1) != (iqm, low, high)  # a bootstrap: another resampling, another interval


def test_the_interval_ignores_and_keeps_numpys_global_generator() -> None:
    """rliable resamples with numpy's global generator: the interval must not depend on its state, and the
    caller's draws must not depend on the interval having been computed."""
    scores = np.arange(16.0) ** 1.5
    np.random.seed(123)
    first = iqm_interval(scores)
    after_first = np.random.rand()
    np.random.seed(456)
    assert iqm_interval(scores) == first
    np.random.seed(123)
    iqm_interval(scores)
    assert np.random.rand() == after_first


def test_equal_scores_have_no_spread_and_one_seed_is_its_own_interval() -> None:
    assert iqm_interval([3.0] * 5) == (3.0, 3.0, 3.0)
    one = seed_stats([7.5], threshold=8.0)
    assert (one.iqm, one.iqm_low, one.iqm_high, one.over) == (7.5, 7.5, 7.5, 0)


def test_without_a_threshold_nothing_is_counted_and_no_scores_is_refused() -> None:
    assert seed_stats(SCORES).over is None and seed_stats(SCORES).fraction_over is None
    with pytest.raises(UsageError, match="at least one score"):
        seed_stats([])
