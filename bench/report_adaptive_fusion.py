#!/usr/bin/env python3
"""Turns the CSVs of bench/study_adaptive_fusion into a Markdown table with totals (printed).

    python3 bench/report_adaptive_fusion.py docs/study/adaptive-fusion-*.csv
"""
import csv
import sys


def main():
    rows = [r for path in sys.argv[1:] for r in csv.DictReader(open(path))]
    rows.sort(key=lambda r: (float(r["pa_reduced"]), float(r["l_eta_reduced"]), int(r["seed"])))
    finished = sum(r["outcome"] == "finished" for r in rows)
    would_fail = [r for r in rows if r["first_rejection_kind"] not in ("", "none")]
    print("| p_a r/2γ | L_η/r | seed | outcome | t end (s) | steps | rejected | shortest Δt (s) "
          "| without adaptive Δt: ends at | θ end (°) | wall (s) |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    for r in rows:
        first = ("runs through" if r["first_rejection_kind"] in ("", "none") else
                 f"{r['first_rejection_kind']} at t = {float(r['first_rejection_t_s']):.0f} s")
        print(f"| {r['pa_reduced']} | {r['l_eta_reduced']} | {r['seed']} | {r['outcome']} | "
              f"{float(r['t_end_s'] or 'nan'):.0f} | {r['steps']} | {r['steps_rejected']} | "
              f"{float(r['dt_min_s'] or 'nan'):g} | {first} | "
              f"{float(r['theta_end_deg'] or 'nan'):.1f} | {float(r['wall_s'] or 'nan'):.0f} |")
    print()
    print(f"{len(rows)} runs: {finished} finished, {len(rows) - finished} failed; "
          f"{len(would_fail)} would have failed without the adaptive time step; "
          f"{sum(int(r['steps_rejected'] or 0) for r in rows)} rejected tries in all.")


if __name__ == "__main__":
    main()
