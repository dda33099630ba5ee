// SQLite job store (see store.h).
#include "store.h"

#include <fcntl.h>
#include <sqlite3.h>
#include <sys/file.h>
#include <unistd.h>

#include <cctype>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstring>
#include <ctime>
#include <random>
#include <set>
#include <tuple>

#include <spdlog/spdlog.h>
#include <nlohmann/json.hpp>

#include "activefoam/run_output.h"

namespace activefoam::server {
namespace {

// ---- small SQLite helpers ----------------------------------------------------------------

// An SQLite failure with its primary result code, so that the writer can tell the storage
// failing (disk full, I/O error: retried) from a bad statement (a bug: reported).
struct SqliteError : std::runtime_error {
  int code;
  SqliteError(int c, const std::string& what) : std::runtime_error(what), code(c & 0xff) {}
};

// Failures of the storage, not of the statement: the same write may succeed later.
bool storageFailure(int code) {
  switch (code) {
    case SQLITE_FULL:
    case SQLITE_IOERR:
    case SQLITE_READONLY:
    case SQLITE_CANTOPEN:
    case SQLITE_NOMEM:
    case SQLITE_BUSY:
    case SQLITE_LOCKED:
    case SQLITE_PROTOCOL:
      return true;
    default:
      return false;
  }
}

bool storageFailure(const std::exception_ptr& e) {
  try {
    std::rethrow_exception(e);
  } catch (const SqliteError& s) {
    return storageFailure(s.code);
  } catch (...) {
    return false;
  }
}

void check(int rc, sqlite3* db, const char* what) {
  if (rc != SQLITE_OK && rc != SQLITE_DONE && rc != SQLITE_ROW)
    throw SqliteError(rc, std::string(what) + ": " + sqlite3_errmsg(db));
}

void exec(sqlite3* db, const std::string& sql) {
  char* err = nullptr;
  if (const int rc = sqlite3_exec(db, sql.c_str(), nullptr, nullptr, &err); rc != SQLITE_OK) {
    std::string msg = err ? err : "?";
    sqlite3_free(err);
    throw SqliteError(rc, "sqlite: " + msg + " in: " + sql.substr(0, 80));
  }
}

class Stmt {
 public:
  Stmt(sqlite3* db, const std::string& sql) : db_(db) {
    check(sqlite3_prepare_v2(db, sql.c_str(), -1, &st_, nullptr), db, sql.c_str());
  }
  ~Stmt() { sqlite3_finalize(st_); }
  Stmt(const Stmt&) = delete;
  Stmt& operator=(const Stmt&) = delete;

  Stmt& bind(int i, const std::string& v) {
    sqlite3_bind_text(st_, i, v.data(), static_cast<int>(v.size()), SQLITE_TRANSIENT);
    return *this;
  }
  Stmt& bind(int i, const char* v) { return bind(i, std::string(v)); }
  Stmt& bind(int i, double v) {
    sqlite3_bind_double(st_, i, v);
    return *this;
  }
  Stmt& bind(int i, std::int64_t v) {
    sqlite3_bind_int64(st_, i, v);
    return *this;
  }
  Stmt& bind(int i, int v) { return bind(i, static_cast<std::int64_t>(v)); }
  Stmt& blob(int i, const std::string& v) {
    sqlite3_bind_blob(st_, i, v.data(), static_cast<int>(v.size()), SQLITE_TRANSIENT);
    return *this;
  }
  Stmt& null(int i) {
    sqlite3_bind_null(st_, i);
    return *this;
  }
  bool step() {
    const int rc = sqlite3_step(st_);
    check(rc, db_, "step");
    return rc == SQLITE_ROW;
  }
  void run() {
    while (step()) {
    }
  }
  std::int64_t i64(int c) { return sqlite3_column_int64(st_, c); }
  double dbl(int c) { return sqlite3_column_double(st_, c); }
  bool isNull(int c) { return sqlite3_column_type(st_, c) == SQLITE_NULL; }
  std::string text(int c) {
    const auto* p = reinterpret_cast<const char*>(sqlite3_column_blob(st_, c));
    return p ? std::string(p, sqlite3_column_bytes(st_, c)) : std::string();
  }

 private:
  sqlite3* db_;
  sqlite3_stmt* st_ = nullptr;
};

sqlite3* openDb(const std::string& path, int busy_ms) {
  sqlite3* db = nullptr;
  if (sqlite3_open_v2(path.c_str(), &db,
                      SQLITE_OPEN_READWRITE | SQLITE_OPEN_CREATE | SQLITE_OPEN_NOMUTEX,
                      nullptr) != SQLITE_OK) {
    std::string msg = db ? sqlite3_errmsg(db) : "out of memory";
    sqlite3_close(db);
    throw std::runtime_error("cannot open database '" + path + "': " + msg);
  }
  sqlite3_busy_timeout(db, busy_ms);
  exec(db, "PRAGMA journal_mode=WAL; PRAGMA synchronous=FULL; PRAGMA foreign_keys=ON;");
  return db;
}

// Migrations: entry i brings the schema from version i to i + 1.
const std::vector<std::string> kMigrations = {
    R"sql(
CREATE TABLE jobs(
  seqno INTEGER PRIMARY KEY AUTOINCREMENT,
  id TEXT NOT NULL UNIQUE,
  state INTEGER NOT NULL,
  reason TEXT NOT NULL DEFAULT '',
  failure_kind TEXT NOT NULL DEFAULT '',
  scene TEXT NOT NULL,
  seed INTEGER NOT NULL,
  priority INTEGER NOT NULL DEFAULT 0,
  tag TEXT NOT NULL DEFAULT '',
  sweep_id TEXT NOT NULL DEFAULT '',
  idem_key TEXT UNIQUE,
  spec_json TEXT NOT NULL,
  engine_version TEXT NOT NULL,
  created_utc TEXT NOT NULL,
  started_utc TEXT NOT NULL DEFAULT '',
  finished_utc TEXT NOT NULL DEFAULT '',
  progress REAL NOT NULL DEFAULT 0,
  t_s REAL NOT NULL DEFAULT 0,
  steps INTEGER NOT NULL DEFAULT 0,
  attempts INTEGER NOT NULL DEFAULT 0,
  last_seq INTEGER NOT NULL DEFAULT 0,
  columns_json TEXT NOT NULL DEFAULT '[]',
  p_duration_s REAL, p_dt_s REAL, p_alpha REAL, p_p_a REAL, p_pa_reduced REAL, p_tau_p_s REAL,
  p_xi REAL, p_gamma REAL, p_eta REAL, p_k_contact REAL, p_n_cells INTEGER,
  p_triangles_per_cell INTEGER);
CREATE INDEX jobs_queue ON jobs(state, priority DESC, seqno);
CREATE INDEX jobs_tag ON jobs(tag);
CREATE INDEX jobs_sweep ON jobs(sweep_id);
CREATE TABLE events(job_id TEXT NOT NULL, seq INTEGER NOT NULL, time_utc TEXT NOT NULL,
  data BLOB NOT NULL, PRIMARY KEY(job_id, seq)) WITHOUT ROWID;
CREATE TABLE samples(job_id TEXT NOT NULL, idx INTEGER NOT NULL, t_s REAL NOT NULL,
  vals BLOB NOT NULL, PRIMARY KEY(job_id, idx)) WITHOUT ROWID;
CREATE TABLE results(job_id TEXT NOT NULL, name TEXT NOT NULL, value REAL,
  PRIMARY KEY(job_id, name)) WITHOUT ROWID;
CREATE TABLE snapshots(job_id TEXT NOT NULL, idx INTEGER NOT NULL, t_s REAL NOT NULL,
  step INTEGER NOT NULL, bytes INTEGER NOT NULL, vertices INTEGER NOT NULL,
  triangles INTEGER NOT NULL, compression TEXT NOT NULL, data BLOB NOT NULL,
  PRIMARY KEY(job_id, idx));
CREATE TABLE checkpoints(job_id TEXT PRIMARY KEY, t_s REAL NOT NULL, data BLOB NOT NULL,
  written_utc TEXT NOT NULL);
CREATE TABLE sweeps(id TEXT PRIMARY KEY, name TEXT NOT NULL DEFAULT '', idem_key TEXT UNIQUE,
  created_utc TEXT NOT NULL, n_jobs INTEGER NOT NULL);
)sql",
    // 1 → 2: executors other than the pool (Slurm) record where a running job runs.
    R"sql(
ALTER TABLE jobs ADD COLUMN executor_ref TEXT NOT NULL DEFAULT '';
)sql",
    // 2 → 3: how a fusion job ended (fused, arrested, separated, no-contact), to filter on.
    R"sql(
ALTER TABLE jobs ADD COLUMN outcome TEXT NOT NULL DEFAULT '';
CREATE INDEX jobs_outcome ON jobs(outcome);
)sql",
    // 3 → 4: the spec keys a sweep varies (its grid's, or its parameter sets'), for its tables.
    R"sql(
ALTER TABLE sweeps ADD COLUMN keys_json TEXT NOT NULL DEFAULT '[]';
)sql",
};

const char* kJobCols =
    "id, state, reason, failure_kind, scene, seed, priority, tag, sweep_id, spec_json, "
    "engine_version, created_utc, started_utc, finished_utc, progress, t_s, steps, attempts, "
    "last_seq, executor_ref, outcome";

v1::Job readJob(Stmt& s) {
  v1::Job j;
  j.set_id(s.text(0));
  j.set_state(static_cast<v1::JobState>(s.i64(1)));
  j.set_reason(s.text(2));
  j.set_failure_kind(s.text(3));
  j.set_scene(s.text(4));
  j.set_seed(static_cast<std::uint64_t>(s.i64(5)));
  j.set_priority(static_cast<int>(s.i64(6)));
  j.set_tag(s.text(7));
  j.set_sweep_id(s.text(8));
  j.set_spec_json(s.text(9));
  j.set_engine_version(s.text(10));
  j.set_created_utc(s.text(11));
  j.set_started_utc(s.text(12));
  j.set_finished_utc(s.text(13));
  j.set_progress(s.dbl(14));
  j.set_t_s(s.dbl(15));
  j.set_steps(s.i64(16));
  j.set_attempts(static_cast<int>(s.i64(17)));
  j.set_last_seq(s.i64(18));
  j.set_executor_ref(s.text(19));
  j.set_outcome(s.text(20));
  return j;
}

std::optional<v1::Job> loadJob(sqlite3* db, const std::string& id) {
  Stmt s(db, std::string("SELECT ") + kJobCols + " FROM jobs WHERE id = ?");
  s.bind(1, id);
  if (!s.step()) return std::nullopt;
  return readJob(s);
}

v1::Job requireJob(sqlite3* db, const std::string& id) {
  auto j = loadJob(db, id);
  if (!j) throw StoreError(StoreError::Kind::NotFound, "no job " + cappedQuote(id));
  return *j;
}

std::string packDoubles(const std::vector<double>& v) {
  std::string s(v.size() * sizeof(double), '\0');
  if (!v.empty()) std::memcpy(s.data(), v.data(), s.size());
  return s;
}
std::vector<double> unpackDoubles(const std::string& s) {
  std::vector<double> v(s.size() / sizeof(double));
  if (!v.empty()) std::memcpy(v.data(), s.data(), v.size() * sizeof(double));
  return v;
}

// Parameter filter key → column ("cells.alpha" and "alpha" alike).
const std::map<std::string, std::string>& paramColumns() {
  static const std::map<std::string, std::string> m = {
      {"seed", "seed"},
      {"duration_s", "p_duration_s"},
      {"dt_s", "p_dt_s"},
      {"alpha", "p_alpha"},
      {"p_a", "p_p_a"},
      {"pa_reduced", "p_pa_reduced"},
      {"tau_p_s", "p_tau_p_s"},
      {"xi", "p_xi"},
      {"gamma", "p_gamma"},
      {"eta", "p_eta"},
      {"k_contact", "p_k_contact"},
      {"n_cells", "p_n_cells"},
      {"triangles_per_cell", "p_triangles_per_cell"},
  };
  return m;
}

// WHERE clause and its bound values for the common filters.
struct Where {
  std::string sql = " WHERE 1";
  std::vector<std::variant<std::string, double, std::int64_t>> args;
  void add(const std::string& cond, std::variant<std::string, double, std::int64_t> v) {
    sql += " AND " + cond;
    args.push_back(std::move(v));
  }
  void bindAll(Stmt& s) const {
    int i = 1;
    for (const auto& a : args) std::visit([&](const auto& v) { s.bind(i++, v); }, a);
  }
};

void addOutcomeFilter(Where& w, const std::string& outcome) {
  if (outcome.empty()) return;
  static const std::set<std::string> kOutcomes = {"fused", "arrested", "separated", "no-contact"};
  if (!kOutcomes.count(outcome))
    throw StoreError(StoreError::Kind::InvalidArgument,
                     "outcome: '" + outcome.substr(0, 64) +
                         "' is not one of fused|arrested|separated|no-contact");
  w.add("outcome = ?", outcome);
}

void addParamFilters(Where& w, const google::protobuf::RepeatedPtrField<v1::ParamRange>& ranges) {
  for (const v1::ParamRange& r : ranges) {
    std::string key = r.key();
    if (auto dot = key.rfind('.'); dot != std::string::npos) key = key.substr(dot + 1);
    const auto it = paramColumns().find(key);
    if (it == paramColumns().end()) {
      std::string allowed;
      for (const auto& [k, c] : paramColumns()) {
        if (!allowed.empty()) allowed += "|";
        allowed += k;
      }
      throw StoreError(StoreError::Kind::InvalidArgument,
                       "params.key: unknown parameter '" + r.key() + "', one of " + allowed);
    }
    for (const auto& [has, v, name] :
         {std::tuple{r.has_min(), r.min(), "min"}, std::tuple{r.has_max(), r.max(), "max"}})
      if (has && std::isnan(v))
        throw StoreError(
            StoreError::Kind::InvalidArgument,
            "params[" + cappedQuote(r.key(), 64) + "]." + name + ": NaN is not a bound");
    if (r.has_min()) w.add(it->second + " >= ?", r.min());
    if (r.has_max()) w.add(it->second + " <= ?", r.max());
  }
}

}  // namespace

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

bool isTerminal(v1::JobState s) {
  return s == v1::JOB_STATE_SUCCEEDED || s == v1::JOB_STATE_FAILED || s == v1::JOB_STATE_CANCELLED;
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

DbLock::DbLock(const std::string& db_path) {
  const std::string lock_path = db_path + ".lock";
  fd_ = ::open(lock_path.c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0644);
  if (fd_ < 0)
    throw std::runtime_error("cannot open lock file '" + lock_path + "': " + std::strerror(errno));
  if (::flock(fd_, LOCK_EX | LOCK_NB) != 0) {
    const int err = errno;
    std::string holder;
    char buf[256];
    const ssize_t n = ::pread(fd_, buf, sizeof buf - 1, 0);
    if (n > 0) holder.assign(buf, static_cast<std::size_t>(n));
    while (!holder.empty() && std::isspace(static_cast<unsigned char>(holder.back())))
      holder.pop_back();
    ::close(fd_);
    fd_ = -1;
    if (err != EWOULDBLOCK)
      throw std::runtime_error("cannot lock '" + lock_path + "': " + std::strerror(err));
    throw StoreError(StoreError::Kind::FailedPrecondition,
                     "database '" + db_path + "' is in use by another foamd (" +
                         (holder.empty() ? std::string("holder unknown") : holder) + "; lock " +
                         lock_path +
                         "): one server per database — stop it first, or give this one its own "
                         "--db");
  }
  char host[256] = "?";
  ::gethostname(host, sizeof host - 1);
  const std::string who =
      "pid " + std::to_string(::getpid()) + " on " + host + ", since " + utcNowText() + "\n";
  if (::ftruncate(fd_, 0) != 0 || ::pwrite(fd_, who.data(), who.size(), 0) < 0)
    spdlog::warn("store: cannot record the holder in '{}': {}", lock_path, std::strerror(errno));
}

DbLock::~DbLock() {
  if (fd_ >= 0) ::close(fd_);  // releases the flock
}

Store::Store(const std::string& path, StoreOptions options)
    : path_(path), options_(options), lock_(path) {
  wdb_ = openDb(path, options.busy_timeout_ms);
  try {
    migrate();
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

void Store::migrate() {
  exec(wdb_, "BEGIN IMMEDIATE");
  try {
    Stmt v(wdb_, "PRAGMA user_version");
    v.step();
    int version = static_cast<int>(v.i64(0));
    if (version > kSchemaVersion)
      throw std::runtime_error("database schema version " + std::to_string(version) +
                               " is newer than this foamd (" + std::to_string(kSchemaVersion) +
                               ")");
    for (; version < kSchemaVersion; ++version) {
      exec(wdb_, kMigrations[static_cast<std::size_t>(version)]);
      exec(wdb_, "PRAGMA user_version = " + std::to_string(version + 1));
      spdlog::info("store: migrated schema to version {}", version + 1);
    }
    exec(wdb_, "COMMIT");
  } catch (...) {
    exec(wdb_, "ROLLBACK");
    throw;
  }
}

int Store::schemaVersion() {
  std::lock_guard lock(rmu_);
  Stmt v(rdb_, "PRAGMA user_version");
  v.step();
  return static_cast<int>(v.i64(0));
}

void Store::setEventListener(std::function<void(const std::string&)> listener) {
  std::lock_guard lock(qmu_);
  listener_ = std::move(listener);
}

void Store::writerLoop() {
  for (;;) {
    std::deque<std::unique_ptr<Task>> batch;
    std::function<void(const std::string&)> listener;
    {
      std::unique_lock lock(qmu_);
      qcv_.wait(lock, [&] { return stop_ || !queue_.empty(); });
      if (queue_.empty()) return;  // stop_ and drained
      batch.swap(queue_);
      busy_ = true;
      listener = listener_;
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
    if (listener) {
      std::sort(tx.touched.begin(), tx.touched.end());
      tx.touched.erase(std::unique(tx.touched.begin(), tx.touched.end()), tx.touched.end());
      for (const std::string& id : tx.touched) listener(id);
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
        const std::string sid = q.text(0);
        Stmt js(tx.db, "SELECT id FROM jobs WHERE sweep_id = ? ORDER BY seqno");
        js.bind(1, sid);
        std::vector<std::string> ids;
        while (js.step()) ids.push_back(js.text(0));
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
      Stmt up(tx.db,
              "UPDATE jobs SET state = ?, attempts = attempts + 1, started_utc = ?, reason = '', "
              "executor_ref = '' WHERE id = ?");
      up.bind(1, static_cast<int>(v1::JOB_STATE_RUNNING)).bind(2, utcNowText()).bind(3, id);
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
  std::lock_guard lock(emu_);
  health_listener_ = std::move(listener);
}

void Store::notifyHealth(bool writable) {
  std::function<void(bool)> h;
  {
    std::lock_guard lock(emu_);
    h = health_listener_;
  }
  if (h) h(writable);
}

v1::Job Store::cancel(const std::string& id, const std::string& reason) {
  return write([&](Tx& tx) -> v1::Job {
    v1::Job j = requireJob(tx.db, id);
    if (j.state() == v1::JOB_STATE_QUEUED) {
      Stmt up(tx.db,
              "UPDATE jobs SET state = ?, reason = ?, failure_kind = 'cancelled', "
              "finished_utc = ? WHERE id = ?");
      up.bind(1, static_cast<int>(v1::JOB_STATE_CANCELLED))
          .bind(2, reason.empty() ? std::string("cancelled before it started") : reason)
          .bind(3, utcNowText())
          .bind(4, id);
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
                   std::int64_t steps, const std::string& outcome) {
  return write([&](Tx& tx) {
    // Only a running job ends, once: a cancel racing a task's final report (Slurm) must not
    // turn one outcome into another.
    Stmt up(tx.db,
            "UPDATE jobs SET state = ?, failure_kind = ?, reason = ?, finished_utc = ?, t_s = ?, "
            "steps = ?, progress = CASE WHEN ? THEN 1 ELSE progress END, outcome = ? WHERE id = ? "
            "AND state = ?");
    up.bind(1, static_cast<int>(state))
        .bind(2, failure_kind)
        .bind(3, reason)
        .bind(4, utcNowText())
        .bind(5, t_s)
        .bind(6, steps)
        .bind(7, state == v1::JOB_STATE_SUCCEEDED ? 1 : 0)
        .bind(8, outcome)
        .bind(9, id)
        .bind(10, static_cast<int>(v1::JOB_STATE_RUNNING));
    up.run();
    if (sqlite3_changes(tx.db) == 0) return false;
    Stmt del(tx.db, "DELETE FROM results WHERE job_id = ?");
    del.bind(1, id).run();
    for (const auto& [name, value] : results) {
      Stmt ins(tx.db, "INSERT OR REPLACE INTO results(job_id, name, value) VALUES (?,?,?)");
      ins.bind(1, id).bind(2, name).bind(3, value).run();
    }
    Stmt ck(tx.db, "DELETE FROM checkpoints WHERE job_id = ?");
    ck.bind(1, id).run();
    tx.stateEvent(id);
    return true;
  });
}

bool Store::requeue(const std::string& id, const std::string& reason) {
  return write([&](Tx& tx) {
    Stmt up(tx.db,
            "UPDATE jobs SET state = ?, reason = ?, executor_ref = '' WHERE id = ? AND state = ?");
    up.bind(1, static_cast<int>(v1::JOB_STATE_QUEUED))
        .bind(2, reason)
        .bind(3, id)
        .bind(4, static_cast<int>(v1::JOB_STATE_RUNNING));
    up.run();
    if (sqlite3_changes(tx.db) == 0) return false;
    tx.stateEvent(id);
    return true;
  });
}

int Store::requeueRunning(const std::string& reason) {
  return write([&](Tx& tx) {
    std::vector<std::string> ids;
    Stmt q(tx.db, "SELECT id FROM jobs WHERE state = ?");
    q.bind(1, static_cast<int>(v1::JOB_STATE_RUNNING));
    while (q.step()) ids.push_back(q.text(0));
    for (const std::string& id : ids) {
      Stmt up(tx.db, "UPDATE jobs SET state = ?, reason = ?, executor_ref = '' WHERE id = ?");
      up.bind(1, static_cast<int>(v1::JOB_STATE_QUEUED)).bind(2, reason).bind(3, id).run();
      tx.stateEvent(id);
    }
    return static_cast<int>(ids.size());
  });
}

void Store::resetOutputs(const std::string& id, std::optional<double> keep_until) {
  write([&](Tx& tx) {
    const double t = keep_until.value_or(-1e300);
    for (const char* table : {"samples", "snapshots"}) {
      Stmt del(tx.db, std::string("DELETE FROM ") + table + " WHERE job_id = ? AND t_s > ?");
      del.bind(1, id).bind(2, t).run();
    }
    Stmt r(tx.db, "DELETE FROM results WHERE job_id = ?");
    r.bind(1, id).run();
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

// ---- reads -----------------------------------------------------------------------------------

std::optional<v1::Job> Store::getJob(const std::string& id) {
  std::lock_guard lock(rmu_);
  return loadJob(rdb_, id);
}

std::vector<v1::Job> Store::runningJobs() {
  std::lock_guard lock(rmu_);
  Stmt s(rdb_, std::string("SELECT ") + kJobCols + " FROM jobs WHERE state = ? ORDER BY seqno");
  s.bind(1, static_cast<int>(v1::JOB_STATE_RUNNING));
  std::vector<v1::Job> out;
  while (s.step()) out.push_back(readJob(s));
  return out;
}

v1::ListJobsResponse Store::listJobs(const v1::ListJobsRequest& req) {
  Where w;
  if (req.states_size() > 0) {
    std::string in;
    for (int s : req.states()) {
      if (!v1::JobState_IsValid(s) || s == v1::JOB_STATE_UNSPECIFIED)
        throw StoreError(StoreError::Kind::InvalidArgument,
                         "states: " + std::to_string(s) +
                             " is not a job state (1..5: queued, running, succeeded, failed, "
                             "cancelled)");
      if (!in.empty()) in += ",";
      in += std::to_string(s);
    }
    w.sql += " AND state IN (" + in + ")";
  }
  if (!req.tag().empty()) w.add("tag = ?", req.tag());
  if (!req.sweep_id().empty()) w.add("sweep_id = ?", req.sweep_id());
  if (!req.scene().empty()) w.add("scene = ?", req.scene());
  addOutcomeFilter(w, req.outcome());
  addParamFilters(w, req.params());
  if (req.page_size() < 0)
    throw StoreError(StoreError::Kind::InvalidArgument, "page_size: must be in [0, 1000]");
  const int page = req.page_size() == 0 ? 50 : std::min(req.page_size(), 1000);

  std::lock_guard lock(rmu_);
  v1::ListJobsResponse out;
  {
    Stmt c(rdb_, "SELECT COUNT(*) FROM jobs" + w.sql);
    w.bindAll(c);
    c.step();
    out.set_total(c.i64(0));
  }
  Where wp = w;
  if (!req.page_token().empty()) {
    std::int64_t after = 0;
    try {
      std::size_t pos = 0;
      after = std::stoll(req.page_token(), &pos);
      if (pos != req.page_token().size() || after <= 0) throw std::invalid_argument("");
    } catch (const std::exception&) {
      throw StoreError(StoreError::Kind::InvalidArgument,
                       "page_token: not a token from ListJobsResponse.next_page_token");
    }
    wp.add("seqno < ?", after);
  }
  Stmt q(rdb_, std::string("SELECT ") + kJobCols + ", seqno FROM jobs" + wp.sql +
                   " ORDER BY seqno DESC LIMIT " + std::to_string(page + 1));
  wp.bindAll(q);
  std::int64_t last = 0;
  int n = 0;
  while (q.step()) {
    if (n == page) {
      out.set_next_page_token(std::to_string(last));
      break;
    }
    *out.add_jobs() = readJob(q);
    last = q.i64(21);  // seqno, after kJobCols
    ++n;
  }
  return out;
}

std::vector<v1::JobEvent> Store::events(const std::string& id, std::int64_t after, int limit) {
  std::lock_guard lock(rmu_);
  Stmt q(rdb_, "SELECT data FROM events WHERE job_id = ? AND seq > ? ORDER BY seq LIMIT ?");
  q.bind(1, id).bind(2, after).bind(3, limit);
  std::vector<v1::JobEvent> out;
  while (q.step()) {
    v1::JobEvent ev;
    ev.ParseFromString(q.text(0));
    out.push_back(std::move(ev));
  }
  return out;
}

v1::JobResults Store::results(const std::string& id, bool with_samples) {
  std::lock_guard lock(rmu_);
  v1::JobResults out;
  *out.mutable_job() = requireJob(rdb_, id);
  {
    Stmt q(rdb_, "SELECT name, value FROM results WHERE job_id = ? ORDER BY name");
    q.bind(1, id);
    while (q.step()) {
      auto* r = out.add_results();
      r->set_name(q.text(0));
      r->set_value(q.isNull(1) ? std::nan("") : q.dbl(1));
    }
  }
  {
    Stmt q(rdb_, "SELECT columns_json FROM jobs WHERE id = ?");
    q.bind(1, id);
    if (q.step())
      for (const auto& c : nlohmann::json::parse(q.text(0))) out.add_columns(c.get<std::string>());
  }
  if (with_samples) {
    Stmt q(rdb_, "SELECT t_s, vals FROM samples WHERE job_id = ? ORDER BY idx");
    q.bind(1, id);
    while (q.step()) {
      auto* s = out.add_samples();
      s->set_t_s(q.dbl(0));
      for (double v : unpackDoubles(q.text(1))) s->add_values(v);
    }
  }
  {
    Stmt q(rdb_,
           "SELECT idx, t_s, step, bytes, vertices, triangles FROM snapshots WHERE job_id = ? "
           "ORDER BY idx");
    q.bind(1, id);
    while (q.step()) {
      auto* s = out.add_snapshots();
      s->set_index(static_cast<int>(q.i64(0)));
      s->set_t_s(q.dbl(1));
      s->set_step(q.i64(2));
      s->set_bytes(q.i64(3));
      s->set_vertices(static_cast<int>(q.i64(4)));
      s->set_triangles(static_cast<int>(q.i64(5)));
    }
  }
  return out;
}

v1::QueryResultsResponse Store::queryResults(const v1::QueryResultsRequest& req) {
  Where w;
  w.add("state = ?", static_cast<std::int64_t>(v1::JOB_STATE_SUCCEEDED));
  if (!req.scene().empty()) w.add("scene = ?", req.scene());
  if (!req.tag().empty()) w.add("tag = ?", req.tag());
  if (!req.sweep_id().empty()) w.add("sweep_id = ?", req.sweep_id());
  addOutcomeFilter(w, req.outcome());
  addParamFilters(w, req.params());
  if (req.limit() < 0 || req.limit() > 100000)
    throw StoreError(StoreError::Kind::InvalidArgument,
                     "limit: " + std::to_string(req.limit()) +
                         " is outside [0, 100000] (0 = the default, 1000)");
  const int limit = req.limit() == 0 ? 1000 : req.limit();
  std::string cols = "id, outcome";
  for (const auto& [k, c] : paramColumns()) cols += ", " + c;
  std::lock_guard lock(rmu_);
  Stmt q(rdb_, "SELECT " + cols + " FROM jobs" + w.sql + " ORDER BY seqno LIMIT " +
                   std::to_string(limit));
  w.bindAll(q);
  v1::QueryResultsResponse out;
  if (!req.sweep_id().empty()) {
    Stmt k(rdb_, "SELECT keys_json FROM sweeps WHERE id = ?");
    k.bind(1, req.sweep_id());
    if (k.step())
      for (const auto& key : nlohmann::json::parse(k.text(0))) out.add_swept_keys(key);
  }
  while (q.step()) {
    auto* row = out.add_rows();
    row->set_job_id(q.text(0));
    row->set_outcome(q.text(1));
    int c = 2;
    for (const auto& [k, col] : paramColumns()) (*row->mutable_params())[k] = q.dbl(c++);
  }
  for (auto& row : *out.mutable_rows()) {
    Stmt r(rdb_, "SELECT name, value FROM results WHERE job_id = ? ORDER BY name");
    r.bind(1, row.job_id());
    while (r.step()) {
      const std::string name = r.text(0);
      if (req.names_size() > 0 &&
          std::find(req.names().begin(), req.names().end(), name) == req.names().end())
        continue;
      auto* res = row.add_results();
      res->set_name(name);
      res->set_value(r.isNull(1) ? std::nan("") : r.dbl(1));
    }
  }
  return out;
}

std::optional<std::tuple<v1::SnapshotInfo, std::string, std::string>> Store::snapshot(
    const std::string& id, int index) {
  std::lock_guard lock(rmu_);
  Stmt q(rdb_, index < 0 ? "SELECT idx, t_s, step, bytes, vertices, triangles, compression, data "
                           "FROM snapshots WHERE job_id = ? ORDER BY idx DESC LIMIT 1"
                         : "SELECT idx, t_s, step, bytes, vertices, triangles, compression, data "
                           "FROM snapshots WHERE job_id = ? AND idx = ?");
  q.bind(1, id);
  if (index >= 0) q.bind(2, index);
  if (!q.step()) return std::nullopt;
  v1::SnapshotInfo info;
  info.set_index(static_cast<int>(q.i64(0)));
  info.set_t_s(q.dbl(1));
  info.set_step(q.i64(2));
  info.set_bytes(q.i64(3));
  info.set_vertices(static_cast<int>(q.i64(4)));
  info.set_triangles(static_cast<int>(q.i64(5)));
  return std::make_tuple(info, q.text(6), q.text(7));
}

std::optional<std::pair<double, std::string>> Store::checkpoint(const std::string& id) {
  std::lock_guard lock(rmu_);
  Stmt q(rdb_, "SELECT t_s, data FROM checkpoints WHERE job_id = ?");
  q.bind(1, id);
  if (!q.step()) return std::nullopt;
  return std::make_pair(q.dbl(0), q.text(1));
}

std::map<v1::JobState, std::int64_t> Store::countByState() {
  std::lock_guard lock(rmu_);
  Stmt q(rdb_, "SELECT state, COUNT(*) FROM jobs GROUP BY state");
  std::map<v1::JobState, std::int64_t> out;
  while (q.step()) out[static_cast<v1::JobState>(q.i64(0))] = q.i64(1);
  return out;
}

std::int64_t Store::countRows(const std::string& table) {
  std::lock_guard lock(rmu_);
  Stmt q(rdb_, "SELECT COUNT(*) FROM " + table);
  q.step();
  return q.i64(0);
}

}  // namespace activefoam::server
