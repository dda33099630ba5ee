"""A fitness study ([fitness]: one key's settings against a reference): the rule's verdict per
candidate and metric, the calibrated permutation test, the seed-by-seed differences, and
fitness.md with its θ(t) bands.
"""

from __future__ import annotations

import math
import textwrap
from pathlib import Path
from typing import Any, Dict, List, Optional, Sequence, Tuple

from activefoam import trends
from activefoam.study import power
from activefoam.study.data import Data, _series
from activefoam.study.outputs import savefig, to_csv, write_text
from activefoam.study.studyfile import SIMULATION_FAILURES, Study, _same
from activefoam.study.tables import _markdown, _point_label, _runs_of_point


def _fitness_pairs(study: Study, runs: Any) -> List[Tuple[Dict[str, Any], Any, Any]]:
    """(candidate point, its reference runs, its own runs) for every candidate grid point."""
    import pandas as pd
    f = study.fitness or {}
    key, ref = f["key"], f["reference"]
    keys = study.swept_keys()
    others = [k for k in keys if k != key]
    points = [p for p in study.points() if key in p]
    refs = [p for p in points if _same(p[key], ref)]
    out = []
    for cand in points:
        if _same(cand[key], ref):
            continue
        matching = [r for r in refs
                    if all(_same(r[k], cand.get(k)) for k in others if k in r)]
        ref_runs = pd.concat([_runs_of_point(runs, r, keys) for r in matching]) if matching \
            else runs.iloc[0:0]
        out.append((cand, ref_runs, _runs_of_point(runs, cand, keys)))
    return out


CALIBRATION_NOTE = """
**The rule's reading.** Two ensembles of equal numerics fail |Δ| < IQR/2 on one metric about
half the time with 5 runs a side (two thirds with 3), so on eight metrics the rule calls equal
numerics fit 0.2 % of the time with 5 seeds (independent metrics; 7 % with 10, 67 % with 30:
docs/science/power.md, "What the fitness rule can certify"). "Not fit" at these ensemble sizes
is therefore no evidence of a difference by itself. The calibrated line is a permutation test of
"the numerics change nothing": the runs are relabelled — each seed's two runs swapped or not
when both settings ran the same seeds (a seed prepares the same spheroids for both), or within
the seeds both ended when those pairs alone can reach p < 0.05 (a run without a partner left
out), else every split of the pooled runs — each metric's difference of means is ranked among its
relabellings, and the smallest rank over the metrics is compared with the same for every
relabelling (min-p: the metrics' correlations kept, no distribution assumed). p < 0.05 says
some metric differs more than relabelling the runs makes it; a larger p says no difference was
found, not that there is none.
"""


def _with_results(runs: Any, metrics: Sequence[str]) -> Any:
    """The runs the calibrated test reads: those with a result for some metric (a metric a run
    lacks is NaN and left out by the rule)."""
    return runs[runs[list(metrics)].notna().any(axis=1)]


def _seeds(runs: Any) -> Optional[List[int]]:
    return [int(x) for x in runs["seed"]] if "seed" in runs else None


def _calibration_runs(ref_ok: Any, cand_ok: Any, n_metrics: int) -> Tuple[Any, Any, bool]:
    """The runs the calibrated test relabels, and whether it relabels within seed pairs.

    Both sides on the same seeds: all of them, paired. Otherwise, where the seeds the two sides
    share form enough pairs for the paired test to reach p < 0.05 at all (its least p is about
    2m/2ⁿ with m metrics: n ≥ 9 for eight), those pairs only: a seed's two runs start from the
    same prepared spheroids, and a run whose seed has no partner (a reference that failed, a
    candidate seed the reference lacks) is left out rather than the pairing given up. Fewer
    shared seeds: every split of all the runs."""
    rs, cs = _seeds(ref_ok), _seeds(cand_ok)
    if rs is None or cs is None:
        return ref_ok, cand_ok, False
    if trends.is_paired(rs, cs):
        return ref_ok, cand_ok, True
    if len(set(rs)) != len(rs) or len(set(cs)) != len(cs):
        return ref_ok, cand_ok, False
    common = sorted(set(rs) & set(cs))
    if 2 * max(1, n_metrics) / 2 ** len(common) >= 0.05:
        return ref_ok, cand_ok, False
    keep = lambda r: r[r["seed"].astype(int).isin(common)]  # noqa: E731
    return keep(ref_ok), keep(cand_ok), True


def fitness_calibration(study: Study, runs: Any) -> Any:
    """Per candidate: the permutation test of "the numerics change nothing" over relabellings of
    the candidate's and its reference's runs (within each seed's pair when both ran the same
    seeds), each metric's own p, and the rule's numbers (activefoam.trends.fitness_permutation)."""
    import pandas as pd
    metrics = (study.fitness or {})["metrics"]
    rows = []
    for cand, ref_runs, cand_runs in _fitness_pairs(study, runs):
        ref_ok, cand_ok = _with_results(ref_runs, metrics), _with_results(cand_runs, metrics)
        label = _point_label(cand, study.fitness["key"])
        if len(ref_ok) < trends.MIN_SEEDS or len(cand_ok) < trends.MIN_SEEDS:
            rows.append({"candidate": label, "n_ref": len(ref_ok), "n": len(cand_ok)})
            continue
        n_ref_all, n_all = len(ref_ok), len(cand_ok)
        ref_ok, cand_ok, _ = _calibration_runs(ref_ok, cand_ok, len(metrics))
        null = trends.fitness_permutation(
            ref_ok[metrics].to_numpy(dtype=float), cand_ok[metrics].to_numpy(dtype=float),
            ref_seeds=_seeds(ref_ok), cand_seeds=_seeds(cand_ok))
        row = {"candidate": label, "n_ref": n_ref_all, "n": n_all,
               "n_relabelled_ref": len(ref_ok), "n_relabelled": len(cand_ok),
               "paired": null.paired, "relabellings": null.splits, "exact": null.exact,
               "p_value": null.p_value, "smallest_p": null.smallest_p,
               "most_different": metrics[null.most_metric] if null.most_metric >= 0 else "",
               "worst_ratio": null.worst,
               "worst_metric": metrics[null.worst_metric] if null.worst_metric >= 0 else "",
               "failures": null.failures, "metrics": null.metrics,
               "rule_pass_rate_equal": null.pass_rate}
        row.update({f"p_{m}": v for m, v in zip(metrics, null.p_metric)})
        rows.append(row)
    return pd.DataFrame(rows)


def fitness_table(study: Study, runs: Any) -> Any:
    """Per candidate grid point (fitness.key at another value than the reference) and metric:
    the difference of medians against the reference runs with its bootstrap 95 % interval, the
    seed-to-seed IQR and the verdict (fit: |Δ| < IQR/2). A candidate's reference runs are those
    of the reference points that agree with it on every other key they set: a grid of
    (key × α) is judged α by α, and a candidate from a second grid that also changes another
    setting (e.g. Δt with ε_CG) against the reference of the first."""
    import pandas as pd
    f = study.fitness or {}
    key, ref = f["key"], f["reference"]
    others = [k for k in study.swept_keys() if k != key]
    rows = []
    for cand, ref_runs, cand_runs in _fitness_pairs(study, runs):
        for m in f["metrics"]:
            fit = trends.fitness(ref_runs[m], cand_runs[m])
            row = {k: cand.get(k) for k in others}
            row.update({"candidate": _point_label(cand, key), key: cand[key], "reference": ref,
                        "metric": m, "median_ref": trends.median(ref_runs[m]),
                        "median": trends.median(cand_runs[m]), "diff": fit.diff.diff,
                        "diff_lo95": fit.diff.lo, "diff_hi95": fit.diff.hi,
                        "iqr": fit.iqr, "n_ref": fit.diff.n_a, "n": fit.diff.n_b,
                        "fit": {True: "yes", False: "no", None: "—"}[fit.fit],
                        "why": fit.why})
            rows.append(row)
    return pd.DataFrame(rows)


def fitness_paired(study: Study, runs: Any) -> Any:
    """Per candidate and metric, where the candidate and its reference ran the same seeds: the
    effect seed by seed (activefoam.trends.paired_difference): the median of candidate −
    reference within each seed's pair, its order-statistic interval with its exact coverage,
    how many pairs went up and down, and `found_80`: the shift of this metric alone that the
    calibrated test finds 80 % of the time with these pairs, from the differences' measured SD
    (activefoam.study.power.paired_detectable_shift; inf where the pairs cannot reach p < 0.05;
    NaN where the calibrated test did not relabel within seed pairs because the two sides'
    seeds differ). Candidates with fewer than MIN_SEEDS such pairs are left out."""
    import pandas as pd

    f = study.fitness or {}
    rows = []
    for cand, ref_runs, cand_runs in _fitness_pairs(study, runs):
        if "seed" not in ref_runs or "seed" not in cand_runs:
            continue
        rs, cs = [int(x) for x in ref_runs["seed"]], [int(x) for x in cand_runs["seed"]]
        calibrated_in_pairs = _calibration_runs(_with_results(ref_runs, f["metrics"]),
                                                _with_results(cand_runs, f["metrics"]),
                                                len(f["metrics"]))[2]
        for m in f["metrics"]:
            d = trends.paired_difference(ref_runs[m], cand_runs[m], rs, cs)
            if d.n < trends.MIN_SEEDS:
                continue
            k = (power.paired_detectable_shift(d.n, len(f["metrics"])) if calibrated_in_pairs
                 else math.nan)
            rows.append({"candidate": _point_label(cand, f["key"]), "metric": m,
                         "pairs": d.n, "paired_diff": d.diff, "paired_lo": d.lo,
                         "paired_hi": d.hi, "coverage": d.coverage, "higher": d.higher,
                         "lower": d.lower, "sd_diff": d.sd,
                         "found_80": k * d.sd if math.isfinite(k) else k})
    return pd.DataFrame(rows, columns=["candidate", "metric", "pairs", "paired_diff", "paired_lo",
                                       "paired_hi", "coverage", "higher", "lower", "sd_diff",
                                       "found_80"])


PAIRED_NOTE = """
**Seed by seed.** Where both settings ran the same seeds, each seed's two runs start from the
same prepared spheroids, so their difference is free of the seed-to-seed spread that the
difference of medians above carries: `paired_diff` is the median over the seeds of candidate −
reference, `higher` / `lower` the pairs that went up or down, and [`paired_lo`, `paired_hi`] a
distribution-free interval of that median (order statistics of the pairs' differences) with its
exact `coverage`: 95 % or more from 6 pairs on, the range of the differences below that (75 %
with 3 pairs, 94 % with 5), where a bootstrap would claim 95 % for the same range. An interval
that excludes 0 on one metric is not the calibrated verdict (eight metrics are read at once;
the min-p line above corrects for that); it says how large and how regular the effect is.
`found_80` is what the calibrated reading could have missed: the shift of that metric alone
(the others unshifted) that its test finds 80 % of the time with these pairs — 1.5 SDs of the
differences with 10 pairs and eight metrics (modelled as normal and independent;
`activefoam.study.power.paired_detectable_shift`), `inf` where the pairs cannot reach p < 0.05
at all (with eight metrics, 8 pairs or fewer: each metric's extreme labelling ties at the least
p, so the least p is about 2·8/2ⁿ), empty where the two sides' seeds differ and the test split
the runs freely. Its SD comes from the same few pairs (±25 % with 10, more with fewer): a "no
difference found" rules out shifts of about that size, not smaller ones.
"""


def _fitness_failures(study: Study, runs: Any) -> List[str]:
    """One line per reference and candidate point with runs that failed in the simulation: the
    seed, the failure's kind and the simulated time it ended at."""
    if "state" not in runs:
        return []
    f = study.fitness or {}
    import pandas as pd
    lines: List[str] = []
    points = []
    for cand, ref_runs, own in _fitness_pairs(study, runs):
        points += [("reference", f"{f['key']} = {f['reference']}", ref_runs),
                   ("candidate", _point_label(cand, f["key"]), own)]
    for role, label, r in points:
        bad = r[(r["state"] == "failed")
                & r.get("failure_kind", pd.Series("", index=r.index)).isin(SIMULATION_FAILURES)]
        if not len(bad):
            continue
        what = []
        for _, b in bad.sort_values("seed").iterrows() if "seed" in bad else bad.iterrows():
            kind = b.get("failure_kind") or "failed"
            t = b.get("t_end_s")
            at = f" at {t:,.0f} s".replace(",", " ") if pd.notna(t) else ""
            what.append(f"seed {int(b['seed'])} ({kind}{at})" if "seed" in b else f"{kind}{at}")
        line = f"- {role} `{label}`: {len(bad)} failed — " + ", ".join(what)
        if line not in lines:
            lines.append(line)
    return lines


def render_fitness(study: Study, data: Data, out: Path) -> List[Path]:
    import matplotlib.pyplot as plt
    import numpy as np
    f = study.fitness or {}
    table = fitness_table(study, data.runs)
    to_csv(table, out / "fitness.csv", index=False)
    verdicts = []
    for cand, g in table.groupby("candidate", sort=False) if len(table) else []:
        judged = g[g["fit"] != "—"]
        if len(judged) < len(g):
            verdicts.append((cand, f"- `{cand}`: not decided — "
                                   f"{len(g) - len(judged)} of {len(g)} metrics lack runs"))
        elif (judged["fit"] == "yes").all():
            verdicts.append((cand, f"- `{cand}`: **fit** — every difference of medians "
                                   f"is below half the seed-to-seed IQR"))
        else:
            bad = ", ".join(judged[judged["fit"] == "no"]["metric"])
            verdicts.append((cand, f"- `{cand}`: **not fit** — {bad}"))
    calibration = fitness_calibration(study, data.runs)
    to_csv(calibration, out / "fitness-calibration.csv", index=False)
    by_candidate = {c["candidate"]: c for _, c in calibration.iterrows()}
    lines = []
    for cand, verdict in verdicts:
        lines.append(verdict)
        c = by_candidate.get(cand)
        if c is None or "p_value" not in c or not (c["p_value"] == c["p_value"]):
            continue
        if c["p_value"] < 0.05:
            reading = (f"**a difference** (p < 0.05): {c['most_different']} differs more than "
                       "relabelling the runs makes it")
        elif c["smallest_p"] >= 0.05:
            reading = (f"no difference found, and none could be: the smallest p "
                       f"{int(c['relabellings'])} relabellings allow is {c['smallest_p']:.3g}")
        else:
            reading = ("no difference found (not: none exists; the shifts it finds 80 % of the "
                       "time: `found_80`, seed by seed below)")
        how = ("within each seed's pair" if c["paired"] else "splits of the pooled runs") + (
            "" if c["exact"] else ", a sample")
        if c["paired"] and (c.get("n_relabelled", c["n"]) < c["n"]
                            or c.get("n_relabelled_ref", c["n_ref"]) < c["n_ref"]):
            how += (f": the {int(c['n_relabelled'])} seeds both sides ended, "
                    f"{int(c['n_ref'] - c['n_relabelled_ref'])} reference and "
                    f"{int(c['n'] - c['n_relabelled'])} candidate runs without a partner left out")
        lines.append(
            f"  - calibrated: p = {c['p_value']:.3g} over {int(c['relabellings'])} "
            f"relabellings ({how}; min-p over {int(c['metrics'])} metrics), the most different "
            f"{c['most_different']} (its own p = {c['p_' + c['most_different']]:.3g}); the "
            f"rule's worst ratio |Δ|/(IQR/2) is {c['worst_ratio']:.3g} ({c['worst_metric']}) "
            f"and it calls {100 * c['rule_pass_rate_equal']:.1f} % of the relabellings fit — "
            f"{reading}")
    failed = _fitness_failures(study, data.runs)
    if failed:
        lines.append("\nRuns that failed in the simulation (a candidate's own failure disqualifies "
                     "it; a reference's is a failure of the reference step, and the candidates "
                     "are read against the references that ended):\n")
        lines += failed
    show = table.drop(columns=["why"]) if len(table) else table
    paired = fitness_paired(study, data.runs)
    to_csv(paired, out / "fitness-paired.csv", index=False)
    seed_by_seed = ("\n## Seed by seed\n\n" + _markdown(paired) + "\n" + PAIRED_NOTE
                    if len(paired) else "")
    write_text(
        out / "fitness.md",
        f"# {study.title}: fitness against `{f['key']} = {f['reference']}`\n\n"
        + "\n".join(lines) + "\n\n" + _markdown(show) + "\n" + CALIBRATION_NOTE
        + seed_by_seed)
    # θ(t) ensemble bands of each value of the key.
    fig, ax = plt.subplots(figsize=(7, 4))
    points = [p for p in study.points() if f["key"] in p]
    for c, p in zip(plt.cm.tab10(np.arange(len(points))), points):
        sel = _runs_of_point(data.runs, p, study.swept_keys())
        t, med, q25, q75 = _series(study, data, sel, "theta_deg")
        if len(t):
            ax.plot(t / 3600, med, color=c, label=f"{_point_label(p, f['key'])} (median, IQR "
                    f"over {int((sel['state'] == 'succeeded').sum())} seeds)")
            ax.fill_between(t / 3600, q25, q75, color=c, alpha=0.25, lw=0)
    ax.set(xlabel="t (h)", ylabel="θ (°)")
    # A study's title is often longer than the axes: wrapped, so that none of it is cut off.
    ax.set_title(textwrap.fill(f"{study.title}: θ(t) ensembles", 80), fontsize=9)
    ax.legend(fontsize=7)
    fig.tight_layout()
    savefig(fig, out / f"{study.name}-theta-bands.png", dpi=110)
    plt.close(fig)
    return [out / "fitness.csv", out / "fitness-calibration.csv", out / "fitness-paired.csv",
            out / "fitness.md",
            out / f"{study.name}-theta-bands.png"]
