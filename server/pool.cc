// Engine workers (see pool.h).
#include "pool.h"

#include <zlib.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <optional>
#include <stdexcept>
#include <type_traits>
#include <utility>

#include <spdlog/spdlog.h>

#include "activefoam/run_output.h"

#include "activefoam/run.h"
#include "activefoam/spec_io.h"
#include "activefoam/threads.h"
#include "spec_convert.h"

namespace activefoam::server {
namespace {

using Clock = std::chrono::steady_clock;

std::string zlibCompress(const std::string& in) {
  uLongf n = compressBound(static_cast<uLong>(in.size()));
  std::string out(n, '\0');
  if (compress2(reinterpret_cast<Bytef*>(out.data()), &n, reinterpret_cast<const Bytef*>(in.data()),
                static_cast<uLong>(in.size()), Z_BEST_SPEED) != Z_OK)
    throw std::runtime_error("zlib: compression failed");
  out.resize(n);
  return out;
}

v1::SnapshotData toProto(const Snapshot& s) {
  v1::SnapshotData d;
  d.set_t_s(s.t_s);
  d.set_step(s.step);
  d.mutable_x()->Reserve(static_cast<int>(s.x.size()));
  for (Eigen::Index i = 0; i < s.x.size(); ++i) d.add_x(s.x.data()[i]);
  for (const Tri& t : s.tri)
    for (int k = 0; k < 3; ++k) d.add_tri(static_cast<int>(t[k]));
  for (int c : s.vertex_cell) d.add_vertex_cell(c);
  for (double p : s.cell_pressure) d.add_cell_pressure(p);
  for (int l : s.cell_label) d.add_cell_label(l);
  return d;
}

}  // namespace

Pool::Pool(Store& store, PoolOptions options) : store_(store), options_(options) {
  const int cores = std::max(1, static_cast<int>(std::thread::hardware_concurrency()));
  if (options_.workers <= 0) options_.workers = cores;
  if (options_.threads_per_job <= 0)
    options_.threads_per_job = std::max(1, cores / options_.workers);
}

Pool::~Pool() {
  stop(true);
}

void Pool::start() {
  for (int i = 0; i < options_.workers; ++i)
    threads_.emplace_back([this] {
      setThreads(options_.threads_per_job);  // per thread: each worker's jobs use this many
      workerLoop();
    });
  spdlog::info("pool: {} engine workers, {} thread(s) per job", options_.workers,
               options_.threads_per_job);
}

void Pool::wake() {
  {
    std::lock_guard lock(mu_);
    ++wake_gen_;
  }
  cv_.notify_all();
}

bool Pool::cancel(const std::string& id, const std::string& reason) {
  std::lock_guard lock(mu_);
  auto it = running_.find(id);
  if (it == running_.end()) return false;
  it->second->reason = reason;
  it->second->cancel = true;
  return true;
}

void Pool::stop(bool requeue_running) {
  {
    std::lock_guard lock(mu_);
    if (stopping_ && threads_.empty()) return;
    stopping_ = true;
    shutdown_requeue_ = requeue_running;
    for (auto& [id, r] : running_) r->cancel = true;
  }
  cv_.notify_all();
  for (std::thread& t : threads_) t.join();
  threads_.clear();
}

void Pool::workerLoop() {
  for (;;) {
    std::uint64_t gen;
    {
      std::lock_guard lock(mu_);
      if (stopping_) return;
      gen = wake_gen_;
    }
    std::optional<Claimed> claimed;
    try {
      claimed = store_.claimNext();
    } catch (const std::exception& e) {
      spdlog::error("pool: cannot claim a job: {}", e.what());
    }
    if (!claimed) {
      std::unique_lock lock(mu_);
      cv_.wait_for(lock, std::chrono::seconds(2), [&] { return stopping_ || wake_gen_ != gen; });
      continue;
    }
    auto flag = std::make_shared<Running>();
    {
      std::lock_guard lock(mu_);
      if (stopping_) flag->cancel = true;
      running_[claimed->job.id()] = flag;
    }
    ++stats_.running;
    runJob(*claimed, *flag);
    --stats_.running;
    {
      std::lock_guard lock(mu_);
      running_.erase(claimed->job.id());
    }
  }
}

void Pool::runJob(const Claimed& claimed, Running& flag) {
  const std::string id = claimed.job.id();
  SpecParseResult parsed = readRecord(claimed.job.spec_json());
  if (!parsed.ok()) {
    store_.finish(id, v1::JOB_STATE_FAILED, "exception",
                  "stored spec does not parse: " + parsed.errors.front().str(), {}, 0, 0);
    ++stats_.jobs_failed;
    return;
  }
  const SceneSpec spec = *parsed.spec;
  const std::vector<std::string> columns = sampleColumns(spec);

  // Outputs recorded after the checkpoint (or all, when starting from scratch) are dropped:
  // the run emits them again.
  const std::string* resume = claimed.checkpoint ? &*claimed.checkpoint : nullptr;
  store_.resetOutputs(id, resume ? std::optional<double>(claimed.checkpoint_t_s) : std::nullopt);
  spdlog::info("job {}: {} ({} attempt {})", id,
               resume ? "resuming from checkpoint at t = " + std::to_string(claimed.checkpoint_t_s)
                      : std::string("starting"),
               claimed.job.scene(), claimed.job.attempts());

  const auto t0 = Clock::now();
  auto last_progress = t0 - std::chrono::hours(1);
  // Steps counted from where this attempt starts (a resumed run does not recount the earlier
  // ones), and the ETA from the pace since the first progress report (spheroid preparation
  // and the earlier attempts are not in it).
  std::int64_t last_step =
      resume ? std::llround(claimed.checkpoint_t_s / spec.numerics.dt_s) : std::int64_t{0};
  std::optional<std::pair<Clock::time_point, double>> pace_from;
  RunObserver obs;
  obs.cancel = &flag.cancel;
  obs.on_sample = [&](const Sample& s) { store_.addSample(id, columns, s.values); };
  obs.on_snapshot = [&](const Snapshot& s) {
    v1::SnapshotData d = toProto(s);
    const std::string raw = d.SerializeAsString();
    v1::SnapshotInfo info;
    info.set_t_s(s.t_s);
    info.set_step(s.step);
    info.set_bytes(static_cast<std::int64_t>(raw.size()));
    info.set_vertices(static_cast<int>(s.x.cols()));
    info.set_triangles(static_cast<int>(s.tri.size()));
    store_.addSnapshot(id, info, "zlib", zlibCompress(raw));
  };
  obs.on_progress = [&](double t_s, std::int64_t step, std::int64_t rejected) {
    stats_.steps_total += step - last_step;
    last_step = step;
    const auto now = Clock::now();
    if (!pace_from) pace_from.emplace(now, t_s);
    if (std::chrono::duration<double>(now - last_progress).count() < options_.progress_every_s)
      return;
    last_progress = now;
    const double wall = std::chrono::duration<double>(now - t0).count();
    const double f = spec.duration_s > 0 ? std::clamp(t_s / spec.duration_s, 0.0, 1.0) : 0.0;
    v1::Progress p;
    p.set_t_s(t_s);
    p.set_step(step);
    p.set_fraction(f);
    p.set_wall_s(wall);
    p.set_steps_rejected(rejected);
    const double done = t_s - pace_from->second;
    const double pace = std::chrono::duration<double>(now - pace_from->first).count();
    p.set_eta_s(done > 0 ? pace / done * std::max(0.0, spec.duration_s - t_s) : -1);
    store_.addProgress(id, p);
  };
  // Periodic, atomic checkpoints (one transaction replaces the previous one), and one when the
  // run is cancelled (shutdown), so a re-queued job resumes where it stopped.
  obs.checkpoint_every_s = options_.checkpoint_every_s;
  obs.spheroid_cache_dir = options_.spheroid_cache_dir;
  obs.on_log = [id](const std::string& line) { spdlog::info("job {}: {}", id, line); };
  obs.on_checkpoint = [&](double t_s, const std::string& state) {
    store_.saveCheckpoint(id, t_s, state);
  };

  RunSummary summary;
  std::string exception;
  try {
    try {
      summary = runScene(spec, obs, resume);
    } catch (const std::invalid_argument& e) {
      if (!resume) throw;
      // The engine refused the checkpoint (written by another engine version or a damaged
      // one). Start over from scratch — same seed, same result.
      spdlog::warn("job {}: cannot resume ({}); restarting from scratch", id, e.what());
      store_.dropCheckpoint(id);
      store_.resetOutputs(id, std::nullopt);
      summary = runScene(spec, obs, nullptr);
    }
  } catch (const std::exception& e) {
    exception = e.what();
  }
  store_.flush();
  stats_.steps_total += summary.steps - last_step;

  bool shutdown;
  {
    std::lock_guard lock(mu_);
    shutdown = stopping_ && shutdown_requeue_;
  }
  if (!exception.empty()) {
    store_.finish(id, v1::JOB_STATE_FAILED, "exception", "engine error: " + exception, {},
                  summary.t_s, summary.steps);
    ++stats_.jobs_failed;
    spdlog::error("job {}: engine error: {}", id, exception);
    return;
  }
  if (summary.failure == FailureKind::Cancelled && shutdown && flag.reason.empty()) {
    store_.requeue(id, "server shut down at t = " + std::to_string(summary.t_s) +
                           " s; re-queued, resumes from its last checkpoint");
    spdlog::info("job {}: re-queued at shutdown (t = {} s)", id, summary.t_s);
    return;
  }
  const FlatResults flat = flattenSummary(summaryToJson(summary, spec, {}));
  const auto& results = flat.values;
  if (summary.ok()) {
    store_.finish(id, v1::JOB_STATE_SUCCEEDED, "", "", results, summary.t_s, summary.steps,
                  flat.outcome, flat.curves);
    ++stats_.jobs_succeeded;
    spdlog::info("job {}: succeeded ({} steps, {:.2f} s wall)", id, summary.steps, summary.wall_s);
  } else if (summary.failure == FailureKind::Cancelled) {
    store_.finish(id, v1::JOB_STATE_CANCELLED, "cancelled",
                  flag.reason.empty() ? "cancelled while running" : flag.reason, results,
                  summary.t_s, summary.steps, flat.outcome);
    ++stats_.jobs_cancelled;
    spdlog::info("job {}: cancelled at t = {} s", id, summary.t_s);
  } else {
    store_.finish(id, v1::JOB_STATE_FAILED, std::string(toString(summary.failure)), summary.reason,
                  results, summary.t_s, summary.steps, flat.outcome, flat.curves);
    ++stats_.jobs_failed;
    spdlog::warn("job {}: failed: {}: {}", id, toString(summary.failure), summary.reason);
  }
}

}  // namespace activefoam::server
