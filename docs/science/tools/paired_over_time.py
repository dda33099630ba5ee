#!/usr/bin/python3
"""A fitness study's seed pairs over time: when does a numerics difference appear, and does it grow?

A fitness report (`scripts/study.sh report`) judges the runs at their end and over their last
hour. Where both settings ran the same seeds, each seed's two runs start from the same prepared
spheroids, so their difference at each sample time is the numerics' effect along the run, free
of the seed-to-seed spread. This prints, per sample time asked for, each seed's candidate −
reference difference of the sampled metrics (samples.csv.gz of the report's data folder) and
their median, as markdown:

    docs/science/tools/paired_over_time.py docs/science/mesh-fitness/data \
        --key numerics.triangles_per_cell --reference 1280 --candidate 320 \
        [--metrics shape_index_mean,unique_contacts_norm,theta_deg] [--times 0,600,3600,7200]

A time at which a seed lacks either run's sample is left blank for that seed. Only succeeded
runs enter.
"""
import argparse
import sys

import pandas as pd


def number(text):
    value = float(text)
    return int(value) if value.is_integer() else value


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("data", help="a report's data folder (runs.csv, samples.csv.gz)")
    parser.add_argument("--key", required=True, help="the settings key the study varies")
    parser.add_argument("--reference", required=True, type=number)
    parser.add_argument("--candidate", required=True, type=number)
    parser.add_argument("--metrics", default="theta_deg,shape_index_mean,unique_contacts_norm")
    parser.add_argument("--times", default="0,600,1800,3600,5400,7200",
                        help="sample times in s, comma-separated")
    args = parser.parse_args(argv)

    runs = pd.read_csv(f"{args.data}/runs.csv")
    samples = pd.read_csv(f"{args.data}/samples.csv.gz")
    if args.key not in runs.columns:
        sys.exit(f"paired_over_time: runs.csv has no column {args.key!r}")
    metrics = [m for m in args.metrics.split(",") if m]
    missing = [m for m in metrics if m not in samples.columns]
    if missing:
        sys.exit(f"paired_over_time: samples have no {', '.join(missing)} "
                 f"(they have: {', '.join(c for c in samples.columns if c not in ('job_id', 't_s'))})")
    times = [number(t) for t in args.times.split(",") if t]

    runs = runs[runs["state"] == "succeeded"][["job_id", "seed", args.key]]
    runs = runs[runs[args.key].isin([args.reference, args.candidate])]
    data = samples.merge(runs, on="job_id")
    data = data[data["t_s"].isin(times)]
    seeds = sorted(set(runs[runs[args.key] == args.reference]["seed"]) &
                   set(runs[runs[args.key] == args.candidate]["seed"]))
    if not seeds:
        sys.exit("paired_over_time: no seed ran both settings to success")
    data = data[data["seed"].isin(seeds)]  # the reference's median over the pairs alone

    print(f"{args.key} = {args.candidate} − {args.reference}, seeds {', '.join(map(str, seeds))}\n")
    for metric in metrics:
        table = data.pivot_table(index=["t_s", "seed"], columns=args.key, values=metric)
        diff = (table[args.candidate] - table[args.reference]).unstack("seed")
        print(f"### {metric}\n")
        print("| t (s) | reference median | " + " | ".join(f"seed {s}" for s in seeds) +
              " | median Δ |")
        print("|---|---|" + "---|" * len(seeds) + "---|")
        for t in times:
            if t not in diff.index:
                continue
            ref = table[args.reference].xs(t, level="t_s")
            cells = [f"{diff.at[t, s]:+.4g}" if s in diff.columns and pd.notna(diff.at[t, s])
                     else "" for s in seeds]
            print(f"| {t} | {ref.median():.4g} | " + " | ".join(cells) +
                  f" | {diff.loc[t].median():+.4g} |")
        print()
    return 0


if __name__ == "__main__":
    sys.exit(main())
