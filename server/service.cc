// The activefoam.v1.Foam service (callback API), see service.h.
#include "service.h"

#include <grpcpp/ext/proto_server_reflection_plugin.h>
#include <grpcpp/grpcpp.h>
#include <grpcpp/health_check_service_interface.h>
#include <grpcpp/security/server_credentials.h>

#include <algorithm>
#include <chrono>
#include <map>
#include <set>
#include <thread>

#include <spdlog/spdlog.h>

#include "activefoam/run.h"
#include "activefoam/spec_io.h"
#include "activefoam/v1/service.grpc.pb.h"
#include "listen.h"
#include "spec_convert.h"

namespace activefoam::server {
namespace {

using grpc::CallbackServerContext;
using grpc::ServerUnaryReactor;
using grpc::Status;
using grpc::StatusCode;

constexpr std::size_t kSnapshotChunk = 1024 * 1024;

// Every call must carry `authorization: Bearer <token>` when a token is set.
class TokenAuth : public grpc::AuthMetadataProcessor {
 public:
  explicit TokenAuth(std::string token) : expected_("Bearer " + std::move(token)) {}
  bool IsBlocking() const override { return false; }
  Status Process(const InputMetadata& md, grpc::AuthContext*, OutputMetadata* consumed,
                 OutputMetadata*) override {
    auto it = md.find("authorization");
    if (it == md.end())
      return Status(StatusCode::UNAUTHENTICATED, "missing 'authorization: Bearer <token>'");
    const std::string got(it->second.data(), it->second.size());
    // Constant-time comparison.
    unsigned diff = got.size() == expected_.size() ? 0u : 1u;
    for (std::size_t i = 0; i < got.size() && i < expected_.size(); ++i)
      diff |= static_cast<unsigned>(got[i] ^ expected_[i]);
    if (diff != 0) return Status(StatusCode::UNAUTHENTICATED, "wrong token");
    consumed->insert(std::make_pair(std::string(it->first.data(), it->first.size()), got));
    return Status::OK;
  }

 private:
  std::string expected_;
};

Status storeStatus(const StoreError& e) {
  switch (e.kind) {
    case StoreError::Kind::InvalidArgument:
      return Status(StatusCode::INVALID_ARGUMENT, e.what());
    case StoreError::Kind::NotFound:
      return Status(StatusCode::NOT_FOUND, e.what());
    case StoreError::Kind::FailedPrecondition:
      return Status(StatusCode::FAILED_PRECONDITION, e.what());
  }
  return Status(StatusCode::INTERNAL, e.what());
}

// A request that could not be taken as sent (request_traits.h): INVALID_ARGUMENT naming why.
Status requestStatus(const google::protobuf::Message& req) {
  const std::string why = activefoam::wire::requestError(req);
  return why.empty() ? Status::OK : Status(StatusCode::INVALID_ARGUMENT, why);
}

// Runs `fn` and maps exceptions to statuses.
template <class F>
Status guarded(F&& fn) {
  try {
    return fn();
  } catch (const StoreError& e) {
    return storeStatus(e);
  } catch (const std::exception& e) {
    spdlog::error("rpc: internal error: {}", e.what());
    return Status(StatusCode::INTERNAL, e.what());
  }
}

// The same for a handler of `req`: a request that could not be taken as sent is answered first.
template <class F>
Status guarded(const google::protobuf::Message& req, F&& fn) {
  if (Status st = requestStatus(req); !st.ok()) return st;
  return guarded(std::forward<F>(fn));
}

// Watchers waiting for new events of a job; poked by the store after each commit.
class Hub {
 public:
  using Poke = std::function<void()>;
  std::uint64_t add(const std::string& job, Poke poke) {
    std::lock_guard lock(mu_);
    const std::uint64_t key = ++next_;
    subs_[job][key] = std::move(poke);
    return key;
  }
  void remove(const std::string& job, std::uint64_t key) {
    std::lock_guard lock(mu_);
    auto it = subs_.find(job);
    if (it == subs_.end()) return;
    it->second.erase(key);
    if (it->second.empty()) subs_.erase(it);
  }
  void notify(const std::string& job) {
    std::lock_guard lock(mu_);  // held while poking: remove() waits, so no poke after OnDone
    auto it = subs_.find(job);
    if (it == subs_.end()) return;
    for (auto& [k, poke] : it->second) poke();
  }

 private:
  std::mutex mu_;
  std::uint64_t next_ = 0;
  std::map<std::string, std::map<std::uint64_t, Poke>> subs_;
};

class WatchReactor : public grpc::ServerWriteReactor<v1::JobEvent> {
 public:
  WatchReactor(Store& store, Hub& hub, const v1::WatchJobRequest& req)
      : store_(store),
        hub_(hub),
        job_(req.job_id()),
        after_(req.from_seq()),
        follow_(req.follow()) {
    key_ = hub_.add(job_, [this] { next(); });
    next();
  }
  void OnWriteDone(bool ok) override {
    {
      std::lock_guard lock(mu_);
      writing_ = false;
      if (!ok) {
        finishLocked(Status(StatusCode::CANCELLED, "stream broken"));
        return;
      }
    }
    next();
  }
  void OnCancel() override {
    std::lock_guard lock(mu_);
    cancelled_ = true;
    if (!writing_) finishLocked(Status::CANCELLED);
  }
  void OnDone() override {
    hub_.remove(job_, key_);
    delete this;
  }

 private:
  void finishLocked(Status s) {
    if (finished_) return;
    finished_ = true;
    Finish(std::move(s));
  }
  // Sends the next stored event, or finishes when there is none and the job has ended.
  void next() {
    std::unique_lock lock(mu_);
    if (writing_ || finished_) return;
    if (cancelled_) {
      finishLocked(Status::CANCELLED);
      return;
    }
    try {
      if (pending_.empty()) {
        const std::optional<v1::Job> job = store_.getJob(job_);  // state first, then events
        if (!job) {
          finishLocked(Status(StatusCode::NOT_FOUND, "no job " + cappedQuote(job_)));
          return;
        }
        auto evs = store_.events(job_, after_, 256);
        for (auto& e : evs) pending_.push_back(std::move(e));
        if (pending_.empty()) {
          if (isTerminal(job->state()) || !follow_) finishLocked(Status::OK);
          return;  // wait for a poke
        }
      }
      current_ = std::move(pending_.front());
      pending_.pop_front();
      if (current_.has_state()) addResolvedRecord(*current_.mutable_state());
      after_ = current_.seq();
      writing_ = true;
    } catch (const std::exception& e) {
      finishLocked(Status(StatusCode::INTERNAL, e.what()));
      return;
    }
    lock.unlock();
    StartWrite(&current_);
  }

  Store& store_;
  Hub& hub_;
  std::string job_;
  std::int64_t after_;
  bool follow_;
  std::uint64_t key_ = 0;
  std::mutex mu_;
  std::deque<v1::JobEvent> pending_;
  v1::JobEvent current_;
  bool writing_ = false;
  bool finished_ = false;
  bool cancelled_ = false;
};

class SnapshotReactor : public grpc::ServerWriteReactor<v1::SnapshotChunk> {
 public:
  SnapshotReactor(v1::SnapshotInfo info, std::string compression, std::string data)
      : data_(std::move(data)) {
    *chunk_.mutable_info() = info;
    chunk_.set_compression(compression);
    chunk_.set_total_bytes(static_cast<std::int64_t>(data_.size()));
    next();
  }
  void OnWriteDone(bool ok) override {
    if (!ok) return Finish(Status(StatusCode::CANCELLED, "stream broken"));
    next();
  }
  void OnDone() override { delete this; }

 private:
  void next() {
    if (offset_ >= data_.size() && offset_ > 0) return Finish(Status::OK);
    const std::size_t n = std::min(kSnapshotChunk, data_.size() - offset_);
    if (offset_ > 0) chunk_.Clear();
    chunk_.set_data(data_.substr(offset_, n));
    offset_ += n;
    if (n == 0) offset_ = 1;  // empty blob: one chunk, then finish
    StartWrite(&chunk_);
  }
  std::string data_;
  std::size_t offset_ = 0;
  v1::SnapshotChunk chunk_;
};

// A server stream that ends at once with `status`.
template <class Message>
struct FailedStream : grpc::ServerWriteReactor<Message> {
  explicit FailedStream(Status status) { this->Finish(std::move(status)); }
  void OnDone() override { delete this; }
};

// The API's limits, the same on every RPC (a 15 MiB cancel reason made every later
// ListJobs exceed the client's message limit; a sweep took a 1 MiB tag).
constexpr std::size_t kMaxKeyBytes = 256;      // tags, names, idempotency keys
constexpr std::size_t kMaxReasonBytes = 1024;  // free text stored with a job
constexpr std::size_t kMaxSweepJobs = 100000;

Status capped(const char* field, const std::string& value, std::size_t max) {
  if (value.size() <= max) return Status::OK;
  return Status(StatusCode::INVALID_ARGUMENT, std::string(field) + ": at most " +
                                                  std::to_string(max) + " bytes, got " +
                                                  std::to_string(value.size()));
}

class FoamService final : public v1::Foam::CallbackService {
 public:
  FoamService(Store& store, Executor& pool, ConvertOptions convert)
      : store_(store), pool_(pool), convert_(convert) {
    store_.setEventListener([this](const std::string& id) { hub_.notify(id); });
  }
  ~FoamService() override { store_.setEventListener(nullptr); }

  ServerUnaryReactor* SubmitJob(CallbackServerContext* ctx, const v1::SubmitJobRequest* req,
                                v1::SubmitJobResponse* resp) override {
    return done(
        ctx, guarded(*req, [&] {
          if (Status st = writable(); !st.ok()) return st;
          if (Status st = capped("idempotency_key", req->idempotency_key(), kMaxKeyBytes); !st.ok())
            return st;
          if (Status st = capped("tag", req->tag(), kMaxKeyBytes); !st.ok()) return st;
          const std::vector<std::string> settings(req->settings().begin(), req->settings().end());
          ConvertResult conv = convertSpec(req->spec(), req->spec_text(), settings, convert_);
          if (!conv.ok()) return Status(StatusCode::INVALID_ARGUMENT, errorText(conv.errors));
          NewJob job;
          job.spec = *conv.spec;
          job.spec_json = specToJson(job.spec).dump();
          job.priority = req->priority();
          job.tag = req->tag();
          job.idempotency_key = req->idempotency_key();
          auto [id, created] = store_.submit(job);
          resp->set_job_id(id);
          resp->set_created(created);
          if (auto j = store_.getJob(id)) {
            *resp->mutable_job() = *j;
            addResolvedRecord(*resp->mutable_job());
          }
          if (created) {
            spdlog::info("job {}: submitted ({}, seed {}, priority {}, preset {}{})", id,
                         toString(job.spec.scene), job.spec.seed, job.priority,
                         toString(job.spec.numerics.preset),
                         job.spec.accuracy.any() ? " chosen for its accuracy target" : "");
            pool_.wake();
          }
          return Status::OK;
        }));
  }

  ServerUnaryReactor* GetJob(CallbackServerContext* ctx, const v1::GetJobRequest* req,
                             v1::Job* resp) override {
    return done(ctx, guarded(*req, [&] {
                  auto j = store_.getJob(req->job_id());
                  if (!j)
                    return Status(StatusCode::NOT_FOUND, "no job " + cappedQuote(req->job_id()));
                  *resp = *j;
                  addResolvedRecord(*resp);
                  return Status::OK;
                }));
  }

  ServerUnaryReactor* ListJobs(CallbackServerContext* ctx, const v1::ListJobsRequest* req,
                               v1::ListJobsResponse* resp) override {
    return done(ctx, guarded(*req, [&] {
                  *resp = store_.listJobs(*req);
                  for (v1::Job& j : *resp->mutable_jobs()) addResolvedRecord(j);
                  return Status::OK;
                }));
  }

  ServerUnaryReactor* CancelJob(CallbackServerContext* ctx, const v1::CancelJobRequest* req,
                                v1::Job* resp) override {
    return done(ctx, guarded(*req, [&] {
                  if (Status st = writable(); !st.ok()) return st;
                  if (Status st = capped("reason", req->reason(), kMaxReasonBytes); !st.ok())
                    return st;
                  const std::string reason =
                      req->reason().empty() ? "cancelled by request" : req->reason();
                  v1::Job j = store_.cancel(req->job_id(), reason);
                  if (j.state() == v1::JOB_STATE_RUNNING) {
                    // Claimed a moment ago, maybe not yet registered with the pool: retry.
                    for (int i = 0; i < 200 && !pool_.cancel(j.id(), reason); ++i) {
                      std::this_thread::sleep_for(std::chrono::milliseconds(10));
                      j = *store_.getJob(j.id());
                      if (j.state() != v1::JOB_STATE_RUNNING) break;
                    }
                    j = *store_.getJob(j.id());
                  }
                  *resp = j;
                  addResolvedRecord(*resp);
                  return Status::OK;
                }));
  }

  grpc::ServerWriteReactor<v1::JobEvent>* WatchJob(CallbackServerContext*,
                                                   const v1::WatchJobRequest* req) override {
    if (Status st = requestStatus(*req); !st.ok()) return new FailedStream<v1::JobEvent>(st);
    return new WatchReactor(store_, hub_, *req);
  }

  ServerUnaryReactor* GetResults(CallbackServerContext* ctx, const v1::GetResultsRequest* req,
                                 v1::JobResults* resp) override {
    return done(ctx, guarded(*req, [&] {
                  *resp = store_.results(req->job_id(), req->with_samples());
                  addResolvedRecord(*resp->mutable_job());
                  return Status::OK;
                }));
  }

  ServerUnaryReactor* QueryResults(CallbackServerContext* ctx, const v1::QueryResultsRequest* req,
                                   v1::QueryResultsResponse* resp) override {
    return done(ctx, guarded(*req, [&] {
                  *resp = store_.queryResults(*req);
                  return Status::OK;
                }));
  }

  ServerUnaryReactor* SubmitSweep(CallbackServerContext* ctx, const v1::SubmitSweepRequest* req,
                                  v1::SubmitSweepResponse* resp) override {
    return done(ctx, guarded(*req, [&] {
                  if (Status st = writable(); !st.ok()) return st;
                  return sweep(*req, resp);
                }));
  }

  // A read: it writes nothing, so it answers while the store cannot write.
  ServerUnaryReactor* ResolveSpec(CallbackServerContext* ctx, const v1::ResolveSpecRequest* req,
                                  v1::ResolveSpecResponse* resp) override {
    return done(
        ctx, guarded(*req, [&] {
          const std::vector<std::string> settings(req->settings().begin(), req->settings().end());
          ConvertResult conv = convertSpec(req->spec(), req->spec_text(), settings, convert_);
          if (!conv.ok()) return Status(StatusCode::INVALID_ARGUMENT, errorText(conv.errors));
          resp->set_spec_json(specToJson(*conv.spec).dump());
          for (const SpecField& f : specFields())
            if (f.label) resp->add_labels(f.key);
          return Status::OK;
        }));
  }

  grpc::ServerWriteReactor<v1::SnapshotChunk>* GetSnapshot(
      CallbackServerContext*, const v1::GetSnapshotRequest* req) override {
    std::optional<std::tuple<v1::SnapshotInfo, std::string, std::string>> snap;
    Status status;
    status = guarded(*req, [&] {
      if (req->index() < -1)
        return Status(StatusCode::INVALID_ARGUMENT,
                      "index: " + std::to_string(req->index()) + " is below -1 (-1 = the latest)");
      if (!store_.getJob(req->job_id()))
        return Status(StatusCode::NOT_FOUND, "no job " + cappedQuote(req->job_id()));
      snap = store_.snapshot(req->job_id(), req->index());
      if (!snap)
        return Status(StatusCode::NOT_FOUND, "job " + cappedQuote(req->job_id()) +
                                                 " has no snapshot " +
                                                 std::to_string(req->index()));
      return Status::OK;
    });
    if (!status.ok()) return new FailedStream<v1::SnapshotChunk>(status);
    auto& [info, comp, data] = *snap;
    return new SnapshotReactor(info, comp, std::move(data));
  }

 private:
  // New work is refused while the store cannot write: its reply would wait for the disk.
  Status writable() const {
    if (!store_.degraded()) return Status::OK;
    return Status(StatusCode::UNAVAILABLE,
                  "the store cannot write (" + store_.lastError().substr(0, 200) +
                      "); nothing was accepted: retry when it recovers (health: NOT_SERVING)");
  }

  static ServerUnaryReactor* done(CallbackServerContext* ctx, Status s) {
    auto* r = ctx->DefaultReactor();
    // The last guard against echoing a huge value: a message beyond gRPC's metadata limit
    // would turn the answer into an opaque transport error (and hung grpc-js channels).
    if (s.error_message().size() > 1024)
      s = Status(s.error_code(), s.error_message().substr(0, 1000) + "... (" +
                                     std::to_string(s.error_message().size()) + " bytes)");
    r->Finish(std::move(s));
    return r;
  }

  Status sweep(const v1::SubmitSweepRequest& req, v1::SubmitSweepResponse* resp) {
    for (const auto& [field, value] :
         {std::pair<const char*, const std::string*>{"tag", &req.tag()},
          {"name", &req.name()},
          {"idempotency_key", &req.idempotency_key()}})
      if (Status st = capped(field, *value, kMaxKeyBytes); !st.ok()) return st;
    // The job count, from the axes and seeds before any parameter set is built: three 300-value
    // axes (a 6 KB request) once built 27 million sets before the cap was checked. Exact up to
    // 2^53; beyond that only its size matters.
    double n_sets = 1;
    for (int a = 0; a < req.grid_size(); ++a) {
      const v1::GridAxis& axis = req.grid(a);
      if (axis.values_size() == 0)
        return Status(StatusCode::INVALID_ARGUMENT,
                      "grid[" + std::to_string(a) + "].values: empty (key " + axis.key() + ")");
      n_sets *= static_cast<double>(axis.values_size());
    }
    if (req.grid_size() == 0 && req.sets_size() > 0) n_sets = req.sets_size();
    const double n_seeds = std::max(req.seeds_size(), 1);
    auto count = [](double n) {  // whole numbers as such while a double holds them exactly
      return n < 9e15 ? std::to_string(static_cast<long long>(n)) : formatNumber(n);
    };
    if (n_sets * n_seeds > static_cast<double>(kMaxSweepJobs))
      return Status(StatusCode::INVALID_ARGUMENT,
                    "grid × seeds: " + count(n_sets) + " parameter sets × " + count(n_seeds) +
                        " seeds, more than the " + std::to_string(kMaxSweepJobs) +
                        " jobs a sweep may have");
    // Parameter sets: the cartesian product of the grid, or the explicit list, or one empty set.
    std::vector<std::vector<std::string>> sets{{}};
    if (req.grid_size() > 0) {
      for (int a = 0; a < req.grid_size(); ++a) {
        const v1::GridAxis& axis = req.grid(a);
        std::vector<std::vector<std::string>> next;
        for (const auto& s : sets)
          for (const std::string& v : axis.values()) {
            next.push_back(s);
            next.back().push_back(axis.key() + "=" + v);
          }
        sets = std::move(next);
        if (sets.size() > kMaxSweepJobs)
          return Status(StatusCode::INVALID_ARGUMENT,
                        "grid: more than " + std::to_string(kMaxSweepJobs) + " jobs");
      }
    } else if (req.sets_size() > 0) {
      sets.clear();
      for (const auto& ps : req.sets())
        sets.emplace_back(ps.settings().begin(), ps.settings().end());
    }
    std::vector<std::uint64_t> seeds(req.seeds().begin(), req.seeds().end());
    // The cap counts jobs, not sets: 1000 values × 101 seeds made 101 000 jobs.
    const std::size_t n_jobs = sets.size() * std::max<std::size_t>(seeds.size(), 1);
    if (sets.size() > kMaxSweepJobs || seeds.size() > kMaxSweepJobs || n_jobs > kMaxSweepJobs)
      return Status(StatusCode::INVALID_ARGUMENT,
                    "grid × seeds: " + std::to_string(sets.size()) + " parameter sets × " +
                        std::to_string(std::max<std::size_t>(seeds.size(), 1)) +
                        " seeds, more than the " + std::to_string(kMaxSweepJobs) +
                        " jobs a sweep may have");
    std::vector<NewJob> jobs;
    const std::vector<std::string> base(req.settings().begin(), req.settings().end());
    for (std::size_t i = 0; i < sets.size(); ++i) {
      std::vector<std::string> settings = base;
      settings.insert(settings.end(), sets[i].begin(), sets[i].end());
      const std::size_t nseeds = seeds.empty() ? 1 : seeds.size();
      for (std::size_t k = 0; k < nseeds; ++k) {
        std::vector<std::string> s = settings;
        if (!seeds.empty()) s.push_back("seed=" + std::to_string(seeds[k]));
        ConvertResult conv = convertSpec(req.spec(), req.spec_text(), s, convert_);
        if (!conv.ok())
          return Status(StatusCode::INVALID_ARGUMENT,
                        "parameter set " + std::to_string(i) + ": " + errorText(conv.errors));
        NewJob j;
        j.spec = *conv.spec;
        j.spec_json = specToJson(j.spec).dump();
        j.priority = req.priority();
        j.tag = req.tag();
        jobs.push_back(std::move(j));
      }
    }
    // The keys the sweep varies, in the order given: its grid's, or its parameter sets'.
    std::vector<std::string> keys;
    auto addKey = [&](const std::string& setting) {
      const std::string key = setting.substr(0, setting.find('='));
      if (std::find(keys.begin(), keys.end(), key) == keys.end()) keys.push_back(key);
    };
    for (const auto& axis : req.grid()) addKey(axis.key());
    if (req.grid_size() == 0)
      for (const auto& ps : req.sets())
        for (const auto& setting : ps.settings()) addKey(setting);
    auto [sid, ids, created] = store_.submitSweep(req.name(), req.idempotency_key(), jobs, keys);
    resp->set_sweep_id(sid);
    for (const auto& id : ids) resp->add_job_ids(id);
    resp->set_created(created);
    if (created) {
      spdlog::info("sweep {}: {} jobs", sid, ids.size());
      pool_.wake();
    }
    return Status::OK;
  }

  ServerUnaryReactor* ReportTask(CallbackServerContext* ctx, const v1::ReportTaskRequest* req,
                                 v1::ReportTaskResponse* resp) override {
    return done(ctx, guarded(*req, [&] { return reportTask(*req, *resp); }));
  }

  Status reportTask(const v1::ReportTaskRequest& req, v1::ReportTaskResponse& resp) {
    const std::optional<v1::Job> j = store_.getJob(req.job_id());
    if (!j) return Status(StatusCode::NOT_FOUND, "no job " + cappedQuote(req.job_id()));
    if (j->state() == v1::JOB_STATE_RUNNING && j->executor_ref().empty())
      // Claimed and submitted, but the executor has not recorded the task yet (a task can start
      // before sbatch answers): the reporter retries.
      return Status(StatusCode::UNAVAILABLE, "job '" + j->id() + "' is not placed yet; retry");
    if (j->state() != v1::JOB_STATE_RUNNING || j->executor_ref() != req.attempt()) {
      // Cancelled, finished, or handed to another task since (re-queued): this task stops.
      resp.set_stop(true);
      return Status::OK;
    }
    // The columns of the job's own spec (its scene's, then its probes'), as its task writes them.
    const SpecParseResult record = readRecord(j->spec_json());
    if (!record.ok())
      return Status(StatusCode::FAILED_PRECONDITION,
                    "the job's stored spec does not parse: " + record.errors.front().str());
    const std::vector<std::string> columns = sampleColumns(*record.spec);
    if (req.samples_size() > 0 &&
        std::vector<std::string>(req.columns().begin(), req.columns().end()) != columns)
      return Status(StatusCode::FAILED_PRECONDITION,
                    "columns: the task's samples.csv columns differ from this foamd's for the "
                    "job's spec (scene " +
                        j->scene() + "; engine versions differ?)");
    if (req.snapshots_size() != req.snapshot_infos_size())
      return Status(StatusCode::INVALID_ARGUMENT, "snapshot_infos: one per snapshot");
    std::vector<std::vector<double>> samples;
    for (const v1::Sample& s : req.samples()) {
      if (static_cast<std::size_t>(s.values_size()) != columns.size())
        return Status(StatusCode::INVALID_ARGUMENT,
                      "samples: " + std::to_string(s.values_size()) + " values for " +
                          std::to_string(columns.size()) + " columns");
      samples.emplace_back(s.values().begin(), s.values().end());
    }
    std::vector<std::pair<v1::SnapshotInfo, std::string>> snapshots;
    for (int k = 0; k < req.snapshots_size(); ++k)
      snapshots.emplace_back(req.snapshot_infos(k), req.snapshots(k));
    std::optional<v1::Progress> progress;
    if (req.has_progress()) progress = req.progress();
    const Store::Held held = store_.ingestReport(j->id(), columns, req.first_sample(), samples,
                                                 req.first_snapshot(), snapshots, progress);
    resp.set_samples_held(held.samples);
    resp.set_snapshots_held(held.snapshots);
    if (req.finished()) {
      if (!pool_.taskFinished(*j, req))
        return Status(StatusCode::FAILED_PRECONDITION,
                      "this foamd runs jobs with its " + std::string(pool_.name()) +
                          " executor, which takes no task reports");
      resp.set_stop(true);
    }
    return Status::OK;
  }

  Store& store_;
  Executor& pool_;
  const ConvertOptions convert_;
  Hub hub_;
};

}  // namespace

struct FoamServer::Impl {
  Store& store;
  Executor& pool;
  ServerConfig config;
  std::unique_ptr<FoamService> service;
  std::unique_ptr<grpc::Server> server;
  int port = 0;
};

FoamServer::FoamServer(Store& store, Executor& pool, ServerConfig config)
    : impl_(new Impl{store, pool, std::move(config), nullptr, nullptr, 0}) {}

FoamServer::~FoamServer() {
  shutdown();
}

void checkServerConfig(const ServerConfig& c) {
  if (!isLoopback(c.listen) && c.token.empty() && !c.insecure_public)
    throw std::invalid_argument(
        "--listen " + c.listen +
        " is not a loopback address and foamd has no --token-file: anyone who reaches it could "
        "submit and cancel jobs. Give --token-file (with --tls-cert/--tls-key), or "
        "--insecure-public on a network you trust");
  if (!isLoopback(c.listen) && !c.token.empty() && (c.tls_cert.empty() || c.tls_key.empty()))
    throw std::invalid_argument("--listen " + c.listen +
                                ": a token on a non-loopback address needs TLS "
                                "(--tls-cert/--tls-key)");
}

void FoamServer::start() {
  Impl& m = *impl_;
  grpc::EnableDefaultHealthCheckService(true);
  grpc::reflection::InitProtoReflectionServerBuilderPlugin();
  ConvertOptions convert;
  convert.allow_unstable = m.config.allow_unstable;
  m.service = std::make_unique<FoamService>(m.store, m.pool, convert);

  checkServerConfig(m.config);
  if (!isLoopback(m.config.listen) && m.config.token.empty())
    spdlog::warn(
        "foamd: --insecure-public: gRPC on {} with no token; anyone who reaches it can "
        "submit and cancel jobs",
        m.config.listen);
  std::shared_ptr<grpc::ServerCredentials> creds;
  const bool tls = !m.config.tls_cert.empty() || !m.config.tls_key.empty();
  if (tls) {
    if (m.config.tls_cert.empty() || m.config.tls_key.empty())
      throw std::runtime_error("TLS needs both --tls-cert and --tls-key");
    grpc::SslServerCredentialsOptions opts;
    opts.pem_key_cert_pairs.push_back({m.config.tls_key, m.config.tls_cert});
    creds = grpc::SslServerCredentials(opts);
  } else if (!m.config.token.empty()) {
    // A token needs a channel that is not plain text to the world: loopback (local
    // credentials; checkServerConfig refused a token elsewhere without TLS) or TLS.
    creds = grpc::experimental::LocalServerCredentials(LOCAL_TCP);
  } else {
    creds = grpc::InsecureServerCredentials();
  }
  if (!m.config.token.empty())
    creds->SetAuthMetadataProcessor(std::make_shared<TokenAuth>(m.config.token));

  if (const std::string why = loopbackSiblingTaken(m.config.listen); !why.empty())
    throw std::runtime_error("cannot listen on " + m.config.listen + ": " + why);
  grpc::ServerBuilder builder;
  // gRPC sets SO_REUSEPORT by default: a second foamd on a taken port would start and the
  // kernel would split the clients between the two servers (and their databases).
  builder.AddChannelArgument(GRPC_ARG_ALLOW_REUSEPORT, 0);
  builder.AddListeningPort(m.config.listen, creds, &m.port);
  builder.RegisterService(m.service.get());
  builder.SetMaxReceiveMessageSize(m.config.max_message_bytes);
  m.server = builder.BuildAndStart();
  if (!m.server || m.port == 0)
    throw std::runtime_error("cannot listen on " + m.config.listen +
                             ": the port is taken (another foamd?) or the address is not this "
                             "machine's");
  if (auto* health = m.server->GetHealthCheckService()) {
    health->SetServingStatus(!m.store.degraded());
    health->SetServingStatus("activefoam.v1.Foam", !m.store.degraded());
    // NOT_SERVING while the store's writes fail (reads still answer).
    m.store.setHealthListener([health](bool writable) {
      health->SetServingStatus(writable);
      health->SetServingStatus("activefoam.v1.Foam", writable);
    });
  }
  spdlog::info("foamd: gRPC on {} (port {}){}{}", m.config.listen, m.port, tls ? ", TLS" : "",
               m.config.token.empty() ? "" : ", token required");
}

int FoamServer::port() const {
  return impl_->port;
}

void FoamServer::shutdown() {
  impl_->store.setHealthListener(nullptr);
  if (impl_->server) {
    if (auto* health = impl_->server->GetHealthCheckService()) health->Shutdown();
    impl_->server->Shutdown(std::chrono::system_clock::now() + std::chrono::seconds(2));
    impl_->server->Wait();
    impl_->server.reset();
  }
  impl_->service.reset();
}

void FoamServer::wait() {
  if (impl_->server) impl_->server->Wait();
}

}  // namespace activefoam::server
