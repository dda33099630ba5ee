// The engine pool: a fixed number of workers take queued jobs from the store by priority then
// age and run them through activefoam::runScene with a cancel flag and a progress callback.
#pragma once

#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <map>
#include <memory>
#include <mutex>
#include <set>
#include <string>
#include <thread>
#include <vector>

#include "executor.h"
#include "store.h"

namespace activefoam::server {

struct PoolOptions {
  int workers = 0;  // 0 = hardware concurrency
  // Engine threads of each job (0: max(1, cores / workers), so workers × threads ≤ cores; more
  // would oversubscribe the cores and OpenMP's spinning barriers then slow every job down).
  int threads_per_job = 0;
  double progress_every_s = 0.5;   // wall time between progress events
  double checkpoint_every_s = 60;  // simulated time between checkpoints
  std::string spheroid_cache_dir;  // prepared spheroids of fusion jobs ("" = not kept)
};

class Pool : public Executor {
 public:
  Pool(Store& store, PoolOptions options);
  ~Pool() override;  // = stop(true)

  std::string_view name() const override { return "pool"; }
  void start() override;
  // Something was queued: wake an idle worker.
  void wake() override;
  // A running job: raise its cancel flag (it ends as cancelled). Returns false if not running here.
  bool cancel(const std::string& id, const std::string& reason) override;
  // Shutdown: raise every flag; running jobs go back to queued (with their last checkpoint).
  void stop(bool requeue_running) override;

  int workers() const override { return static_cast<int>(threads_.size()); }
  const PoolStats& stats() const override { return stats_; }

 private:
  struct Running {
    std::atomic<bool> cancel{false};
    std::string reason;
  };
  void workerLoop();
  void runJob(const Claimed& claimed, Running& flag);

  Store& store_;
  PoolOptions options_;
  PoolStats stats_;
  std::vector<std::thread> threads_;
  std::mutex mu_;
  std::condition_variable cv_;
  std::map<std::string, std::shared_ptr<Running>> running_;
  std::uint64_t wake_gen_ = 0;
  bool stopping_ = false;
  bool shutdown_requeue_ = false;
};

}  // namespace activefoam::server
