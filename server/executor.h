// Where jobs run: the local engine pool (pool.h, the default) or a Slurm cluster (slurm.h). The
// service, the HTTP endpoint and main see only this interface; both executors take queued jobs
// from the store and leave every output and final state in it, so the API, WatchJob and results
// behave the same whichever runs them.
#pragma once

#include <atomic>
#include <cstdint>
#include <string>
#include <string_view>

#include "activefoam/v1/service.pb.h"

namespace activefoam::server {

struct PoolStats {
  std::atomic<std::int64_t> steps_total{0};
  std::atomic<std::int64_t> jobs_succeeded{0};
  std::atomic<std::int64_t> jobs_failed{0};
  std::atomic<std::int64_t> jobs_cancelled{0};
  std::atomic<int> running{0};
};

class Executor {
 public:
  virtual ~Executor() = default;
  virtual std::string_view name() const = 0;  // "pool" | "slurm"
  virtual void start() = 0;
  // Something was queued.
  virtual void wake() = 0;
  // A running job: stop it; it ends as cancelled with `reason`. False if it does not run here
  // (yet: the service retries a job claimed a moment ago).
  virtual bool cancel(const std::string& id, const std::string& reason) = 0;
  // Shutdown. The pool stops its runs (re-queued with their checkpoints when requeue_running);
  // Slurm tasks keep running and report to the next foamd.
  virtual void stop(bool requeue_running) = 0;
  virtual int workers() const = 0;  // concurrent runs it manages (metrics)
  virtual const PoolStats& stats() const = 0;
  // A remote task's report said its run ended: record the job's final state. The pool runs no
  // remote tasks and refuses (false).
  virtual bool taskFinished(const v1::Job&, const v1::ReportTaskRequest&) { return false; }
};

}  // namespace activefoam::server
