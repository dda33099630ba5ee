"""How large an effect a trend verdict can resolve with n seeds a point (ensembles sized from the
measured spread).

A verdict (activefoam.trends.trend) calls a trend *agrees* when the bootstrap interval of the
difference of medians excludes 0 on the supplement's side. With few seeds that needs an effect
several times the seed-to-seed spread: with 3 runs a side the interval excludes 0 only when the
two ensembles do not overlap at all (the percentile bootstrap's 2.5 % quantile is then min(high)
− max(low)), which two equal ensembles do with probability 1/20. This module measures, by
simulation with the verdict's own rule, the smallest effect that `agrees` with a given
probability (80 % by default), in units of the spread σ; and for the "no change within ±band"
statements, the probability that two equal ensembles are judged *agrees*.

The ensembles are modelled as normal with σ = IQR / 1.349 (the IQR of a normal), the IQR
measured on the reduced base point. Run it on a study's data:

    python3 -m activefoam.study power STUDY.toml --data DIR --point KEY=VALUE [...] --out FILE.md
"""

from __future__ import annotations

import argparse
import math
import sys
from typing import Any, Dict, List, Optional, Sequence

import numpy as np

from activefoam import trends
from activefoam.study.data import load_data
from activefoam.study.matching import _py
from activefoam.study.outputs import write_text
from activefoam.study.studyfile import FITNESS_METRICS, _same, load

IQR_OF_NORMAL = 1.3489795  # the IQR of a standard normal


def agree_probability(n: int, effect_sigma: float, expect: str = "increase",
                      band_sigma: float = 0.0, trials: int = 400, n_boot: int = 2000,
                      seed: int = 1) -> float:
    """P(verdict = agrees) for two normal ensembles of n runs of spread σ = 1, the high one
    shifted by effect_sigma, judged by activefoam.trends.trend (with n_boot resamples)."""
    rng = np.random.default_rng(seed)
    hits = 0
    for _ in range(trials):
        low = rng.normal(0.0, 1.0, n)
        high = rng.normal(effect_sigma, 1.0, n)
        d = trends.diff_of_medians(low, high, n_boot=n_boot, seed=int(rng.integers(1 << 31)))
        if expect == "none":
            ok = -band_sigma <= d.lo and d.hi <= band_sigma
        else:
            sign = 1 if expect == "increase" else -1
            ok = sign * d.lo > 0 and sign * d.hi > 0
        hits += ok
    return hits / trials


def detectable_effect(n: int, power: float = 0.8, trials: int = 400, step: float = 0.25,
                      largest: float = 12.0) -> float:
    """The smallest effect, in σ, on a grid of `step`, that an increase verdict calls *agrees*
    with probability ≥ power; inf if none up to `largest`."""
    e = step
    while e <= largest + 1e-9:
        if agree_probability(n, e, trials=trials) >= power:
            return e
        e += step
    return math.inf


def rule_pass_probability(n: int, metrics: int = 1, trials: int = 20000, seed: int = 1) -> float:
    """P(the fitness rule calls two equal ensembles fit): n normal runs a side, `metrics`
    independent metrics, each judged |Δ median| < IQR/2 (activefoam.trends.rule_ratios)."""
    rng = np.random.default_rng(seed)
    a = rng.normal(size=(trials, n, metrics))
    b = rng.normal(size=(trials, n, metrics))
    return float((np.nanmax(trends.rule_ratios(a, b, min_seeds=1), axis=1) < 1).mean())


def calibrated_power(n: int, shift_sigma: float, metrics: int = 8, shifted: int = 1,
                     trials: int = 200, level: float = 0.05, max_splits: int = 2000,
                     paired: bool = True, rho: float = 0.0, seed: int = 1) -> float:
    """P(the calibrated fitness test finds a difference, p < level): n runs a side of
    `metrics` independent normal metrics, the candidate's first `shifted` moved by shift_sigma σ.
    Paired: run i of both sides shares seed i, correlated by rho (activefoam.trends.
    fitness_permutation relabels within the pairs); else two independent ensembles."""
    rng = np.random.default_rng(seed)
    hits = 0
    seeds = list(range(n)) if paired else None
    for _ in range(trials):
        ref = rng.normal(size=(n, metrics))
        cand = rho * ref + math.sqrt(1 - rho * rho) * rng.normal(size=(n, metrics)) if paired \
            else rng.normal(size=(n, metrics))
        cand[:, :shifted] += shift_sigma
        null = trends.fitness_permutation(ref, cand, seeds, seeds, max_splits=max_splits,
                                          seed=int(rng.integers(1 << 31)))
        hits += null.p_value < level
    return hits / trials


_PAIRED_SHIFT_CACHE: Dict[tuple, float] = {}


def paired_detectable_shift(n: int, metrics: int = 8, power: float = 0.8, level: float = 0.05,
                            trials: int = 200, largest: float = 8.0, seed: int = 1) -> float:
    """The shift of one metric, in units of the SD of its within-seed differences, that the
    calibrated fitness test (activefoam.trends.fitness_permutation on n seed pairs, min-p over
    `metrics` metrics) finds at p < level with probability `power`: normal, independent
    differences; bisection to 0.05 σ on common random draws. inf when n pairs cannot reach
    p < level at all or no shift up to `largest` does: one metric's least p is 2/2ⁿ (n ≤ 5 at 5 %
    returns at once), and with m metrics each one's extreme labelling ties there, so the least
    p is about 2m/2ⁿ (eight metrics: n ≤ 8, found by the simulation)."""
    key = (n, metrics, power, level, trials, largest, seed)
    if key in _PAIRED_SHIFT_CACHE:
        return _PAIRED_SHIFT_CACHE[key]
    if 2 / 2 ** n >= level:
        _PAIRED_SHIFT_CACHE[key] = math.inf
        return math.inf
    rng = np.random.default_rng(seed)
    draws = rng.normal(size=(trials, n, metrics))
    perm_seeds = [int(x) for x in rng.integers(1 << 31, size=trials)]
    zero, ids = np.zeros((n, metrics)), list(range(n))

    def found(shift: float) -> float:
        hits = 0
        for d, ps in zip(draws, perm_seeds):
            cand = d.copy()
            cand[:, 0] += shift
            hits += trends.fitness_permutation(zero, cand, ids, ids, seed=ps).p_value < level
        return hits / trials

    if found(largest) < power:
        _PAIRED_SHIFT_CACHE[key] = math.inf
        return math.inf
    lo, hi = 0.0, largest
    while hi - lo > 0.05:
        mid = (lo + hi) / 2
        lo, hi = (lo, mid) if found(mid) >= power else (mid, hi)
    _PAIRED_SHIFT_CACHE[key] = hi
    return hi


def spread(values: Sequence[float]) -> float:
    """σ of a normal with the values' IQR."""
    return trends.iqr(values) / IQR_OF_NORMAL


def table(values_by_metric: Dict[str, Sequence[float]], seeds: Sequence[int] = (3, 5),
          power: float = 0.8, band_rel: float = 0.25, trials: int = 400) -> List[Dict]:
    """Per metric: the median, σ, and for each n the detectable effect (absolute and relative to
    the median) and the probability that a 'no change within ±band_rel of the median' statement
    is judged *agrees* when nothing changes."""
    k = {n: detectable_effect(n, power, trials) for n in seeds}
    rows = []
    for m, vals in values_by_metric.items():
        med, s = trends.median(vals), spread(vals)
        row: Dict = {"metric": m, "runs": len(trends.finite(vals)), "median": med, "sigma": s}
        for n in seeds:
            row[f"effect_{n}"] = k[n] * s
            row[f"effect_{n}_rel"] = k[n] * s / abs(med) if med else math.nan
            band = band_rel * abs(med) / s if s > 0 else math.inf
            row[f"none_agrees_{n}"] = (agree_probability(n, 0.0, "none", band, trials)
                                       if math.isfinite(band) else 1.0)
        rows.append(row)
    return rows


def fitness_rule_table(seeds: Sequence[int] = (3, 5, 10, 20, 30),
                       shifts: Sequence[float] = (1, 2, 3, 100), metrics: int = 8,
                       trials: int = 400) -> List[str]:
    """Markdown: what the fitness rule gives equal ensembles, and how often the calibrated test
    finds a shift of one metric or of all of them (normal, independent metrics)."""
    lines = ["| runs a side | P(rule calls equal numerics fit), one metric | "
             f"{metrics} independent metrics |", "|---|---|---|"]
    for n in seeds:
        lines.append(f"| {n} | {rule_pass_probability(n):.3f} | "
                     f"{rule_pass_probability(n, metrics):.4f} |")
    cases = [(5, False, 0.0), (5, True, 0.0), (10, False, 0.0), (10, True, 0.0),
             (10, True, 0.8)]
    lines += ["", f"P(calibrated p < 0.05): one of {metrics} metrics moved by k σ (all {metrics} "
              "moved in the last column)", "",
              "| runs a side | relabelled | seed-to-seed correlation of paired runs | " +
              " | ".join(f"k = {k:g}" for k in (0.0,) + tuple(shifts)) +
              " | all moved, k = 2 |", "|---|---|---|" + "---|" * (len(shifts) + 2)]
    for n, paired, rho in cases:
        cells = [calibrated_power(n, k, metrics, 1, trials, paired=paired, rho=rho)
                 for k in (0.0,) + tuple(shifts)]
        cells.append(calibrated_power(n, 2.0, metrics, metrics, trials, paired=paired, rho=rho))
        lines.append(f"| {n} | {'within seed pairs' if paired else 'free splits'} | "
                     f"{rho:g} | " + " | ".join(f"{c:.2f}" for c in cells) + " |")
    return lines


def pair_divergence(runs: Any, samples: Any, arm_keys: Sequence[str], times: Sequence[float],
                    column: str = "theta_deg", tolerance_s: float = 120.0) -> List[Dict]:
    """How long the two runs of one seed under two numerics stay together: for each time, over
    the seeds that ran both arms (the two values of `arm_keys` among `runs`' succeeded runs),
    the correlation across seeds of the arms' `column` at that time (the sample nearest to it,
    within `tolerance_s`; a run without one is left out there), the median |difference| within a
    seed, and the spread (SD) across seeds of the first setting in sorted order. Seeds with other
    than one run of each setting are left out. Pairing a fitness test's runs by seed helps a
    metric only while the correlation is high; with 5 seeds a correlation of unrelated runs
    still ranges over about ±0.9."""
    import pandas as pd
    ok = runs[runs["state"] == "succeeded"].copy()
    ok["_arm"] = ok[list(arm_keys)].astype(str).agg("|".join, axis=1)
    arms = sorted(set(ok["_arm"]))
    if len(arms) != 2:
        raise ValueError(f"{', '.join(arm_keys)}: {len(arms)} settings among the runs, not 2")
    by_job = {j: g.sort_values("t_s") for j, g in samples.groupby("job_id")}
    rows = []
    for t in times:
        a, b = [], []
        for _, g in ok.groupby("seed"):
            if sorted(g["_arm"]) != sorted(arms):
                continue
            v = {}
            for _, r in g.iterrows():
                q = by_job.get(r["job_id"])
                if q is None or not len(q):
                    break
                near = int((q["t_s"] - t).abs().argmin())
                if abs(float(q["t_s"].iloc[near]) - t) > tolerance_s:
                    break
                v[r["_arm"]] = float(q[column].iloc[near])
            if len(v) == 2:
                a.append(v[arms[0]])
                b.append(v[arms[1]])
        xa, xb = np.array(a), np.array(b)
        corr = float(pd.Series(xa).corr(pd.Series(xb))) if len(xa) > 2 else math.nan
        rows.append({"t_s": t, "seeds": len(xa), "corr": corr,
                     "median_abs_diff": float(np.median(np.abs(xa - xb))) if len(xa) else math.nan,
                     "sd_seeds": float(np.std(xa, ddof=1)) if len(xa) > 1 else math.nan})
    return rows


def _value(text: str):
    if text in ("true", "True", "false", "False"):
        return text in ("true", "True")
    try:
        return float(text)
    except ValueError:
        return text


def main(argv: Optional[Sequence[str]] = None) -> int:
    ap = argparse.ArgumentParser(prog="python3 -m activefoam.study power", description=__doc__.split(
        "\n\n")[0])
    ap.add_argument("study", nargs="?", help="the study file whose data is read")
    ap.add_argument("--data", help="its report's data folder")
    ap.add_argument("--fitness-rule", action="store_true",
                    help="instead: what the fitness rule and its calibrated reading give on "
                    "synthetic ensembles (no study needed)")
    ap.add_argument("--pairs", metavar="KEY[,KEY]",
                    help="instead: how long the two runs of a seed under the two settings of "
                    "these keys stay together (θ at --times)")
    ap.add_argument("--times", default="600,1800,3600,7200,10800,14400",
                    help="with --pairs: the times (s)")
    ap.add_argument("--point", action="append", default=[], metavar="KEY=VALUE",
                    help="the runs to take (the base point), repeatable")
    ap.add_argument("--metrics", default=",".join(FITNESS_METRICS + ["mixing_time_s"]))
    ap.add_argument("--trials", type=int, default=400)
    ap.add_argument("--out", required=True, help="markdown table to write")
    args = ap.parse_args(argv)
    if args.fitness_rule:
        lines = ["The fitness rule |Δ median| < IQR/2 on synthetic normal ensembles (pass "
                 f"rates from 20 000 draws, the calibrated test's from {args.trials} trials a "
                 f"cell; `python3 -m activefoam.study power --fitness-rule --trials {args.trials} "
                 "--out FILE`)", ""] + fitness_rule_table(
                     trials=args.trials)
        write_text(args.out, "\n".join(lines) + "\n")
        print(args.out)
        return 0
    if not args.study or not args.data:
        ap.error("a study file and --data are needed (or --fitness-rule)")
    study = load(args.study)
    data = load_data(study, args.data)
    if args.pairs:
        keys = [k for k in args.pairs.split(",") if k]
        missing = [k for k in keys if k not in data.runs]
        if missing:
            print(f"error: --pairs: no column {missing[0]!r} in the data", file=sys.stderr)
            return 2
        try:
            rows = pair_divergence(data.runs, data.samples, keys,
                                   [float(t) for t in args.times.split(",") if t])
        except ValueError as e:
            print(f"error: --pairs: {e}", file=sys.stderr)
            return 2
        lines = [f"The two runs of a seed under the two settings of {', '.join(keys)}: "
                 f"{study.name} (`python3 -m activefoam.study power {args.study} --data {args.data} "
                 f"--pairs {args.pairs} --out FILE`)", "",
                 "| t (h) | seeds | correlation of θ across seeds | median \\|θ₁ − θ₂\\| "
                 "within a seed (°) | SD of θ across seeds (°) |", "|---|---|---|---|---|"]
        for r in rows:
            lines.append(f"| {r['t_s'] / 3600:.2g} | {r['seeds']} | {r['corr']:.2f} | "
                         f"{r['median_abs_diff']:.2f} | {r['sd_seeds']:.2f} |")
        write_text(args.out, "\n".join(lines) + "\n")
        print(args.out)
        return 0
    runs = data.runs[data.runs["state"] == "succeeded"]
    for p in args.point:
        key, _, value = p.partition("=")
        if key not in runs:
            print(f"error: --point {p}: no column {key!r} in the data", file=sys.stderr)
            return 2
        runs = runs[[_same(_py(v), _value(value)) for v in runs[key]]]
    metrics = [m for m in args.metrics.split(",") if m]
    rows = table({m: list(runs[m]) for m in metrics}, trials=args.trials)
    lines = [f"Seed-to-seed spread and resolvable effects: {study.name}, "
             f"{', '.join(args.point) or 'all runs'} ({len(runs)} runs)", "",
             "| metric | runs | median | σ (IQR/1.349) | effect resolved 80 %, 3 seeds | "
             "5 seeds | P(no change ±25 % agrees), 3 seeds | 5 seeds |",
             "|---|---|---|---|---|---|---|---|"]
    for r in rows:
        lines.append(f"| {r['metric']} | {r['runs']} | {r['median']:.4g} | {r['sigma']:.3g} | "
                     f"{r['effect_3']:.3g} ({100 * r['effect_3_rel']:.1f} %) | "
                     f"{r['effect_5']:.3g} ({100 * r['effect_5_rel']:.1f} %) | "
                     f"{r['none_agrees_3']:.2f} | {r['none_agrees_5']:.2f} |")
    write_text(args.out, "\n".join(lines) + "\n")
    print(args.out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
