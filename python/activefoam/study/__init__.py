"""Studies as files: a TOML study (base spec, grids, seeds, preset) run through foamd, resumably,
and reported from the store alone (docs/usage.md has the format and the commands).

    python3 -m activefoam.study run studies/fig14-reduced.toml      # submit what is missing, wait
    python3 -m activefoam.study report studies/fig14-reduced.toml   # figure + tables from the store
    python3 -m activefoam.study report FILE --from-data DIR          # ... from committed data
    python3 -m activefoam.study run|report FILE --with-data DIR      # store + an earlier one's data
    python3 -m activefoam.study save-store DIR | restore-store DIR   # carry a store across machines
    python3 -m activefoam.study verdicts studies/verdicts.toml --data DIR --out DIR
    python3 -m activefoam.study power STUDY --data DIR ...           # what its seeds can resolve

(`foam-study` is the same command, installed with the package.)

A run of a study is one (grid point, seed). Its jobs carry the tag `study:NAME`; a job belongs
to a run when foamd's engine reads both the same: the run's spec as foamd resolves it (the base,
the study's keys, every default and preset value filled in) and the job's record as the engine
reads it today (keys renamed, retired or added since it was stored read as the engine's key
table says) agree on every key but the labels (the preset's name, the accuracy targets). So
rerunning `run` submits only the runs that have no job yet, or whose job was cancelled or failed
for a reason other than the simulation itself (an engine error, a lost worker). A run that
failed in the simulation (non-finite, volume drift, interpenetration, ...) is a result — the
supplement's hatched cells — and is not run again unless `--retry-failed` (`--retry-kinds
preparation-failed`: only the runs that failed so). A job of the study that is no run of the
file as it is now (an earlier version's [spec], grid or seeds) is named when it is queued or
running, and cancelled with `--cancel-stale`. A run that failed in the simulation is rerun once
with other numerics (tag `diag:NAME`): an interpenetration with the remesher's keep-out at the
interpenetration guard's depth, any other failure of the step at the next finer step after the
run's preset (`standard` → `reference` → Δt 0.1 s); a study file's [[diagnose]] tables replace
these, `[study] diagnose = false` turns them off. The report says whether the rerun ran past the
failure (then the failure is those numerics', not the point's, and the verdict table's `failed`
leaves it out). Exit codes: 0 done, 1 some runs failed, 2 bad study file or spec, or a file that
cannot be read or written (named), 3 foamd unreachable, 4 token refused, 130 interrupted (the
jobs go on in foamd; rerun to follow them).

The modules, each importing only those before it: outputs (files written whole or not at all),
studyfile (the format), matching (jobs to runs), submission (submit, wait), data (collect,
load, derive the metrics), tables, power, fitness, report (figures), verdicts (the trend
statements), store_copy (save-store, restore-store) and cli.
"""

from activefoam.study.studyfile import (FITNESS_METRICS, MAX_ATTEMPTS, MAX_RUNS, METRICS,
                                        SAMPLE_COLUMNS, SIMULATION_FAILURES, Diagnosis, Run,
                                        Share, Study, StudyError, builtin_diagnoses, load,
                                        shown_metrics)
from activefoam.study.matching import NOOP_TEXT, Carried, carried_runs, run_diagnoses
from activefoam.study.submission import (cancel_stale, live_stale_jobs, submit_diagnoses,
                                         submit_missing, wait)
from activefoam.study.data import Data, collect, derive_metrics, load_data, study_radius
from activefoam.study.tables import (failed_runs_markdown, summary_markdown, summary_table,
                                     unsaturated_fits_markdown)
from activefoam.study.fitness import (fitness_calibration, fitness_paired, fitness_table,
                                      render_fitness)
from activefoam.study.report import render
from activefoam.study.cli import main

__all__ = ["FITNESS_METRICS", "MAX_ATTEMPTS", "MAX_RUNS", "METRICS", "NOOP_TEXT", "SAMPLE_COLUMNS",
           "SIMULATION_FAILURES", "Carried", "Data", "Diagnosis", "Run", "Share", "Study",
           "StudyError", "builtin_diagnoses", "cancel_stale", "carried_runs", "collect",
           "derive_metrics", "failed_runs_markdown", "fitness_calibration", "fitness_paired",
           "fitness_table", "live_stale_jobs", "load", "load_data", "main", "render",
           "render_fitness", "run_diagnoses", "shown_metrics", "study_radius",
           "submit_diagnoses", "submit_missing", "summary_markdown", "summary_table",
           "unsaturated_fits_markdown", "wait"]
