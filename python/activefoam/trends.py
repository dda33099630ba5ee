"""Ensemble statistics of studies: medians, IQRs, bootstrap intervals and the verdict rules.

Everything a study report concludes goes through these few functions, so that the rules are
written once and tested on synthetic data with known answers (python/tests/test_trends.py):

- `diff_of_medians(a, b)`: median(b) − median(a) with a percentile-bootstrap interval (each
  ensemble resampled with replacement, independently; a fixed generator seed, so a report is
  reproducible from its data).
- `fitness(a_ref, b)`: a candidate ensemble is *fit* against a reference ensemble when the
  difference of medians is below half the seed-to-seed IQR (the mean of the two ensembles'
  IQRs): the preset-fitness rule of docs/science/presets.md.
- `fitness_permutation(ref_rows, cand_rows)`: the fitness rule calibrated on the runs themselves.
  Two ensembles drawn from one distribution fail |Δ| < IQR/2 on a metric about half the time with
  5 runs a side (two thirds with 3), so "not fit" on some of 8 metrics says nothing until it is
  compared with what equal numerics give: every split of the pooled runs into two ensembles of
  the same sizes (a permutation test; the metrics' correlations kept, no model) is judged by the
  same rule, and the p-value is the share of splits whose worst ratio |Δ|/(IQR/2) is at least
  the observed one.
- `trend(x_low, x_high, expect)`: the effect of raising a parameter, with its interval, and the
  verdict against the supplement's statement: *agrees* when the interval excludes 0 on the
  stated side, *disagrees* when it excludes 0 on the other side (or, for "no change", excludes
  the stated band), *not resolved* otherwise. No verdict from fewer than `MIN_SEEDS` runs a side.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Optional, Sequence

import numpy as np

MIN_SEEDS = 3          # no trend is judged from fewer runs per point
BOOTSTRAP = 10000      # resamples per interval
LEVEL = 0.95           # interval level


def finite(x: Sequence[float]) -> np.ndarray:
    a = np.asarray(list(x), dtype=float)
    return a[np.isfinite(a)]


def median(x: Sequence[float]) -> float:
    a = finite(x)
    return float(np.median(a)) if len(a) else math.nan


def iqr(x: Sequence[float]) -> float:
    """Interquartile range (linear interpolation between order statistics, as pandas)."""
    a = finite(x)
    if len(a) == 0:
        return math.nan
    q75, q25 = np.percentile(a, [75, 25])
    return float(q75 - q25)


@dataclass
class Difference:
    diff: float        # median(b) − median(a)
    lo: float          # bootstrap interval of diff
    hi: float
    n_a: int
    n_b: int


def diff_of_medians(a: Sequence[float], b: Sequence[float], n_boot: int = BOOTSTRAP,
                    level: float = LEVEL, seed: int = 12345) -> Difference:
    """median(b) − median(a) and its percentile-bootstrap interval (NaN with an empty side)."""
    xa, xb = finite(a), finite(b)
    if len(xa) == 0 or len(xb) == 0:
        return Difference(math.nan, math.nan, math.nan, len(xa), len(xb))
    rng = np.random.default_rng(seed)
    ma = np.median(xa[rng.integers(0, len(xa), size=(n_boot, len(xa)))], axis=1)
    mb = np.median(xb[rng.integers(0, len(xb), size=(n_boot, len(xb)))], axis=1)
    d = mb - ma
    tail = 100 * (1 - level) / 2
    lo, hi = np.percentile(d, [tail, 100 - tail])
    return Difference(float(np.median(xb) - np.median(xa)), float(lo), float(hi), len(xa),
                      len(xb))


@dataclass
class Fitness:
    diff: Difference
    iqr: float         # seed-to-seed spread: the mean of both ensembles' IQRs
    fit: Optional[bool]  # None: too few runs to say
    why: str


def fitness(reference: Sequence[float], candidate: Sequence[float],
            min_seeds: int = MIN_SEEDS) -> Fitness:
    """Is `candidate` interchangeable with `reference` for this metric? |Δ median| < IQR / 2."""
    d = diff_of_medians(reference, candidate)
    spread = float(np.nanmean([iqr(reference), iqr(candidate)])) if (
        d.n_a and d.n_b) else math.nan
    if d.n_a < min_seeds or d.n_b < min_seeds:
        return Fitness(d, spread, None, f"too few runs ({d.n_a} and {d.n_b}; {min_seeds} needed)")
    if abs(d.diff) < spread / 2:
        return Fitness(d, spread, True, f"|Δ| = {abs(d.diff):.3g} < IQR/2 = {spread / 2:.3g}")
    return Fitness(d, spread, False, f"|Δ| = {abs(d.diff):.3g} ≥ IQR/2 = {spread / 2:.3g}")


@dataclass
class FitnessNull:
    worst: float       # the rule's worst ratio |Δ| / (IQR/2) over the judged metrics (fit: < 1)
    worst_metric: int  # its column
    failures: int      # metrics with a ratio ≥ 1
    metrics: int       # metrics judged (≥ min_seeds finite runs a side)
    splits: int        # splits of the pooled runs evaluated (all of them, or a sample)
    exact: bool        # every split enumerated
    p_value: float     # share of splits whose worst ratio is ≥ the observed one
    worst95: float     # the worst ratio that 95 % of the splits stay below
    pass_rate: float   # share of splits the rule calls fit (worst ratio < 1): what it gives
                       # for equal numerics at these ensemble sizes


def rule_ratios(a: np.ndarray, b: np.ndarray, min_seeds: int = MIN_SEEDS) -> np.ndarray:
    """|Δ median| / (IQR/2) of fitness() for stacked ensembles a (S, n_a, M) and b (S, n_b, M):
    the rule fails a metric where the ratio is ≥ 1. NaN where a side has fewer than min_seeds
    finite runs (not judged); a metric without spread has ratio inf with a difference and 1
    without (|Δ| < 0 is impossible: the rule fails it)."""
    import warnings
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # all-NaN slices give NaN, not judged
        # NaN-aware quantiles are an order slower: only where a run lacks a metric.
        gaps = np.isnan(a).any() or np.isnan(b).any()
        med = np.nanmedian if gaps else np.median
        pct = np.nanpercentile if gaps else np.percentile
        d = np.abs(med(b, axis=1) - med(a, axis=1))
        qa = pct(a, [75, 25], axis=1)
        qb = pct(b, [75, 25], axis=1)
        half = np.nanmean(np.stack([qa[0] - qa[1], qb[0] - qb[1]]), axis=0) / 2
        ratio = np.where(half > 0, d / np.where(half > 0, half, 1.0),
                         np.where(d > 0, np.inf, 1.0))
    judged = ((np.isfinite(a).sum(axis=1) >= min_seeds) & (np.isfinite(b).sum(axis=1) >= min_seeds)
              & np.isfinite(d))
    return np.where(judged, ratio, np.nan)


def fitness_permutation(reference: Sequence[Sequence[float]], candidate: Sequence[Sequence[float]],
                        max_splits: int = 20000, seed: int = 12345,
                        min_seeds: int = MIN_SEEDS) -> FitnessNull:
    """The fitness rule's worst ratio for reference (runs × metrics) against candidate, and its
    permutation distribution: every way to split the pooled runs into ensembles of the same two
    sizes (a fixed-seed sample of max_splits when there are more) judged by the same rule. The
    p-value is the share of splits at least as far from fit as the observed ensembles: small when
    the numerics moved some metric by more than a relabelling of the seeds does."""
    import itertools
    import warnings
    ra = np.asarray(reference, dtype=float).reshape(len(reference), -1)
    rb = np.asarray(candidate, dtype=float).reshape(len(candidate), -1)
    if ra.shape[1] != rb.shape[1]:
        raise ValueError(f"reference has {ra.shape[1]} metrics, candidate {rb.shape[1]}")
    pooled = np.vstack([ra, rb])
    n, n_a = len(pooled), len(ra)
    observed = rule_ratios(ra[None], rb[None], min_seeds)[0]
    total = math.comb(n, n_a)
    if total <= max_splits:
        picks = np.array(list(itertools.combinations(range(n), n_a)), dtype=int)
        exact = True
    else:
        rng = np.random.default_rng(seed)
        picks = np.argsort(rng.random((max_splits, n)), axis=1)[:, :n_a]
        exact = False
    in_a = np.zeros((len(picks), n), dtype=bool)
    in_a[np.arange(len(picks))[:, None], picks] = True
    split = pooled[np.argsort(~in_a, axis=1, kind="stable")]   # a's runs first, then b's
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        worst = np.nanmax(rule_ratios(split[:, :n_a], split[:, n_a:], min_seeds), axis=1)
    judged = np.isfinite(observed) | np.isinf(observed)
    if not judged.any():
        return FitnessNull(math.nan, -1, 0, 0, len(picks), exact, math.nan, math.nan, math.nan)
    w = float(np.nanmax(observed))
    # Ties (equal medians in many splits of few runs) count as at least as far.
    tol = 1e-12 * max(1.0, abs(w)) if math.isfinite(w) else 0.0
    return FitnessNull(w, int(np.nanargmax(observed)), int((observed[judged] >= 1).sum()),
                       int(judged.sum()), len(picks), exact, float((worst >= w - tol).mean()),
                       float(np.nanpercentile(worst, 95)), float((worst < 1).mean()))


EXPECTATIONS = ("increase", "decrease", "none")


@dataclass
class Trend:
    diff: Difference
    expect: str
    verdict: str       # agrees | disagrees | not resolved | too few runs


def trend(low: Sequence[float], high: Sequence[float], expect: str, band: float = 0.0,
          min_seeds: int = MIN_SEEDS) -> Trend:
    """The effect median(high) − median(low) of raising a parameter, judged against the
    supplement's `expect`: "increase", "decrease", or "none" (|effect| within ±band)."""
    if expect not in EXPECTATIONS:
        raise ValueError(f"expect: {expect!r} is not one of {', '.join(EXPECTATIONS)}")
    d = diff_of_medians(low, high)
    if d.n_a < min_seeds or d.n_b < min_seeds:
        return Trend(d, expect, "too few runs")
    if expect == "none":
        if -band <= d.lo and d.hi <= band:
            verdict = "agrees"
        elif d.lo > band or d.hi < -band:
            verdict = "disagrees"
        else:
            verdict = "not resolved"
        return Trend(d, expect, verdict)
    sign = 1 if expect == "increase" else -1
    if sign * d.lo > 0 and sign * d.hi > 0:
        verdict = "agrees"
    elif sign * d.lo < 0 and sign * d.hi < 0:
        verdict = "disagrees"
    else:
        verdict = "not resolved"
    return Trend(d, expect, verdict)
