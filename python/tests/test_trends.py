"""The study statistics on synthetic data with known answers (no foamd needed)."""

import math

import numpy as np
import pytest

from activefoam import trends


def test_difference_of_medians_and_its_interval():
    a = [10.0, 11.0, 12.0, 13.0, 14.0]
    b = [x + 5.0 for x in a]
    d = trends.diff_of_medians(a, b)
    assert d.diff == 5.0
    assert d.lo <= 5.0 <= d.hi
    assert d.lo > 0  # five clean runs a side: the shift is resolved
    assert (d.n_a, d.n_b) == (5, 5)
    # Reproducible: the generator is seeded.
    assert trends.diff_of_medians(a, b) == d
    # NaN runs (a fit that did not converge) are left out, not counted as zero.
    d2 = trends.diff_of_medians(a + [math.nan], b)
    assert d2.n_a == 5 and d2.diff == 5.0
    assert math.isnan(trends.diff_of_medians([], b).diff)


def test_bootstrap_interval_covers_the_true_shift_at_about_its_level():
    rng = np.random.default_rng(7)
    cover, trials = 0, 200
    for _ in range(trials):
        a = rng.normal(0, 1, 15)
        b = rng.normal(1, 1, 15)
        d = trends.diff_of_medians(a, b, n_boot=400, seed=int(rng.integers(1 << 30)))
        cover += d.lo <= 1.0 <= d.hi
    # A percentile bootstrap of medians at n = 15 covers near its nominal 95 %.
    assert 0.85 <= cover / trials <= 1.0


def test_iqr_matches_the_quartiles():
    assert trends.iqr([1, 2, 3, 4, 5]) == 2.0
    assert trends.iqr([7, 7, 7]) == 0.0
    assert math.isnan(trends.iqr([]))


def test_fitness_rule_is_half_the_iqr():
    ref = [60.0, 62.0, 64.0, 66.0, 68.0]           # IQR 4
    near = [x + 1.5 for x in ref]                   # |Δ| 1.5 < 2
    far = [x + 2.5 for x in ref]                    # |Δ| 2.5 ≥ 2
    assert trends.fitness(ref, near).fit is True
    f = trends.fitness(ref, far)
    assert f.fit is False and f.iqr == 4.0 and f.diff.diff == 2.5
    # Too few runs: no verdict at all.
    assert trends.fitness(ref, far[:2]).fit is None
    # No spread and a difference: not fit (|Δ| < 0 is impossible).
    assert trends.fitness([1.0, 1.0, 1.0], [1.1, 1.1, 1.1]).fit is False


def test_trend_verdicts():
    low = [10.0, 11.0, 12.0, 13.0, 14.0]
    high = [20.0, 21.0, 22.0, 23.0, 24.0]
    assert trends.trend(low, high, "increase").verdict == "agrees"
    assert trends.trend(low, high, "decrease").verdict == "disagrees"
    assert trends.trend(high, low, "decrease").verdict == "agrees"
    noisy = [5.0, 30.0, 12.0, 2.0, 25.0]
    assert trends.trend(low, noisy, "increase").verdict == "not resolved"
    same = [10.2, 11.1, 11.9, 13.2, 13.8]
    assert trends.trend(low, same, "none", band=3.0).verdict == "agrees"
    assert trends.trend(low, same, "none", band=1.0).verdict == "not resolved"
    assert trends.trend(low, high, "none", band=3.0).verdict == "disagrees"
    assert trends.trend(low[:2], high, "increase").verdict == "too few runs"
    with pytest.raises(ValueError, match="expect"):
        trends.trend(low, high, "up")
