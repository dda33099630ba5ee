// The store's SQL (see store_sql.h).
#include "store_sql.h"

#include <cmath>
#include <cstring>
#include <set>
#include <tuple>

#include <spdlog/spdlog.h>

#include "store.h"

namespace activefoam::server::sql {

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
    // 4 → 5: curves a run ends with (fusion: the MSRD against the lag), packed doubles.
    R"sql(
CREATE TABLE curves(job_id TEXT NOT NULL, name TEXT NOT NULL, x BLOB NOT NULL, y BLOB NOT NULL,
  PRIMARY KEY(job_id, name));
)sql",
};

void migrateSchema(sqlite3* db) {
  exec(db, "BEGIN IMMEDIATE");
  try {
    Stmt v(db, "PRAGMA user_version");
    v.step();
    int version = static_cast<int>(v.i64(0));
    if (version > kSchemaVersion)
      throw std::runtime_error("database schema version " + std::to_string(version) +
                               " is newer than this foamd (" + std::to_string(kSchemaVersion) +
                               ")");
    for (; version < kSchemaVersion; ++version) {
      exec(db, kMigrations[static_cast<std::size_t>(version)]);
      exec(db, "PRAGMA user_version = " + std::to_string(version + 1));
      spdlog::info("store: migrated schema to version {}", version + 1);
    }
    exec(db, "COMMIT");
  } catch (...) {
    exec(db, "ROLLBACK");
    throw;
  }
}

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
  j.set_terminal(isTerminal(j.state()));
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

}  // namespace activefoam::server::sql
