// The Slurm executor (deploy/slurm/README.md): queued jobs go to a Slurm cluster as
// batch array tasks (a sweep's queued jobs as one `sbatch --array`). Each task runs
// `foam report JOB RUN -- foam-run SPEC --out RUN/run --resume`: foam-run computes on the
// compute node and checkpoints into the shared work directory; `foam report` sends what the run
// folder holds (progress, samples, snapshots, the final summary) to foamd's ReportTask with the
// server's token, retrying while foamd is away. foamd polls Slurm (squeue, then sacct) for
// tasks that ended without a final report and maps Slurm's failure states to the job's.
//
// Shared-filesystem assumptions: work_dir is visible at the same path to foamd and to every
// compute node (specs, checkpoints and outputs live there); the SQLite store stays local to
// foamd and is never put on it.
#pragma once

#include <chrono>
#include <condition_variable>
#include <map>
#include <mutex>
#include <set>
#include <string>
#include <thread>
#include <vector>

#include "executor.h"
#include "store.h"

namespace activefoam::server {

struct SlurmOptions {
  std::string work_dir;   // shared filesystem: jobs/<id>/ (spec, run folder), arrays/<name>/
  std::string partition;  // "" = the cluster's default
  std::string foam_run = "foam-run";  // paths as the compute nodes see them
  std::string foam = "foam";
  std::string report_to;   // HOST:PORT the tasks report to (foamd's --listen, reachable)
  std::string token_file;  // token file readable by the tasks ("" = no token)
  std::string tls_ca;      // CA file for the tasks when foamd serves TLS ("" = plain)
  std::vector<std::string> sbatch_args;  // extra, e.g. --time=24:00:00 --mem=2G
  double poll_every_s = 5;
  double checkpoint_every_s = 300;  // foam-run --checkpoint-every (wall time)
  // A task Slurm lists as ended whose final report has not arrived after this long is judged
  // from Slurm's state (the report may be in flight when Slurm already says COMPLETED).
  double report_grace_s = 30;
  std::string sbatch = "sbatch", squeue = "squeue", sacct = "sacct", scancel = "scancel";
};

// Slurm job states and what they mean for a job (exposed for tests).
struct SlurmState {
  enum Kind { Active, Completed, Failed, Cancelled, Unknown } kind = Unknown;
  std::string name;  // RUNNING, TIMEOUT, ...
};
SlurmState classifySlurmState(const std::string& state);

class SlurmExecutor : public Executor {
 public:
  SlurmExecutor(Store& store, SlurmOptions options);
  ~SlurmExecutor() override;

  std::string_view name() const override { return "slurm"; }
  void start() override;
  void wake() override;
  bool cancel(const std::string& id, const std::string& reason) override;
  void stop(bool requeue_running) override;
  int workers() const override { return stats_.running.load(); }
  const PoolStats& stats() const override { return stats_; }
  bool taskFinished(const v1::Job& job, const v1::ReportTaskRequest& report) override;

 private:
  void loop();
  void submitQueued();
  void poll();
  void submitGroup(const std::string& name, const std::vector<v1::Job>& jobs);
  std::string writeTaskScript(const std::string& array_dir) const;

  Store& store_;
  SlurmOptions options_;
  PoolStats stats_;
  std::thread thread_;
  std::mutex mu_;
  std::condition_variable cv_;
  bool stopping_ = false;
  std::uint64_t wake_gen_ = 0;
  std::set<std::string> cancelled_unplaced_;  // cancelled between claim and sbatch
  std::map<std::string, std::chrono::steady_clock::time_point> ended_since_;
  std::chrono::steady_clock::time_point submit_after_{};  // pause after an sbatch failure
};

}  // namespace activefoam::server
