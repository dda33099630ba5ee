#!/usr/bin/env python3
"""The table of across.sh's runs: how each ended, its volume errors, rescues and redone steps.
    /usr/bin/python3 docs/science/fig8-pa1-probe/scripts/across_table.py [FOLDER]   (default across/)
"""
import glob
import json
import os
import re
import sys

import pandas as pd

here = os.path.dirname(os.path.abspath(__file__))
folder = sys.argv[1] if len(sys.argv) > 1 else os.path.join(here, "..", "across")
STEP = {"b05": "0.5 s / 1e-2, within prisms", "b025": "0.25 s / 1e-3, within prisms",
        "l025": "0.25 s / 1e-3, the law"}
rows = []
for d in sorted(glob.glob(os.path.join(folder, "*-a*-s*"))):
    if not os.path.isdir(d):
        continue
    name = os.path.basename(d)
    k, rest = name.split("-a", 1)
    alpha, seed = rest.split("-s")
    summary = json.load(open(os.path.join(d, "summary.json")))
    df = pd.read_csv(os.path.join(d, "samples.csv"))
    ve = df.volume_error_max.abs() * 100
    log = open(os.path.join(d, "foam-run.log")).read().strip().splitlines()
    last = log[-1] if log else ""
    m = re.search(r"failed at t = ([\d.]+) s.*?: ([a-z-]+):", last)
    if m:
        end = f"failed at {float(m.group(1)):.0f} s: {m.group(2)}"
    elif "interrupted" in last:
        end = f"ran {df.t_s.iloc[-1]:.0f} s (stopped)"
    else:
        end = f"ran {df.t_s.iloc[-1]:.0f} s"
    rows.append({"step": STEP[k], "α": float(alpha), "seed": int(seed), "ended": end,
                 "volume error, largest (%)": round(ve.max(), 1),
                 "samples above 5 %": f"{int((ve > 5).sum())} of {len(df)}",
                 "rescued remeshes": summary.get("remesh_rescues"),
                 "steps redone": summary.get("steps_rejected")})
t = pd.DataFrame(rows).sort_values(["α", "step", "seed"])
print("| " + " | ".join(t.columns) + " |")
print("|" + "---|" * len(t.columns))
for _, r in t.iterrows():
    print("| " + " | ".join(str(v) for v in r.values) + " |")
