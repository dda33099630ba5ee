"""activefoam.study.power: the effects a trend verdict resolves with n seeds, on synthetic ensembles
with known answers."""

import math

import numpy as np
import pytest

from activefoam.study import power as pw
from activefoam import trends


def test_with_three_seeds_a_side_agrees_means_the_ensembles_do_not_overlap():
    # The percentile bootstrap's 2.5 % quantile of a 3-against-3 difference of medians is
    # min(high) − max(low): the verdict agrees exactly when the two do not overlap.
    rng = np.random.default_rng(5)
    for _ in range(200):
        low, high = rng.normal(0, 1, 3), rng.normal(1.5, 1, 3)
        t = trends.trend(low, high, "increase")
        assert (t.verdict == "agrees") == (high.min() > low.max())


def test_two_equal_ensembles_of_three_agree_on_an_increase_one_time_in_twenty():
    # Non-overlap in a given order: 1 / C(6, 3) = 0.05 for exchangeable runs.
    p = pw.agree_probability(3, 0.0, trials=4000, seed=11)
    assert p == pytest.approx(0.05, abs=0.012)
    assert pw.agree_probability(3, 8.0, trials=200) > 0.99
    assert pw.agree_probability(3, -3.0, trials=200) == 0.0  # the other way: never agrees


def test_the_resolved_effect_shrinks_with_seeds_and_scales_with_the_spread():
    k3, k5 = pw.detectable_effect(3, trials=300), pw.detectable_effect(5, trials=300)
    assert 2.0 <= k3 <= 3.5 and k5 <= k3
    rows = pw.table({"a": [10, 11, 12, 13, 14], "b": [20, 22, 24, 26, 28]}, trials=300)
    a, b = rows
    assert a["sigma"] == pytest.approx(2 / pw.IQR_OF_NORMAL)   # IQR of 10..14 is 2
    assert b["sigma"] == pytest.approx(2 * a["sigma"])
    assert b["effect_3"] == pytest.approx(2 * a["effect_3"])
    # "No change within ±25 % of the median": a band of 10 σ is resolved, of 2 σ a third of the
    # time (the 3-seed interval spans about ±2.5 σ), of 0.3 σ almost never.
    narrow = pw.table({"n": [12, 12.2, 12.4, 12.6, 12.8]}, trials=300)[0]
    wide = pw.table({"w": [1, 5, 10, 15, 19]}, trials=300)[0]
    assert narrow["none_agrees_3"] > 0.95
    assert 0.2 < a["none_agrees_3"] < 0.5
    assert wide["none_agrees_3"] < 0.05


def test_the_fitness_rule_rarely_passes_equal_ensembles_of_few_seeds():
    # One metric: two thirds fail with 3 runs a side, half with 5; many runs pass. The large-n
    # limit: the difference of medians is normal with σ √(π/n) and half the IQR is 0.674 σ.
    p3, p5 = pw.rule_pass_probability(3), pw.rule_pass_probability(5)
    assert 0.30 < p3 < p5 < 0.52
    n = 41
    z = 0.6745 / math.sqrt(math.pi / n)
    assert pw.rule_pass_probability(n) == pytest.approx(math.erf(z / math.sqrt(2)), abs=0.02)
    # Eight independent metrics: p to the eighth (at 10 seeds, where it is not tiny).
    p10 = pw.rule_pass_probability(10)
    assert pw.rule_pass_probability(10, metrics=8) == pytest.approx(p10 ** 8, rel=0.1)


def test_the_calibrated_test_finds_a_shift_with_ten_pairs_and_none_with_five():
    assert pw.calibrated_power(10, 0.0, metrics=4, trials=150) <= 0.1
    # A gross shift of one metric: every time with ten pairs; never with five (2 / 2^5 > 5 %).
    assert pw.calibrated_power(10, 100.0, metrics=4, trials=40) == 1.0
    assert pw.calibrated_power(5, 100.0, metrics=4, trials=40) == 0.0
    # Correlated pairs (one seed's two runs alike) show a 1 σ shift far more often.
    assert pw.calibrated_power(10, 1.0, metrics=4, trials=150, rho=0.8) > \
        pw.calibrated_power(10, 1.0, metrics=4, trials=150, rho=0.0) + 0.2


def test_the_paired_shift_found_80_percent_of_the_time_matches_the_t_test_for_one_metric():
    # One metric, ten pairs, normal differences of SD 1: a paired t-test at 5 % has 80 % power
    # at (t_.975,9 + t_.8,9) / √10 ≈ 0.99; the sign-flip test needs about as much.
    k1 = pw.paired_detectable_shift(10, 1, trials=100)
    assert 0.8 <= k1 <= 1.3
    # Eight metrics read at once (min-p) need a larger shift to find one of them; five pairs
    # cannot reach p < 0.05 at all.
    assert pw.paired_detectable_shift(10, 8, trials=100) > k1
    assert math.isinf(pw.paired_detectable_shift(5, 8))


def test_pair_divergence_follows_a_seeds_two_runs_apart():
    import pandas as pd
    # Five seeds; the two arms agree exactly until 1 h (θ = 40 + 2·seed), after which the second
    # arm's θ is an unrelated permutation of the seeds' values.
    rows, samples = [], []
    later = {1: 5, 2: 3, 3: 1, 4: 2, 5: 4}
    for seed in range(1, 6):
        for arm in (0.25, 0.5):
            jid = f"j-{arm}-{seed}"
            rows.append({"seed": seed, "numerics.dt_s": arm, "job_id": jid,
                         "state": "succeeded"})
            for t in (0, 1800, 3600, 7200):
                s = seed if (t <= 3600 or arm == 0.25) else later[seed]
                samples.append({"job_id": jid, "t_s": t, "theta_deg": 40 + 2 * s})
    rows.append({"seed": 6, "numerics.dt_s": 0.25, "job_id": "j-alone", "state": "succeeded"})
    samples.append({"job_id": "j-alone", "t_s": 0, "theta_deg": 90.0})
    out = pw.pair_divergence(pd.DataFrame(rows), pd.DataFrame(samples), ["numerics.dt_s"],
                             [1800, 3700, 7100])
    assert [r["seeds"] for r in out] == [5, 5, 5]        # seed 6 ran one arm only
    assert out[0]["corr"] == pytest.approx(1.0) and out[0]["median_abs_diff"] == 0
    assert out[1]["corr"] == pytest.approx(1.0)          # the nearest sample to 3700 s is 3600
    assert out[2]["corr"] == pytest.approx(np.corrcoef([1, 2, 3, 4, 5], [5, 3, 1, 2, 4])[0, 1])
    assert out[2]["median_abs_diff"] == pytest.approx(4.0)   # |2 (s − later[s])|: 8 2 4 4 2
    assert out[0]["sd_seeds"] == pytest.approx(2 * np.std([1, 2, 3, 4, 5], ddof=1))
    # A run whose samples end before a time has no value there: its seed is left out.
    cut = pd.DataFrame(samples)
    cut = cut[~((cut["job_id"] == "j-0.5-1") & (cut["t_s"] > 3600))]
    late = pw.pair_divergence(pd.DataFrame(rows), cut, ["numerics.dt_s"], [3600, 7200])
    assert [r["seeds"] for r in late] == [5, 4]
    with pytest.raises(ValueError):
        pw.pair_divergence(pd.DataFrame(rows[:2]), pd.DataFrame(samples), ["seed"], [0])
