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


def _rule_fits_by_hand(a, b):
    """The rule written out again, independently of activefoam.trends: every column's
    |median(b) − median(a)| below half the mean of the two IQRs (pandas' quartiles)."""
    import statistics
    for j in range(len(a[0])):
        ca, cb = [r[j] for r in a], [r[j] for r in b]
        spread = (np.subtract(*np.percentile(ca, [75, 25]))
                  + np.subtract(*np.percentile(cb, [75, 25]))) / 2
        if not abs(statistics.median(cb) - statistics.median(ca)) < spread / 2:
            return False
    return True


def test_the_permutation_null_counts_every_split_by_the_rule_itself():
    import itertools
    rng = np.random.default_rng(7)
    for _ in range(20):
        ref, cand = rng.normal(0, 1, (3, 2)), rng.normal(0.5, 1, (4, 2))
        null = trends.fitness_permutation(ref, cand)
        # The observed ensembles: the worst ratio is below 1 exactly when fitness() says fit.
        fits = [trends.fitness(ref[:, j], cand[:, j]).fit for j in range(2)]
        assert (null.worst < 1) == all(fits) == _rule_fits_by_hand(ref, cand)
        assert null.failures == fits.count(False) and null.metrics == 2
        # Every split of the 7 runs into 3 + 4, judged by hand.
        pooled = np.vstack([ref, cand])
        splits = list(itertools.combinations(range(7), 3))
        assert null.exact and null.splits == len(splits) == 35
        passing = sum(_rule_fits_by_hand(pooled[list(s)],
                                         pooled[[i for i in range(7) if i not in s]])
                      for s in splits)
        assert null.pass_rate == pytest.approx(passing / 35)


def _min_p_by_hand(labellings):
    """The min-p permutation p-value written out with loops: labellings is a list of (a, b)
    ensembles (runs × metrics), the observed one first."""
    m = labellings[0][0].shape[1]
    diffs = [[abs(b[:, j].mean() - a[:, j].mean()) for j in range(m)] for a, b in labellings]
    n = len(diffs)
    ps = [min(sum(d2[j] >= d[j] - 1e-9 for d2 in diffs) / n for j in range(m)) for d in diffs]
    return sum(p <= ps[0] + 1e-12 for p in ps) / n


def _smallest_p_by_hand(labellings):
    """The least p-value any labelling of these runs could have: the share of labellings whose
    smallest per-metric p is the least of all (each metric's own extreme and its mirror tie)."""
    m = labellings[0][0].shape[1]
    diffs = [[abs(b[:, j].mean() - a[:, j].mean()) for j in range(m)] for a, b in labellings]
    n = len(diffs)
    ps = [min(sum(d2[j] >= d[j] - 1e-9 for d2 in diffs) / n for j in range(m)) for d in diffs]
    return sum(p <= min(ps) + 1e-12 for p in ps) / n


def test_the_permutation_p_value_is_counted_by_hand_for_free_splits_and_seed_pairs():
    import itertools
    rng = np.random.default_rng(3)
    ref = rng.normal(0, 1, (5, 3))
    cand = rng.normal(0, 1, (5, 3))
    cand[:, 1] += 100.0          # one metric moved far beyond the seeds' spread
    null = trends.fitness_permutation(ref, cand)
    pooled = np.vstack([ref, cand])
    splits = [(pooled[list(c)], pooled[[i for i in range(10) if i not in c]])
              for c in itertools.combinations(range(10), 5)]
    assert not null.paired and null.splits == 252
    assert null.p_value == pytest.approx(_min_p_by_hand(splits))
    # The moved metric is the most different, at the smallest p a metric can have (the observed
    # split and its mirror); the others' own extremes keep the min-p above it.
    assert null.most_metric == 1 and null.p_metric[1] == pytest.approx(2 / 252)
    assert null.p_value < 0.05
    # The same seeds on both sides, listed in another order: each seed's two runs are swapped
    # or not (2^5 relabellings), matched by seed.
    order = [4, 2, 0, 1, 3]
    paired = trends.fitness_permutation(ref, cand[order], ref_seeds=[1, 2, 3, 4, 5],
                                        cand_seeds=[order[i] + 1 for i in range(5)])
    flips = [(np.where(np.array(f)[:, None], cand, ref), np.where(np.array(f)[:, None], ref, cand))
             for f in itertools.product([False, True], repeat=5)]
    assert paired.paired and paired.splits == 32 and paired.exact
    assert paired.p_value == pytest.approx(_min_p_by_hand(flips))
    # Five pairs cannot show a difference at 5 %: a metric's smallest p is 2 / 2^5, and with
    # three metrics each one's extreme labelling (and its mirror) ties there, so no labelling of
    # these runs reads below 2 · 3 / 2^5 — the least p counted by hand.
    assert paired.p_metric[1] == pytest.approx(2 / 32) and paired.p_value >= 2 / 32
    assert paired.smallest_p == pytest.approx(_smallest_p_by_hand(flips))
    assert 2 / 32 < paired.smallest_p <= 6 / 32
    assert null.smallest_p == pytest.approx(_smallest_p_by_hand(splits))
    assert null.p_value >= null.smallest_p
    three = trends.fitness_permutation(ref[:3], cand)
    pooled3 = np.vstack([ref[:3], cand])
    splits3 = [(pooled3[list(c)], pooled3[[i for i in range(8) if i not in c]])
               for c in itertools.combinations(range(8), 3)]
    assert three.smallest_p == pytest.approx(_smallest_p_by_hand(splits3))
    assert 1 / 56 <= three.smallest_p <= 3 / 56     # unequal sides: no mirror
    one = trends.fitness_permutation(ref[:, :1], cand[:, :1], [1, 2, 3, 4, 5], [1, 2, 3, 4, 5])
    assert one.smallest_p == pytest.approx(2 / 32)  # one metric: its extreme and its mirror
    # Ten pairs can: 1024 relabellings.
    big_ref, big_cand = rng.normal(0, 1, (10, 3)), rng.normal(0, 1, (10, 3))
    big_cand[:, 0] += 100.0
    ten = trends.fitness_permutation(big_ref, big_cand, list(range(10)), list(range(10)))
    assert ten.splits == 1024 and ten.p_value < 0.05 and ten.most_metric == 0


def test_the_median_interval_takes_the_order_statistics_its_coverage_allows():
    # Coverage of [x_(k), x_(n+1−k)]: 1 − 2 P(Binom(n, ½) ≤ k − 1).
    lo, hi, c = trends.median_interval([3.0, 1.0, 2.0])
    assert (lo, hi) == (1.0, 3.0) and c == pytest.approx(0.75)
    x = list(range(10, 0, -1))                  # 10 values: k = 2 covers 1 − 2·11/1024 ≥ 95 %,
    lo, hi, c = trends.median_interval(x)     # k = 3 only 1 − 2·56/1024 = 89 %
    assert (lo, hi) == (2.0, 9.0) and c == pytest.approx(1 - 22 / 1024)
    lo, hi, c = trends.median_interval(range(100))
    assert c >= 0.95 and trends.median_interval(range(100), 0.5)[2] < c
    assert 39 <= lo < 49.5 < hi <= 60
    # The coverage is what it says: the interval holds the true median that often.
    rng = np.random.default_rng(7)
    hits = [lo <= 0 <= hi for lo, hi, _ in (trends.median_interval(rng.standard_cauchy(10))
                                            for _ in range(4000))]
    assert np.mean(hits) == pytest.approx(1 - 22 / 1024, abs=0.01)
    assert math.isnan(trends.median_interval([math.nan])[0])


def test_the_paired_difference_cancels_the_seed_spread_and_matches_runs_by_seed():
    # Seeds spread by ±10, the candidate is each seed's reference + 1 (+ small noise): the
    # difference of medians carries the seed spread in its interval, the paired one does not.
    spread = {1: -10.0, 2: -5.0, 3: 0.0, 4: 5.0, 5: 10.0, 6: 7.0}
    noise = {1: 0.1, 2: -0.1, 3: 0.2, 4: -0.2, 5: 0.0, 6: 0.0}
    ref_seeds, cand_seeds = [1, 2, 3, 4, 5, 6], [5, 3, 1, 2, 4]   # seed 6 has no candidate run
    ref = [100 + spread[s] for s in ref_seeds]
    cand = [100 + spread[s] + 1 + noise[s] for s in cand_seeds]
    d = trends.paired_difference(ref, cand, ref_seeds, cand_seeds)
    assert d.n == 5 and d.higher == 5 and d.lower == 0
    assert d.diff == pytest.approx(1.0)       # the median of 1.1, 0.9, 1.2, 0.8, 1.0
    # Five pairs: no order-statistic interval reaches 95 %; the range, at 1 − 2/32.
    assert (d.lo, d.hi) == pytest.approx((0.8, 1.2)) and d.coverage == pytest.approx(30 / 32)
    unpaired = trends.diff_of_medians(ref, cand)
    assert unpaired.hi - unpaired.lo > 10 * (d.hi - d.lo)
    # A pair with a missing result is left out; so is a seed run twice on one side.
    cand_nan = list(cand)
    cand_nan[0] = math.nan
    assert trends.paired_difference(ref, cand_nan, ref_seeds, cand_seeds).n == 4
    assert trends.paired_difference(ref + [1.0], cand, ref_seeds + [5], cand_seeds).n == 4
    lower = trends.paired_difference(cand, ref[:5], cand_seeds, ref_seeds[:5])
    assert lower.diff == pytest.approx(-1.0) and lower.lower == 5
    assert math.isnan(trends.paired_difference([1.0], [2.0], [1], [2]).diff)
    with pytest.raises(ValueError):
        trends.paired_difference([1.0, 2.0], [1.0], [1], [1])


def test_equal_ensembles_are_called_different_at_most_as_often_as_the_level():
    rng = np.random.default_rng(11)
    ps = [trends.fitness_permutation(rng.normal(0, 1, (6, 4)), rng.normal(0, 1, (6, 4))).p_value
          for _ in range(300)]
    assert np.mean(np.array(ps) < 0.05) <= 0.05 + 0.03
    # Paired runs, correlated within a seed (as the studies' are): the same level.
    ps = []
    for _ in range(300):
        a = rng.normal(0, 1, (8, 4))
        ps.append(trends.fitness_permutation(a, 0.8 * a + 0.6 * rng.normal(0, 1, (8, 4)),
                                             list(range(8)), list(range(8))).p_value)
    assert np.mean(np.array(ps) < 0.05) <= 0.05 + 0.03
    # A sample of relabellings when there are too many to enumerate: the observed one is
    # counted, so p is never 0.
    a, b = rng.normal(0, 1, (12, 2)), rng.normal(0, 1, (12, 2))
    b[:, 0] += 100.0
    sampled = trends.fitness_permutation(a, b, max_splits=3000)
    assert not sampled.exact and sampled.splits == 3000
    assert 1 / 3000 <= sampled.p_value < 0.05


def test_a_metric_without_enough_runs_is_not_judged_by_the_permutation_null():
    ref = np.array([[1.0, 5.0], [2.0, np.nan], [3.0, np.inf], [4.0, np.nan]])
    cand = ref + [0.1, 0.0]
    null = trends.fitness_permutation(ref, cand)
    assert null.metrics == 1 and null.worst_metric == 0 and math.isnan(null.p_metric[1])
    nothing = trends.fitness_permutation(ref[:, 1:], cand[:, 1:])
    assert nothing.metrics == 0 and math.isnan(nothing.p_value)
    # ±inf is dropped as fitness() drops it.
    ref3 = np.array([[1.0], [2.0], [3.0], [np.inf]])
    assert trends.rule_ratios(ref3[None], (ref3 + 0.1)[None])[0, 0] == pytest.approx(
        0.1 / (trends.fitness(ref3[:, 0], ref3[:, 0] + 0.1).iqr / 2))


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
