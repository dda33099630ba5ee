// A sweep's or a tag's jobs and results (see table.h).
#include "table.h"

#include <algorithm>
#include <cmath>
#include <iostream>

namespace activefoam::client {

std::map<std::string, nlohmann::json> flatSpec(const std::string& spec_json) {
  std::map<std::string, nlohmann::json> out;
  const nlohmann::json spec = nlohmann::json::parse(spec_json, nullptr, false);
  if (!spec.is_object()) return out;
  const nlohmann::json flat = spec.flatten();  // kept: items() does not own what it walks
  for (const auto& [pointer, value] : flat.items()) {
    std::string key = pointer.substr(1);  // "/cells/gamma" → "cells.gamma"
    std::replace(key.begin(), key.end(), '/', '.');
    out[key] = value;
  }
  return out;
}

double quantile(const std::vector<double>& sorted, double q) {
  if (sorted.empty()) return std::nan("");
  const double pos = q * static_cast<double>(sorted.size() - 1);
  const auto lo = static_cast<std::size_t>(std::floor(pos));
  const std::size_t hi = std::min(lo + 1, sorted.size() - 1);
  return sorted[lo] + (pos - static_cast<double>(lo)) * (sorted[hi] - sorted[lo]);
}

std::map<std::vector<double>, Group> aggregateBy(const std::vector<v1::Job>& jobs,
                                                 const v1::QueryResultsResponse& rows,
                                                 const std::vector<std::string>& by,
                                                 std::string& err) {
  std::map<std::string, const v1::QueryResultsRow*> row_of;
  for (const auto& r : rows.rows()) row_of[r.job_id()] = &r;
  std::map<std::vector<double>, Group> groups;
  for (const v1::Job& j : jobs) {
    const std::map<std::string, nlohmann::json> spec = flatSpec(j.spec_json());
    std::vector<double> key;
    for (const std::string& k : by) {
      const auto it = spec.find(k);
      const nlohmann::json* v = it == spec.end() ? nullptr : &it->second;
      if (!v || !v->is_number()) {
        err = "'" + k + "' is not a numeric key of job " + j.id() +
              "'s spec (dotted, as foam-run --keys lists them, e.g. cells.alpha)";
        return {};
      }
      key.push_back(v->get<double>());
    }
    Group& g = groups[key];
    ++g.jobs;
    if (j.state() == v1::JOB_STATE_FAILED || j.state() == v1::JOB_STATE_CANCELLED) ++g.failed;
    if (j.state() != v1::JOB_STATE_SUCCEEDED) continue;
    ++g.succeeded;
    if (const auto it = row_of.find(j.id()); it != row_of.end())
      for (const auto& r : it->second->results())
        if (std::isfinite(r.value())) g.values[r.name()].push_back(r.value());
  }
  for (auto& [key, g] : groups)
    for (auto& [name, v] : g.values) std::sort(v.begin(), v.end());
  return groups;
}

int fetchTable(Conn& conn, const std::string& sweep, const std::string& tag,
               const std::string& outcome, const std::vector<std::string>& names,
               std::vector<v1::Job>& jobs, v1::QueryResultsResponse& resp) {
  v1::QueryResultsRequest req;
  req.set_sweep_id(sweep);
  req.set_tag(tag);
  req.set_outcome(outcome);
  for (const auto& m : names) req.add_names(m);
  req.set_limit(100000);
  auto ctx = conn.ctx();
  if (const grpc::Status st = conn.stub->QueryResults(ctx.get(), req, &resp); !st.ok())
    return rpcError(st, "results");
  v1::ListJobsRequest lr;
  lr.set_sweep_id(sweep);
  lr.set_tag(tag);
  lr.set_outcome(outcome);
  lr.set_page_size(1000);
  for (;;) {
    v1::ListJobsResponse page;
    auto lctx = conn.ctx();
    if (const grpc::Status ls = conn.stub->ListJobs(lctx.get(), lr, &page); !ls.ok())
      return rpcError(ls, "results");
    jobs.insert(jobs.end(), page.jobs().begin(), page.jobs().end());
    if (page.next_page_token().empty()) break;
    lr.set_page_token(page.next_page_token());
  }
  if (jobs.empty()) {
    std::cerr << "foam: no jobs" << (sweep.empty() ? "" : " in sweep " + sweep)
              << (tag.empty() ? "" : " with tag " + tag) << "\n";
    return kNotFound;
  }
  return 0;
}

}  // namespace activefoam::client
