// The store's reads (see store.h): their own connection, committed data only.
#include <cmath>
#include <tuple>

#include <nlohmann/json.hpp>

#include "store.h"
#include "store_sql.h"

namespace activefoam::server {

using namespace sql;

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
  {
    Stmt q(rdb_, "SELECT name, x, y FROM curves WHERE job_id = ? ORDER BY name");
    q.bind(1, id);
    while (q.step()) {
      auto* c = out.add_curves();
      c->set_name(q.text(0));
      for (double v : unpackDoubles(q.text(1))) c->add_x(v);
      for (double v : unpackDoubles(q.text(2))) c->add_y(v);
    }
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
