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
  compared with what equal numerics give. The runs are relabelled (within each seed's pair
  when both settings ran the same seeds; else every split of the pooled runs) and each metric's
  difference of means is ranked among its relabellings; the smallest of those ranks over the
  metrics, against the same for every relabelling, is the p-value (a min-p permutation test:
  the metrics' correlations kept, no distribution assumed).
- `paired_difference(ref, cand, ref_seeds, cand_seeds)`: the candidate's effect seed by seed (the
  median of the within-seed differences, its order-statistic interval, and how many pairs
  went up and down): the effect size that the paired test above reads, without the seed-to-seed
  spread that a difference of medians carries.
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
    paired: bool       # relabelled within each seed's pair of runs (else free splits)
    splits: int        # relabellings evaluated (the observed one included)
    exact: bool        # every relabelling enumerated
    p_value: float     # min-p over the metrics, adjusted by the relabellings (see below)
    smallest_p: float  # the smallest p_value these runs allow under any labelling: the share of
                       # relabellings whose smallest per-metric p is the least any reaches (each
                       # metric's most extreme labelling and, with sides of one size, its mirror:
                       # about 2m/2^n for m metrics on n seed pairs, not 2/2^n)
    p_metric: np.ndarray  # each metric's own permutation p of |Δ mean| (NaN: not judged)
    most_metric: int   # the metric with the smallest p_metric
    pass_rate: float   # share of relabellings the rule calls fit: what it gives equal numerics


def _finite_or_nan(x: np.ndarray) -> np.ndarray:
    return np.where(np.isfinite(x), x, np.nan)   # fitness() drops ±inf as it drops NaN


def _stats(a: np.ndarray, b: np.ndarray, min_seeds: int):
    """For stacked ensembles a (S, n_a, M), b (S, n_b, M): |Δ mean| (the permutation test's
    statistic) and the rule's ratio |Δ median| / (IQR/2), both NaN where a side has fewer than
    min_seeds finite runs (not judged)."""
    import warnings
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # all-NaN slices give NaN, not judged
        # NaN-aware quantiles are an order slower: only where a run lacks a metric.
        gaps = np.isnan(a).any() or np.isnan(b).any()
        med = np.nanmedian if gaps else np.median
        pct = np.nanpercentile if gaps else np.percentile
        d = np.abs(med(b, axis=1) - med(a, axis=1))
        mean = np.nanmean if gaps else np.mean
        dm = np.abs(mean(b, axis=1) - mean(a, axis=1))
        qa = pct(a, [75, 25], axis=1)
        qb = pct(b, [75, 25], axis=1)
        half = np.nanmean(np.stack([qa[0] - qa[1], qb[0] - qb[1]]), axis=0) / 2
        # No spread: inf with a difference, 1 without (|Δ| < 0 is impossible: the rule fails).
        ratio = np.where(half > 0, d / np.where(half > 0, half, 1.0),
                         np.where(d > 0, np.inf, 1.0))
    judged = ((np.isfinite(a).sum(axis=1) >= min_seeds) & (np.isfinite(b).sum(axis=1) >= min_seeds)
              & np.isfinite(d))
    return np.where(judged, dm, np.nan), np.where(judged, ratio, np.nan)


def rule_ratios(a: np.ndarray, b: np.ndarray, min_seeds: int = MIN_SEEDS) -> np.ndarray:
    """|Δ median| / (IQR/2) of fitness() for stacked ensembles a (S, n_a, M) and b (S, n_b, M):
    the rule fails a metric where the ratio is ≥ 1; NaN where a side has fewer than min_seeds
    finite runs (not judged)."""
    return _stats(_finite_or_nan(np.asarray(a, dtype=float)),
                  _finite_or_nan(np.asarray(b, dtype=float)), min_seeds)[1]


def is_paired(ref_seeds: Optional[Sequence[int]], cand_seeds: Optional[Sequence[int]]) -> bool:
    """Do two ensembles form seed pairs (the same seeds, each once on each side)? Then
    fitness_permutation relabels within the pairs; else it splits the pooled runs freely."""
    if ref_seeds is None or cand_seeds is None:
        return False
    a, b = list(ref_seeds), list(cand_seeds)
    return len(a) == len(b) and len(set(a)) == len(a) and set(a) == set(b)


def fitness_permutation(reference: Sequence[Sequence[float]], candidate: Sequence[Sequence[float]],
                        ref_seeds: Optional[Sequence[int]] = None,
                        cand_seeds: Optional[Sequence[int]] = None, max_splits: int = 20000,
                        seed: int = 12345, min_seeds: int = MIN_SEEDS) -> FitnessNull:
    """Is the candidate (runs × metrics) further from the reference than relabelling the runs
    makes it? A permutation test of "the numerics change nothing":

    - the relabellings: when both ensembles hold the same seeds once each (the studies' paired
      design: a seed prepares the same spheroids for both settings, and the runs of one seed
      are correlated), each seed's two runs swap sides or not (2^n); otherwise every split of
      the pooled runs into ensembles of the two sizes. All of them, or a fixed-seed sample of
      max_splits with the observed labelling counted too;
    - the statistic: each metric's |Δ mean| is ranked among its own relabellings (its p), and
      the smallest p over the metrics is compared with the smallest p of every relabelling
      (Westfall–Young's min-p): a shift of any one metric, on its own scale, with the metrics'
      correlations kept and no distribution assumed. Means, not the rule's medians: a median
      barely moves when a few runs change sides, so among the relabellings a difference of
      medians hides even a gross shift (one metric moved by 100 σ is found 78 % of the time
      with 10 seed pairs by medians, every time by means).

    Also the rule's own numbers: its worst ratio on the observed ensembles, and the share of
    relabellings it calls fit (what the rule gives equal numerics at these sizes)."""
    import itertools
    ra = _finite_or_nan(np.asarray(reference, dtype=float).reshape(len(reference), -1))
    rb = _finite_or_nan(np.asarray(candidate, dtype=float).reshape(len(candidate), -1))
    if ra.shape[1] != rb.shape[1]:
        raise ValueError(f"reference has {ra.shape[1]} metrics, candidate {rb.shape[1]}")
    n_a, n_b, m = len(ra), len(rb), ra.shape[1]
    paired = is_paired(ref_seeds, cand_seeds)
    total = 2 ** n_a if paired else math.comb(n_a + n_b, n_a)
    smallest_p = (2 if paired or n_a == n_b else 1) / total
    rng = np.random.default_rng(seed)
    if paired:
        rb = rb[[list(cand_seeds).index(s) for s in ref_seeds]]   # pair i: ra[i], rb[i]
        exact = total <= max_splits
        flips = (np.array(list(itertools.product([False, True], repeat=n_a)), dtype=bool)
                 if exact else np.vstack([np.zeros(n_a, dtype=bool),
                                          rng.random((max_splits - 1, n_a)) < 0.5]))
        a = np.where(flips[:, :, None], rb[None], ra[None])
        b = np.where(flips[:, :, None], ra[None], rb[None])
    else:
        pooled = np.vstack([ra, rb])
        n = n_a + n_b
        exact = total <= max_splits
        picks = (np.array(list(itertools.combinations(range(n), n_a)), dtype=int) if exact
                 else np.vstack([np.arange(n_a)[None],
                                 np.argsort(rng.random((max_splits - 1, n)), axis=1)[:, :n_a]]))
        in_a = np.zeros((len(picks), n), dtype=bool)
        in_a[np.arange(len(picks))[:, None], picks] = True
        split = pooled[np.argsort(~in_a, axis=1, kind="stable")]   # a's runs first, then b's
        a, b = split[:, :n_a], split[:, n_a:]
    # The observed labelling is row 0 in every case (no flips; the first combination).
    d, ratio = _stats(a, b, min_seeds)
    s_count = len(d)
    obs_ratio = ratio[0]
    judged = ~np.isnan(obs_ratio)
    if not judged.any():
        return FitnessNull(math.nan, -1, 0, 0, paired, s_count, exact, math.nan, smallest_p,
                           np.full(m, math.nan), -1, math.nan)
    # Each metric's p for every relabelling: the share of relabellings at least as far. Ties
    # (a relabelling and its mirror give the same difference) count as as far.
    pm = np.ones_like(d)
    for j in range(m):
        col = d[:, j]
        ok = ~np.isnan(col)
        if not judged[j] or not ok.any():
            continue
        ordered = np.sort(col[ok])
        tol = 1e-12 * max(1.0, float(np.abs(ordered).max()))
        at_least = len(ordered) - np.searchsorted(ordered, col[ok] - tol, side="left")
        pm[ok, j] = at_least / s_count
    pm[:, ~judged] = 1.0
    smallest = pm.min(axis=1)
    p_value = float((smallest <= smallest[0] * (1 + 1e-12)).mean())
    # Each metric's own extreme labelling reaches the least per-metric p, so with several metrics
    # several labellings tie there and no labelling of these values gives a smaller p_value.
    smallest_p = float((smallest <= smallest.min() * (1 + 1e-12)).mean())
    p_metric = np.where(judged, pm[0], np.nan)
    with np.errstate(invalid="ignore"):
        worst_all = np.nanmax(np.where(np.isnan(ratio), -np.inf, ratio), axis=1)
    w = float(np.nanmax(obs_ratio))
    return FitnessNull(w, int(np.nanargmax(obs_ratio)), int((obs_ratio[judged] >= 1).sum()),
                       int(judged.sum()), paired, s_count, exact, p_value, smallest_p, p_metric,
                       int(np.nanargmin(p_metric)), float((worst_all < 1).mean()))


@dataclass
class PairedDifference:
    diff: float        # median over seeds of (candidate − reference) within each seed's pair
    lo: float          # distribution-free interval of that median: order statistics of the
    hi: float          # pairs' differences (see paired_difference)
    coverage: float    # its exact coverage (≥ LEVEL where the pairs allow it)
    sd: float          # the differences' standard deviation (NaN below 2 pairs)
    n: int             # pairs with both runs finite
    higher: int        # pairs where the candidate is above its reference
    lower: int         # ... below


def median_interval(x: Sequence[float], level: float = LEVEL):
    """Distribution-free interval of a median from n values: [x_(k), x_(n+1−k)] with the largest
    k whose coverage 1 − 2 P(Binom(n, ½) < k) is at least `level`; below 6 values no k reaches
    95 % and the range [min, max] is returned with its coverage (75 % for 3 values, 94 % for 5).
    A percentile bootstrap says 95 % there too, but at n = 3 it is the same range: its stated
    level would be wrong. Returns (lo, hi, coverage); NaNs for no values."""
    a = np.sort(finite(x))
    n = len(a)
    if n == 0:
        return math.nan, math.nan, math.nan
    def cover(k):
        return 1 - 2 * sum(math.comb(n, i) for i in range(k)) / 2 ** n
    k = 1
    while k + 1 <= (n + 1) // 2 and cover(k + 1) >= level:
        k += 1
    return float(a[k - 1]), float(a[n - k]), float(cover(k))


def paired_difference(reference: Sequence[float], candidate: Sequence[float],
                      ref_seeds: Sequence[int], cand_seeds: Sequence[int],
                      level: float = LEVEL) -> PairedDifference:
    """The candidate's effect seed by seed: median of candidate − reference over the seeds both
    ran, with its distribution-free interval (median_interval). A seed prepares the same
    spheroids for both settings, so the seed-to-seed spread that the difference of medians
    carries cancels in each pair; a pair missing either run (or a seed run twice on a side) is
    left out."""
    ra, rb = np.asarray(list(reference), dtype=float), np.asarray(list(candidate), dtype=float)
    if len(ra) != len(ref_seeds) or len(rb) != len(cand_seeds):
        raise ValueError("one seed per run on each side")
    sa, sb = list(ref_seeds), list(cand_seeds)
    both = [s for s in dict.fromkeys(sa) if sa.count(s) == 1 and sb.count(s) == 1]
    d = np.array([rb[sb.index(s)] - ra[sa.index(s)] for s in both], dtype=float)
    d = d[np.isfinite(d)]
    if len(d) == 0:
        return PairedDifference(math.nan, math.nan, math.nan, math.nan, math.nan, 0, 0, 0)
    lo, hi, coverage = median_interval(d, level)
    sd = float(np.std(d, ddof=1)) if len(d) > 1 else math.nan
    return PairedDifference(float(np.median(d)), lo, hi, coverage, sd, len(d),
                            int((d > 0).sum()), int((d < 0).sum()))


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
