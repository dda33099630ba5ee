#!/bin/bash
# The batch script of one foamd job on Slurm, as foamd's Slurm executor writes it into
# WORK_DIR/arrays/NAME/task.sh for every array it submits (server/slurm.cc, writeTaskScript).
# Kept here to read and adapt (module loads, scratch directories); foamd fills in the paths:
#
#   sbatch --parsable --array=0-N --job-name=foam-NAME --requeue \
#          --output=WORK_DIR/arrays/NAME/task-%a.out [--partition=P] [--slurm-sbatch-arg ...] \
#          WORK_DIR/arrays/NAME/task.sh
#
# Array task k runs the job on line k+1 of WORK_DIR/arrays/NAME/jobs. foam-run reads the
# resolved spec foamd stored (WORK_DIR/jobs/JOB/spec.json), writes and checkpoints into
# WORK_DIR/jobs/JOB/run (its stderr in WORK_DIR/jobs/JOB/run.log), and `foam report` sends the
# folder's samples, snapshots, progress and outcome to foamd (ReportTask, with the token),
# retrying for an hour while foamd is unreachable, then exits with foam-run's status. A
# requeued task finds the checkpoint and resumes; a task run again on a finished folder only
# reports it.
set -u
# The engine's OpenMP threads: the CPUs Slurm gave the task, not the node's.
export OMP_NUM_THREADS=${SLURM_CPUS_PER_TASK:-1}
ARRAY_DIR='/shared/foam/arrays/s-0123456789ab-1700000000'
WORK_DIR='/shared/foam'
JOB=$(sed -n "$((SLURM_ARRAY_TASK_ID + 1))p" "$ARRAY_DIR/jobs")
RUN="$WORK_DIR/jobs/$JOB"
exec '/opt/activefoam/bin/foam' --server 'foamd.example.org:50051' \
  --token-file '/shared/foam/token' --tls-ca '/shared/foam/foamd-ca.pem' \
  report "$JOB" "$RUN/run" --attempt "slurm:${SLURM_ARRAY_JOB_ID}_${SLURM_ARRAY_TASK_ID}" -- \
  '/opt/activefoam/bin/foam-run' "$RUN/spec.json" --out "$RUN/run" --resume \
  --checkpoint-every 300 --quiet
