"""docs/science/tools/paired_over_time.py on synthetic seed pairs with known differences."""
import subprocess
import sys
from pathlib import Path

import pandas as pd

TOOL = Path(__file__).resolve().parents[2] / "docs" / "science" / "tools" / "paired_over_time.py"


def data(tmp_path, offsets, failed=()):
    """Runs at key 1280 (reference) and 320 for each seed of `offsets`; the candidate's
    shape_index_mean is the reference's plus offsets[seed] · t / 100 (0 at t = 0)."""
    d = tmp_path / "data"
    d.mkdir()
    runs, samples = [], []
    for seed, offset in offsets.items():
        for mesh in (1280, 320):
            job = f"j-{mesh}-{seed}"
            state = "failed" if (mesh, seed) in failed else "succeeded"
            runs.append({"run": len(runs), "numerics.triangles_per_cell": mesh, "seed": seed,
                         "job_id": job, "state": state})
            for t in (0, 100, 200):
                base = 5.0 + 0.1 * seed + 0.001 * t
                value = base + (offset * t / 100 if mesh == 320 else 0.0)
                samples.append({"job_id": job, "t_s": t, "shape_index_mean": value})
    pd.DataFrame(runs).to_csv(d / "runs.csv", index=False)
    pd.DataFrame(samples).to_csv(d / "samples.csv.gz", index=False)
    return d


def run(d, *extra):
    out = subprocess.run([sys.executable, str(TOOL), str(d), "--key",
                          "numerics.triangles_per_cell", "--reference", "1280", "--candidate",
                          "320", "--metrics", "shape_index_mean", "--times", "0,100,200",
                          *extra], capture_output=True, text=True)
    return out.returncode, out.stdout, out.stderr


def rows(stdout):
    table = [line for line in stdout.splitlines() if line.startswith("| ") and
             not line.startswith("| t (s)")]
    return {int(r.split("|")[1]): [c.strip() for c in r.split("|")[2:-1]] for r in table}


def test_each_seeds_difference_and_their_median_at_each_time(tmp_path):
    code, out, err = run(data(tmp_path, {1: 0.01, 2: 0.03, 3: -0.02}))
    assert code == 0, err
    table = rows(out)
    assert table[0][1:] == ["+0", "+0", "+0", "+0"]
    assert table[100][1:] == ["+0.01", "+0.03", "-0.02", "+0.01"]
    assert table[200][1:] == ["+0.02", "+0.06", "-0.04", "+0.02"]
    # the reference's median at t = 200: seeds' bases 5.1, 5.2, 5.3 plus 0.2
    assert table[200][0] == "5.4"


def test_a_seed_whose_run_failed_is_no_pair(tmp_path):
    code, out, err = run(data(tmp_path, {1: 0.01, 2: 0.03}, failed={(320, 2)}))
    assert code == 0, err
    assert "seeds 1\n" in out and "seed 2" not in out
    assert rows(out)[100] == ["5.2", "+0.01", "+0.01"]  # seed 2's reference (5.3) left out


def test_a_metric_the_samples_lack_is_named(tmp_path):
    code, _, err = run(data(tmp_path, {1: 0.01}), "--metrics", "theta_deg")
    assert code != 0 and "theta_deg" in err and "shape_index_mean" in err
