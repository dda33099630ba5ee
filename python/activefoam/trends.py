"""Ensemble statistics of studies: medians, IQRs, bootstrap intervals and the verdict rules.

Everything a study report concludes goes through these few functions, so that the rules are
written once and tested on synthetic data with known answers (python/tests/test_trends.py):

- `diff_of_medians(a, b)`: median(b) − median(a) with a percentile-bootstrap interval (each
  ensemble resampled with replacement, independently; a fixed generator seed, so a report is
  reproducible from its data).
- `fitness(a_ref, b)`: a candidate ensemble is *fit* against a reference ensemble when the
  difference of medians is below half the seed-to-seed IQR (the mean of the two ensembles'
  IQRs): the preset-fitness rule of docs/science/presets.md.
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
