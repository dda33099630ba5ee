// SQLite job store (see store.h).
#include "store.h"

#include <chrono>
#include <cmath>
#include <cstring>
#include <ctime>
#include <filesystem>
#include <random>
#include <set>
#include <tuple>

#include <spdlog/spdlog.h>
#include <nlohmann/json.hpp>

#include "activefoam/run_output.h"
#include "heap_shm_vfs.h"
#include "store_sql.h"

namespace activefoam::server {

using namespace sql;

// ---- free helpers ---------------------------------------------------------------------------

std::string newId(const std::string& prefix) {
  static std::mutex mu;
  static std::mt19937_64 rng{std::random_device{}()};
  std::lock_guard lock(mu);
  char buf[32];
  std::snprintf(buf, sizeof buf, "%012llx",
                static_cast<unsigned long long>(rng() & 0xffffffffffffULL));
  return prefix + buf;
}

std::string utcNowText() {
  const auto now = std::chrono::system_clock::now();
  const std::time_t t = std::chrono::system_clock::to_time_t(now);
  const auto ms =
      std::chrono::duration_cast<std::chrono::milliseconds>(now.time_since_epoch()).count() % 1000;
  std::tm tm{};
  gmtime_r(&t, &tm);
  char buf[80];
  std::snprintf(buf, sizeof buf, "%04d-%02d-%02dT%02d:%02d:%02d.%03dZ", tm.tm_year + 1900,
                tm.tm_mon + 1, tm.tm_mday, tm.tm_hour, tm.tm_min, tm.tm_sec, static_cast<int>(ms));
  return buf;
}

const std::vector<std::string>& Store::paramKeys() {
  static const std::vector<std::string> keys = [] {
    std::vector<std::string> k;
    for (const auto& [name, col] : paramColumns()) k.push_back(name);
    return k;
  }();
  return keys;
}

// ---- writer ----------------------------------------------------------------------------------

struct Store::Tx {
  sqlite3* db;
  std::vector<std::string> touched;  // jobs with new events

  // Appends the next event of a job (seq = last_seq + 1).
  std::int64_t event(const std::string& id, v1::JobEvent ev) {
    Stmt up(db, "UPDATE jobs SET last_seq = last_seq + 1 WHERE id = ? RETURNING last_seq");
    up.bind(1, id);
    if (!up.step()) throw StoreError(StoreError::Kind::NotFound, "no job " + cappedQuote(id));
    const std::int64_t seq = up.i64(0);
    up.run();
    ev.set_seq(seq);
    ev.set_job_id(id);
    ev.set_time_utc(utcNowText());
    Stmt ins(db, "INSERT INTO events(job_id, seq, time_utc, data) VALUES (?, ?, ?, ?)");
    ins.bind(1, id).bind(2, seq).bind(3, ev.time_utc()).blob(4, ev.SerializeAsString());
    ins.run();
    touched.push_back(id);
    return seq;
  }
  // The only place a job's state changes (job_states.h): `from` → `to` if the job is in `from`
  // now; false when it is not (a race the caller expected: a cancel against a final report).
  // A change outside the table is a bug and throws.
  bool changeState(const std::string& id, v1::JobState from, v1::JobState to) {
    if (!allowedTransition(from, to))
      throw std::logic_error("store: job " + id + ": no transition " + v1::JobState_Name(from) +
                             " -> " + v1::JobState_Name(to));
    Stmt up(db, "UPDATE jobs SET state = ? WHERE id = ? AND state = ?");
    up.bind(1, static_cast<int>(to)).bind(2, id).bind(3, static_cast<int>(from)).run();
    return sqlite3_changes(db) > 0;
  }
  void stateEvent(const std::string& id) {
    v1::JobEvent ev;
    *ev.mutable_state() = requireJob(db, id);
    ev.mutable_state()->set_last_seq(ev.state().last_seq() + 1);
    event(id, std::move(ev));
  }
  // Index the next sample / snapshot of a job gets (one past the highest stored).
  std::int64_t nextIndex(const char* table, const std::string& id) {
    Stmt n(db,
           std::string("SELECT COALESCE(MAX(idx), -1) + 1 FROM ") + table + " WHERE job_id = ?");
    n.bind(1, id);
    n.step();
    return n.i64(0);
  }
  // Stores sample `idx` of a job with its event (the first also records the columns).
  void appendSample(const std::string& id, std::int64_t idx,
                    const std::vector<std::string>& columns, const std::vector<double>& values) {
    const double t = values.empty() ? 0.0 : values[0];
    Stmt ins(db, "INSERT INTO samples(job_id, idx, t_s, vals) VALUES (?,?,?,?)");
    ins.bind(1, id).bind(2, idx).bind(3, t).blob(4, packDoubles(values)).run();
    if (idx == 0) {
      Stmt c(db, "UPDATE jobs SET columns_json = ? WHERE id = ?");
      c.bind(1, nlohmann::json(columns).dump()).bind(2, id).run();
    }
    v1::JobEvent ev;
    ev.mutable_sample()->set_t_s(t);
    for (double v : values) ev.mutable_sample()->add_values(v);
    for (const std::string& c : columns) ev.add_columns(c);
    event(id, std::move(ev));
  }
  // Stores snapshot info.index() of a job with its event, keeping the newest `keep` (0 = all).
  void appendSnapshot(const std::string& id, const v1::SnapshotInfo& info,
                      const std::string& compression, const std::string& data, int keep) {
    Stmt ins(db,
             "INSERT INTO snapshots(job_id, idx, t_s, step, bytes, vertices, triangles, "
             "compression, data) VALUES (?,?,?,?,?,?,?,?,?)");
    ins.bind(1, id)
        .bind(2, info.index())
        .bind(3, info.t_s())
        .bind(4, info.step())
        .bind(5, info.bytes())
        .bind(6, info.vertices())
        .bind(7, info.triangles())
        .bind(8, compression)
        .blob(9, data)
        .run();
    if (keep > 0) {
      Stmt del(db, "DELETE FROM snapshots WHERE job_id = ? AND idx <= ?");
      del.bind(1, id).bind(2, info.index() - keep).run();
    }
    v1::JobEvent ev;
    *ev.mutable_snapshot() = info;
    event(id, std::move(ev));
  }
  void setProgress(const std::string& id, const v1::Progress& p) {
    Stmt up(db, "UPDATE jobs SET progress = ?, t_s = ?, steps = ? WHERE id = ?");
    up.bind(1, p.fraction()).bind(2, p.t_s()).bind(3, p.step()).bind(4, id).run();
    v1::JobEvent ev;
    *ev.mutable_progress() = p;
    event(id, std::move(ev));
  }
};

std::string cappedQuote(const std::string& value, std::size_t max) {
  if (value.size() <= max) return "'" + value + "'";
  return "'" + value.substr(0, max) + "'... (" + std::to_string(value.size()) + " bytes)";
}

namespace {

// Pages damaged on disk are found when foamd starts, not by the first query that happens to read
// them (health said SERVING, then ListJobs failed INTERNAL "database disk image is
// malformed"). quick_check reads every page once: ~0.1 s for 100 MB.
void checkIntegrity(sqlite3* db, const std::string& path) {
  std::string result;
  try {
    Stmt q(db, "PRAGMA quick_check(1)");
    if (q.step()) result = q.text(0);
  } catch (const SqliteError& e) {
    if (e.code == SQLITE_BUSY)
      throw std::runtime_error("database '" + path +
                               "' is open in another process (SQLite: database is locked): "
                               "foamd must be the only program using its database");
    result = e.what();
  }
  if (result == "ok") return;
  throw std::runtime_error("database '" + path +
                           "' is damaged (SQLite quick_check: " + result.substr(0, 300) +
                           "): restore it from a backup, or move it aside with its -wal and -shm "
                           "files to start on a new one; foamd does not serve a damaged store");
}

}  // namespace

DbCheck checkDatabase(const std::string& path) {
  namespace fs = std::filesystem;
  std::error_code ec;
  if (!fs::is_regular_file(path, ec))
    throw std::runtime_error("database '" + path + "': no such file");
  DbLock lock(path);
  sqlite3* db = nullptr;
  // Not openDb: a missing file must not be created, and the journal mode is left as it is.
  if (sqlite3_open_v2(path.c_str(), &db, SQLITE_OPEN_READWRITE, sql::heapShmVfs()->zName) !=
      SQLITE_OK) {
    const std::string msg = db ? sqlite3_errmsg(db) : "out of memory";
    sqlite3_close(db);
    throw std::runtime_error("cannot open database '" + path + "': " + msg);
  }
  DbCheck r;
  const auto t0 = std::chrono::steady_clock::now();
  try {
    Stmt q(db, "PRAGMA integrity_check(20)");
    while (q.step()) r.problems += (r.problems.empty() ? "" : "; ") + q.text(0);
  } catch (const SqliteError& e) {
    r.problems = e.what();  // a header or a page too damaged to walk
  }
  sqlite3_close(db);
  r.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  r.ok = r.problems == "ok";
  for (char& c : r.problems)
    if (c == '\n') c = ' ';
  r.bytes = static_cast<std::int64_t>(fs::file_size(path, ec));
  return r;
}

Store::Store(const std::string& path, StoreOptions options)
    : path_(path), options_(options), lock_(path) {
  try {
    wdb_ = openDb(path, options.busy_timeout_ms);
  } catch (const SqliteError& e) {
    if (e.code != SQLITE_CORRUPT && e.code != SQLITE_NOTADB) throw;
    throw std::runtime_error("database '" + path + "' is damaged (" + e.what() +
                             "): restore it from a backup, or move it aside with its -wal and "
                             "-shm files to start on a new one");
  }
  try {
    checkIntegrity(wdb_, path);
    migrateSchema(wdb_);
    rdb_ = openDb(path, options.busy_timeout_ms);
  } catch (...) {
    sqlite3_close(wdb_);
    throw;
  }
  writer_ = std::thread([this] { writerLoop(); });
}

Store::~Store() {
  {
    std::lock_guard lock(qmu_);
    stop_ = true;
  }
  qcv_.notify_all();
  writer_.join();
  sqlite3_close(rdb_);
  sqlite3_close(wdb_);
}

int Store::schemaVersion() {
  std::lock_guard lock(rmu_);
  Stmt v(rdb_, "PRAGMA user_version");
  v.step();
  return static_cast<int>(v.i64(0));
}

void Store::setEventListener(std::function<void(const std::string&)> listener) {
  // Under lmu_: once this returns, the writer runs the old listener no more (the service
  // clears it in its destructor; ASan caught the writer notifying a freed service).
  std::lock_guard lock(lmu_);
  listener_ = std::move(listener);
}

void Store::writerLoop() {
  for (;;) {
    std::deque<std::unique_ptr<Task>> batch;
    {
      std::unique_lock lock(qmu_);
      qcv_.wait(lock, [&] { return stop_ || !queue_.empty(); });
      if (queue_.empty()) return;  // stop_ and drained
      batch.swap(queue_);
      busy_ = true;
    }
    Tx tx{wdb_, {}};
    std::vector<std::exception_ptr> errors(batch.size());
    std::exception_ptr commit_error;
    // A batch that fails on the storage (disk full, I/O error) is rolled back and run again,
    // whole and in order, with backoff, until it commits: nothing queued is dropped. Meanwhile
    // the store is degraded (health NOT_SERVING, new submits refused) and reads go on.
    for (int attempt = 0;; ++attempt) {
      commit_error = nullptr;
      std::fill(errors.begin(), errors.end(), nullptr);
      tx.touched.clear();
      try {
        exec(wdb_, "BEGIN IMMEDIATE");
        for (std::size_t i = 0; i < batch.size(); ++i) {
          const std::size_t mark = tx.touched.size();
          exec(wdb_, "SAVEPOINT w");
          try {
            batch[i]->fn(tx);
            exec(wdb_, "RELEASE w");
          } catch (...) {
            // A statement that failed on the storage fails the whole batch (retried below);
            // any other error is this task's alone.
            if (storageFailure(std::current_exception())) throw;
            errors[i] = std::current_exception();
            tx.touched.resize(mark);
            exec(wdb_, "ROLLBACK TO w; RELEASE w");
          }
        }
        exec(wdb_, "COMMIT");
      } catch (...) {
        commit_error = std::current_exception();
        sqlite3_exec(wdb_, "ROLLBACK", nullptr, nullptr, nullptr);
        tx.touched.clear();
      }
      if (!commit_error || !storageFailure(commit_error)) break;
      std::string what;
      try {
        std::rethrow_exception(commit_error);
      } catch (const std::exception& e) {
        what = e.what();
      }
      store_errors_.fetch_add(1);
      {
        std::lock_guard lock(emu_);
        last_error_ = what;
      }
      if (!degraded_.exchange(true)) {
        spdlog::error(
            "store: a write to {} failed: {}; {} queued write(s) are kept and retried "
            "with backoff, new submits are refused until it succeeds",
            path_, what, batch.size());
        notifyHealth(false);
      } else if (attempt % 20 == 0) {
        spdlog::error("store: writes still failing after {} tries: {}", attempt + 1, what);
      }
      std::unique_lock lock(qmu_);
      if (stop_) {
        spdlog::error("store: closing while writes fail: {} write(s) not committed", batch.size());
        break;
      }
      const auto backoff = std::chrono::milliseconds(std::min(5000, 50 << std::min(attempt, 7)));
      qcv_.wait_for(lock, backoff, [&] { return stop_; });
    }
    if (!commit_error && degraded_.exchange(false)) {
      spdlog::info("store: writes succeed again ({} failure(s) so far)", store_errors_.load());
      notifyHealth(true);
    }
    for (std::size_t i = 0; i < batch.size(); ++i) {
      if (commit_error)
        batch[i]->done.set_exception(commit_error);
      else if (errors[i])
        batch[i]->done.set_exception(errors[i]);
      else
        batch[i]->done.set_value();
    }
    {
      std::lock_guard lock(lmu_);
      if (listener_) {
        std::sort(tx.touched.begin(), tx.touched.end());
        tx.touched.erase(std::unique(tx.touched.begin(), tx.touched.end()), tx.touched.end());
        for (const std::string& id : tx.touched) listener_(id);
      }
    }
    {
      std::lock_guard lock(qmu_);
      busy_ = false;
    }
    idle_cv_.notify_all();
  }
}

template <class F>
auto Store::write(F f) -> decltype(f(std::declval<Tx&>())) {
  using R = decltype(f(std::declval<Tx&>()));
  auto task = std::make_unique<Task>();
  std::future<void> done = task->done.get_future();
  std::optional<std::conditional_t<std::is_void_v<R>, int, R>> result;
  task->fn = [&](Tx& tx) {
    if constexpr (std::is_void_v<R>)
      f(tx);
    else
      result = f(tx);
  };
  {
    std::lock_guard lock(qmu_);
    if (stop_) throw std::runtime_error("store is closed");
    queue_.push_back(std::move(task));
  }
  qcv_.notify_one();
  done.get();  // rethrows the task's error
  if constexpr (!std::is_void_v<R>) return std::move(*result);
}

void Store::post(std::function<void(Tx&)> fn) {
  auto task = std::make_unique<Task>();
  task->fn = [fn = std::move(fn)](Tx& tx) {
    try {
      fn(tx);
    } catch (const SqliteError& e) {
      if (!storageFailure(e.code))  // storage failures are retried and logged by the writer
        spdlog::error("store: background write failed: {}", e.what());
      throw;
    } catch (const std::exception& e) {
      spdlog::error("store: background write failed: {}", e.what());
      throw;
    }
  };
  {
    std::lock_guard lock(qmu_);
    if (stop_) return;
    queue_.push_back(std::move(task));
  }
  qcv_.notify_one();
}

void Store::flush() {
  write([](Tx&) {});
}

// ---- job writes ------------------------------------------------------------------------------

namespace {

std::string insertJob(sqlite3* db, const NewJob& j, const std::string& id) {
  const SceneSpec& s = j.spec;
  const nlohmann::json reduced = reducedParameters(s);
  Stmt ins(db,
           "INSERT INTO jobs(id, state, scene, seed, priority, tag, sweep_id, idem_key, spec_json, "
           "engine_version, created_utc, p_duration_s, p_dt_s, p_alpha, p_p_a, p_pa_reduced, "
           "p_tau_p_s, p_xi, p_gamma, p_eta, p_k_contact, p_n_cells, p_triangles_per_cell) "
           "VALUES (?,?,?,?,?,?,?,?,?,?,?,?,?,?,?,?,?,?,?,?,?,?,?)");
  ins.bind(1, id)
      .bind(2, static_cast<int>(v1::JOB_STATE_QUEUED))
      .bind(3, std::string(toString(s.scene)))
      .bind(4, static_cast<std::int64_t>(s.seed))
      .bind(5, j.priority)
      .bind(6, j.tag)
      .bind(7, j.sweep_id);
  if (j.idempotency_key.empty())
    ins.null(8);
  else
    ins.bind(8, j.idempotency_key);
  ins.bind(9, j.spec_json)
      .bind(10, ACTIVEFOAM_VERSION)
      .bind(11, utcNowText())
      .bind(12, s.duration_s)
      .bind(13, s.numerics.dt_s)
      .bind(14, s.cells.alpha)
      .bind(15, s.cells.p_a)
      .bind(16, reduced.value("pa_reduced", 0.0))
      .bind(17, s.cells.tau_p_s)
      .bind(18, s.cells.xi)
      .bind(19, s.cells.gamma)
      .bind(20, s.cells.eta)
      .bind(21, s.cells.k_contact)
      .bind(22, sceneCellCount(s))
      .bind(23, s.numerics.triangles_per_cell);
  ins.run();
  return id;
}

}  // namespace

std::pair<std::string, bool> Store::submit(const NewJob& job) {
  return write([&](Tx& tx) -> std::pair<std::string, bool> {
    if (!job.idempotency_key.empty()) {
      Stmt q(tx.db, "SELECT id, spec_json, priority, tag FROM jobs WHERE idem_key = ?");
      q.bind(1, job.idempotency_key);
      if (q.step()) {
        if (q.text(1) != job.spec_json || q.i64(2) != job.priority || q.text(3) != job.tag)
          throw StoreError(StoreError::Kind::FailedPrecondition,
                           "idempotency_key '" + job.idempotency_key + "' was used for job " +
                               q.text(0) + " with a different request");
        return {q.text(0), false};
      }
    }
    const std::string id = insertJob(tx.db, job, newId("j-"));
    tx.stateEvent(id);
    return {id, true};
  });
}

std::tuple<std::string, std::vector<std::string>, bool> Store::submitSweep(
    const std::string& name, const std::string& idem, const std::vector<NewJob>& jobs,
    const std::vector<std::string>& keys) {
  return write([&](Tx& tx) -> std::tuple<std::string, std::vector<std::string>, bool> {
    if (!idem.empty()) {
      Stmt q(tx.db, "SELECT id FROM sweeps WHERE idem_key = ?");
      q.bind(1, idem);
      if (q.step()) {
        // The same request again gets the sweep it made; another request under the key is
        // refused, as SubmitJob refuses one (it was answered with the old sweep in silence).
        const std::string sid = q.text(0);
        Stmt js(tx.db,
                "SELECT id, spec_json, priority, tag FROM jobs WHERE sweep_id = ? ORDER BY seqno");
        js.bind(1, sid);
        std::vector<std::string> ids;
        bool same = true;
        while (js.step()) {
          const std::size_t k = ids.size();
          same = same && k < jobs.size() && js.text(1) == jobs[k].spec_json &&
                 js.i64(2) == jobs[k].priority && js.text(3) == jobs[k].tag;
          ids.push_back(js.text(0));
        }
        if (!same || ids.size() != jobs.size())
          throw StoreError(StoreError::Kind::FailedPrecondition, "idempotency_key '" + idem +
                                                                     "' was used for sweep " + sid +
                                                                     " with a different request");
        return {sid, ids, false};
      }
    }
    const std::string sid = newId("s-");
    Stmt ins(tx.db,
             "INSERT INTO sweeps(id, name, idem_key, created_utc, n_jobs, keys_json) VALUES "
             "(?,?,?,?,?,?)");
    ins.bind(1, sid).bind(2, name).bind(6, nlohmann::json(keys).dump());
    if (idem.empty())
      ins.null(3);
    else
      ins.bind(3, idem);
    ins.bind(4, utcNowText()).bind(5, static_cast<std::int64_t>(jobs.size()));
    ins.run();
    std::vector<std::string> ids;
    for (NewJob j : jobs) {
      j.sweep_id = sid;
      j.idempotency_key.clear();
      ids.push_back(insertJob(tx.db, j, newId("j-")));
      tx.stateEvent(ids.back());
    }
    return {sid, ids, true};
  });
}

std::optional<Claimed> Store::claimNext() {
  std::vector<Claimed> c = claimQueued(1, true);
  if (c.empty()) return std::nullopt;
  return std::move(c.front());
}

std::vector<Claimed> Store::claimQueued(int max, bool with_checkpoint) {
  return write([&](Tx& tx) {
    std::vector<std::string> ids;
    Stmt q(tx.db, "SELECT id FROM jobs WHERE state = ? ORDER BY priority DESC, seqno ASC LIMIT ?");
    q.bind(1, static_cast<int>(v1::JOB_STATE_QUEUED)).bind(2, max);
    while (q.step()) ids.push_back(q.text(0));
    std::vector<Claimed> out;
    for (const std::string& id : ids) {
      tx.changeState(id, v1::JOB_STATE_QUEUED, v1::JOB_STATE_RUNNING);
      Stmt up(tx.db,
              "UPDATE jobs SET attempts = attempts + 1, started_utc = ?, reason = '', "
              "executor_ref = '' WHERE id = ?");
      up.bind(1, utcNowText()).bind(2, id);
      up.run();
      tx.stateEvent(id);
      Claimed c;
      c.job = requireJob(tx.db, id);
      Stmt ck(tx.db, "SELECT t_s, data FROM checkpoints WHERE job_id = ?");
      ck.bind(1, id);
      if (ck.step()) {
        c.checkpoint_t_s = ck.dbl(0);
        if (with_checkpoint) c.checkpoint = ck.text(1);
      }
      out.push_back(std::move(c));
    }
    return out;
  });
}

void Store::setExecutorRef(const std::string& id, const std::string& ref) {
  write([&](Tx& tx) {
    Stmt up(tx.db, "UPDATE jobs SET executor_ref = ? WHERE id = ?");
    up.bind(1, ref).bind(2, id).run();
    tx.stateEvent(id);
  });
}

Store::Held Store::ingestReport(
    const std::string& id, const std::vector<std::string>& columns, std::int64_t first_sample,
    const std::vector<std::vector<double>>& samples, int first_snapshot,
    const std::vector<std::pair<v1::SnapshotInfo, std::string>>& snapshots,
    const std::optional<v1::Progress>& progress) {
  return write([&](Tx& tx) {
    Held held;
    // Only the next index is taken: held already (a repeated report) or beyond a gap (waits for
    // the earlier ones) is skipped.
    held.samples = tx.nextIndex("samples", id);
    for (std::size_t k = 0; k < samples.size(); ++k)
      if (first_sample + static_cast<std::int64_t>(k) == held.samples)
        tx.appendSample(id, held.samples++, columns, samples[k]);
    held.snapshots = static_cast<int>(tx.nextIndex("snapshots", id));
    for (std::size_t k = 0; k < snapshots.size(); ++k) {
      if (first_snapshot + static_cast<int>(k) != held.snapshots) continue;
      v1::SnapshotInfo info = snapshots[k].first;
      info.set_index(held.snapshots++);
      tx.appendSnapshot(id, info, "zlib", snapshots[k].second, options_.keep_snapshots);
    }
    if (progress) tx.setProgress(id, *progress);
    return held;
  });
}

std::string Store::lastError() const {
  std::lock_guard lock(emu_);
  return last_error_;
}

void Store::setHealthListener(std::function<void(bool)> listener) {
  std::lock_guard lock(lmu_);  // as setEventListener: no call of the old one after this
  health_listener_ = std::move(listener);
}

void Store::notifyHealth(bool writable) {
  std::lock_guard lock(lmu_);
  if (health_listener_) health_listener_(writable);
}

v1::Job Store::cancel(const std::string& id, const std::string& reason) {
  return write([&](Tx& tx) -> v1::Job {
    v1::Job j = requireJob(tx.db, id);
    if (tx.changeState(id, v1::JOB_STATE_QUEUED, v1::JOB_STATE_CANCELLED)) {
      Stmt up(tx.db,
              "UPDATE jobs SET reason = ?, failure_kind = 'cancelled', finished_utc = ? WHERE "
              "id = ?");
      up.bind(1, reason.empty() ? std::string("cancelled before it started") : reason)
          .bind(2, utcNowText())
          .bind(3, id);
      up.run();
      Stmt del(tx.db, "DELETE FROM checkpoints WHERE job_id = ?");
      del.bind(1, id).run();
      tx.stateEvent(id);
      j = requireJob(tx.db, id);
    }
    return j;
  });
}

bool Store::finish(const std::string& id, v1::JobState state, const std::string& failure_kind,
                   const std::string& reason,
                   const std::vector<std::pair<std::string, double>>& results, double t_s,
                   std::int64_t steps, const std::string& outcome,
                   const std::vector<FlatCurve>& curves) {
  return write([&](Tx& tx) {
    if (!isTerminal(state))
      throw std::logic_error("store: finish(" + id + ") with " + v1::JobState_Name(state) +
                             ", not an end state");
    // Only a running job ends, once: a cancel racing a task's final report (Slurm) must not
    // turn one outcome into another.
    if (!tx.changeState(id, v1::JOB_STATE_RUNNING, state)) return false;
    Stmt up(tx.db,
            "UPDATE jobs SET failure_kind = ?, reason = ?, finished_utc = ?, t_s = ?, steps = ?, "
            "progress = CASE WHEN ? THEN 1 ELSE progress END, outcome = ? WHERE id = ?");
    up.bind(1, failure_kind)
        .bind(2, reason)
        .bind(3, utcNowText())
        .bind(4, t_s)
        .bind(5, steps)
        .bind(6, state == v1::JOB_STATE_SUCCEEDED ? 1 : 0)
        .bind(7, outcome)
        .bind(8, id);
    up.run();
    Stmt del(tx.db, "DELETE FROM results WHERE job_id = ?");
    del.bind(1, id).run();
    for (const auto& [name, value] : results) {
      Stmt ins(tx.db, "INSERT OR REPLACE INTO results(job_id, name, value) VALUES (?,?,?)");
      ins.bind(1, id).bind(2, name).bind(3, value).run();
    }
    Stmt delc(tx.db, "DELETE FROM curves WHERE job_id = ?");
    delc.bind(1, id).run();
    for (const FlatCurve& c : curves) {
      Stmt ins(tx.db, "INSERT OR REPLACE INTO curves(job_id, name, x, y) VALUES (?,?,?,?)");
      ins.bind(1, id).bind(2, c.name).blob(3, packDoubles(c.x)).blob(4, packDoubles(c.y)).run();
    }
    Stmt ck(tx.db, "DELETE FROM checkpoints WHERE job_id = ?");
    ck.bind(1, id).run();
    tx.stateEvent(id);
    return true;
  });
}

bool Store::requeue(const std::string& id, const std::string& reason) {
  return write([&](Tx& tx) {
    if (!tx.changeState(id, v1::JOB_STATE_RUNNING, v1::JOB_STATE_QUEUED)) return false;
    Stmt up(tx.db, "UPDATE jobs SET reason = ?, executor_ref = '' WHERE id = ?");
    up.bind(1, reason).bind(2, id).run();
    tx.stateEvent(id);
    return true;
  });
}

int Store::requeueAll(Tx& tx, const std::string& reason) {
  std::vector<std::string> ids;
  Stmt q(tx.db, "SELECT id FROM jobs WHERE state = ?");
  q.bind(1, static_cast<int>(v1::JOB_STATE_RUNNING));
  while (q.step()) ids.push_back(q.text(0));
  for (const std::string& id : ids) {
    tx.changeState(id, v1::JOB_STATE_RUNNING, v1::JOB_STATE_QUEUED);
    Stmt up(tx.db, "UPDATE jobs SET reason = ?, executor_ref = '' WHERE id = ?");
    up.bind(1, reason).bind(2, id).run();
    tx.stateEvent(id);
  }
  return static_cast<int>(ids.size());
}

int Store::requeueRunning(const std::string& reason) {
  return write([&](Tx& tx) { return requeueAll(tx, reason); });
}

int Store::requeueRunningInBackground(const std::string& reason) {
  const int n = static_cast<int>(runningJobs().size());
  post([reason](Tx& tx) { requeueAll(tx, reason); });
  return n;
}

void Store::resetOutputs(const std::string& id, std::optional<double> keep_until) {
  write([&](Tx& tx) {
    const double t = keep_until.value_or(-1e300);
    for (const char* table : {"samples", "snapshots"}) {
      Stmt del(tx.db, std::string("DELETE FROM ") + table + " WHERE job_id = ? AND t_s > ?");
      del.bind(1, id).bind(2, t).run();
    }
    for (const char* table : {"results", "curves"}) {
      Stmt r(tx.db, std::string("DELETE FROM ") + table + " WHERE job_id = ?");
      r.bind(1, id).run();
    }
  });
}

void Store::dropCheckpoint(const std::string& id) {
  write([&](Tx& tx) {
    Stmt del(tx.db, "DELETE FROM checkpoints WHERE job_id = ?");
    del.bind(1, id).run();
  });
}

// ---- running-job writes (posted) -------------------------------------------------------------

void Store::addSample(const std::string& id, const std::vector<std::string>& columns,
                      const std::vector<double>& values) {
  post([=](Tx& tx) { tx.appendSample(id, tx.nextIndex("samples", id), columns, values); });
}

void Store::addProgress(const std::string& id, const v1::Progress& p) {
  post([=](Tx& tx) { tx.setProgress(id, p); });
}

void Store::addSnapshot(const std::string& id, const v1::SnapshotInfo& info_in,
                        const std::string& compression, std::string data) {
  post([=, this, data = std::move(data)](Tx& tx) {
    v1::SnapshotInfo info = info_in;
    info.set_index(static_cast<int>(tx.nextIndex("snapshots", id)));
    tx.appendSnapshot(id, info, compression, data, options_.keep_snapshots);
  });
}

void Store::saveCheckpoint(const std::string& id, double t_s, std::string data) {
  // One statement in a transaction: the old checkpoint or the new one, never half of one.
  post([=, data = std::move(data)](Tx& tx) {
    Stmt ins(tx.db,
             "INSERT OR REPLACE INTO checkpoints(job_id, t_s, data, written_utc) VALUES (?,?,?,?)");
    ins.bind(1, id).bind(2, t_s).blob(3, data).bind(4, utcNowText()).run();
  });
}

}  // namespace activefoam::server
