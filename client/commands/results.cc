// foam results: one job's results (and samples, --csv/--json), or a table of a sweep's or a
// tag's jobs, over seeds with --by.
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <iostream>
#include <set>

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include "../commands.h"
#include "../table.h"

namespace activefoam::client {
namespace {

enum class TableFormat { Text, Csv, Json };

// The shortest decimal that reads back as the same double ("0.4", not "0.40000000000000002").
std::string shortestNumber(double v) {
  if (std::isnan(v)) return "nan";
  char b[32];
  for (int digits = 15; digits <= 17; ++digits) {
    std::snprintf(b, sizeof b, "%.*g", digits, v);
    if (std::strtod(b, nullptr) == v) break;
  }
  return b;
}

// A sweep's or tag's jobs as a table, one row per job in submission order: id, state, fusion
// outcome, seed, the swept keys (dotted; for a tag, the keys whose values differ between the
// jobs), and the results (QueryResults: succeeded jobs; nan / null elsewhere; their union).
void printResultsTable(const std::vector<v1::Job>& jobs, const v1::QueryResultsResponse& resp,
                       TableFormat format) {
  std::set<std::string> result_keys;
  std::map<std::string, std::map<std::string, double>> results;
  for (const auto& row : resp.rows())
    for (const auto& r : row.results()) {
      result_keys.insert(r.name());
      results[row.job_id()][r.name()] = r.value();
    }
  std::vector<std::map<std::string, nlohmann::json>> specs;
  for (auto it = jobs.rbegin(); it != jobs.rend(); ++it) specs.push_back(flatSpec(it->spec_json()));
  // The sweep's own keys (what its grid varies); for a tag, the keys whose values differ
  // between the jobs (derived ones included: they differ too).
  std::vector<std::string> swept(resp.swept_keys().begin(), resp.swept_keys().end());
  if (swept.empty()) {
    std::set<std::string> differ;
    for (const auto& spec : specs)
      for (const auto& [k, v] : spec)
        if (k != "seed" && !differ.count(k))
          for (const auto& other : specs)
            if (!other.count(k) || other.at(k) != v) {
              differ.insert(k);
              break;
            }
    swept.assign(differ.begin(), differ.end());
  }
  auto result = [&](const std::string& id, const std::string& k) {
    const auto it = results.find(id);
    if (it == results.end()) return std::nan("");
    const auto r = it->second.find(k);
    return r == it->second.end() ? std::nan("") : r->second;
  };
  auto number = shortestNumber;
  auto jsonNumber = [](double v) {
    return std::isnan(v) ? nlohmann::json(nullptr) : nlohmann::json(v);
  };
  auto text = [&](const std::map<std::string, nlohmann::json>& spec, const std::string& k) {
    const auto it = spec.find(k);
    if (it == spec.end() || it->second.is_null()) return std::string("nan");
    if (it->second.is_number()) return number(it->second.get<double>());
    if (it->second.is_string()) return it->second.get<std::string>();
    return it->second.dump();
  };
  std::size_t row = 0;
  if (format == TableFormat::Json) {
    nlohmann::json rows = nlohmann::json::array();
    for (auto it = jobs.rbegin(); it != jobs.rend(); ++it, ++row) {
      const v1::Job& job = *it;
      nlohmann::json j{{"job_id", job.id()},
                       {"state", stateName(job.state())},
                       {"outcome", job.outcome()},
                       {"seed", job.seed()}};
      j["params"] = nlohmann::json::object();
      for (const auto& k : swept)
        j["params"][k] = specs[row].count(k) ? specs[row].at(k) : nlohmann::json(nullptr);
      j["results"] = nlohmann::json::object();
      for (const auto& k : result_keys) j["results"][k] = jsonNumber(result(job.id(), k));
      rows.push_back(j);
    }
    std::cout << rows.dump(2) << "\n";
    return;
  }
  const char* sep = format == TableFormat::Csv ? "," : "  ";
  std::cout << "job_id" << sep << "state" << sep << "outcome" << sep << "seed";
  for (const auto& k : swept) std::cout << sep << k;
  for (const auto& k : result_keys) std::cout << sep << k;
  std::cout << "\n";
  for (auto it = jobs.rbegin(); it != jobs.rend(); ++it, ++row) {
    const v1::Job& job = *it;
    std::cout << job.id() << sep << stateName(job.state()) << sep
              << (job.outcome().empty() ? "-" : job.outcome()) << sep << job.seed();
    for (const auto& k : swept) std::cout << sep << text(specs[row], k);
    for (const auto& k : result_keys) std::cout << sep << number(result(job.id(), k));
    std::cout << "\n";
  }
  if (format == TableFormat::Text) std::cerr << "foam: " << jobs.size() << " jobs\n";
}

// ---- foam results --by: a sweep's results over seeds ----------------------------------------

void printAggregate(const std::map<std::vector<double>, Group>& groups,
                    const std::vector<std::string>& by, TableFormat format) {
  std::set<std::string> names;
  for (const auto& [key, g] : groups)
    for (const auto& [name, v] : g.values) names.insert(name);
  const std::vector<double> none;
  auto valuesOf = [&](const Group& g, const std::string& n) -> const std::vector<double>& {
    const auto it = g.values.find(n);
    return it == g.values.end() ? none : it->second;
  };
  auto num = shortestNumber;
  if (format == TableFormat::Json) {
    nlohmann::json out = nlohmann::json::array();
    for (const auto& [key, g] : groups) {
      nlohmann::json row;
      for (std::size_t k = 0; k < by.size(); ++k) row[by[k]] = key[k];
      row["jobs"] = g.jobs;
      row["succeeded"] = g.succeeded;
      row["failed"] = g.failed;
      for (const std::string& n : names) {
        const std::vector<double>& v = valuesOf(g, n);
        auto q = [&](double p) {
          return v.empty() ? nlohmann::json(nullptr) : nlohmann::json(quantile(v, p));
        };
        row[n] = {{"n", v.size()}, {"median", q(0.5)}, {"q25", q(0.25)}, {"q75", q(0.75)}};
      }
      out.push_back(row);
    }
    std::cout << out.dump(2) << "\n";
    return;
  }
  const char* sep = format == TableFormat::Csv ? "," : "  ";
  for (std::size_t k = 0; k < by.size(); ++k) std::cout << (k ? sep : "") << by[k];
  std::cout << sep << "jobs" << sep << "succeeded" << sep << "failed";
  for (const std::string& n : names)
    std::cout << sep << n << "_n" << sep << n << "_median" << sep << n << "_q25" << sep << n
              << "_q75";
  std::cout << "\n";
  for (const auto& [key, g] : groups) {
    for (std::size_t k = 0; k < key.size(); ++k) std::cout << (k ? sep : "") << num(key[k]);
    std::cout << sep << g.jobs << sep << g.succeeded << sep << g.failed;
    for (const std::string& n : names) {
      const std::vector<double>& v = valuesOf(g, n);
      std::cout << sep << v.size() << sep << num(quantile(v, 0.5)) << sep << num(quantile(v, 0.25))
                << sep << num(quantile(v, 0.75));
    }
    std::cout << "\n";
  }
}

int runTable(Conn& conn, const ResultsOptions& o) {
  if (o.sweep.empty() && o.tag.empty()) {
    std::cerr << "foam: results: give a job ID, or --sweep ID / --tag TAG for a table\n";
    return kUsage;
  }
  std::vector<v1::Job> jobs;
  v1::QueryResultsResponse resp;
  if (const int rc = fetchTable(conn, o.sweep, o.tag, o.outcome, o.metrics, jobs, resp)) return rc;
  const TableFormat format = o.json  ? TableFormat::Json
                             : o.csv ? TableFormat::Csv
                                     : TableFormat::Text;
  if (o.by.empty()) {
    printResultsTable(jobs, resp, format);
    return kOk;
  }
  std::string err;
  const auto groups = aggregateBy(jobs, resp, o.by, err);
  if (!err.empty()) {
    std::cerr << "foam: results --by: " << err << "\n";
    return kUsage;
  }
  printAggregate(groups, o.by, format);
  return kOk;
}

int runJob(Conn& conn, const ResultsOptions& o) {
  v1::GetResultsRequest req;
  req.set_job_id(o.id);
  req.set_with_samples(o.json || o.csv);
  v1::JobResults r;
  auto ctx = conn.ctx();
  const grpc::Status st = conn.stub->GetResults(ctx.get(), req, &r);
  if (!st.ok()) return rpcError(st, "results " + o.id);
  if (o.csv) {
    for (int i = 0; i < r.columns_size(); ++i) std::cout << (i ? "," : "") << r.columns(i);
    std::cout << "\n";
    for (const auto& s : r.samples()) {
      for (int i = 0; i < s.values_size(); ++i) {
        char b[32];
        std::snprintf(b, sizeof b, "%.17g", s.values(i));
        std::cout << (i ? "," : "") << b;
      }
      std::cout << "\n";
    }
    return kOk;
  }
  if (o.json) {
    nlohmann::json j;
    j["id"] = r.job().id();
    j["state"] = stateName(r.job().state());
    j["reason"] = r.job().reason();
    j["scene"] = r.job().scene();
    j["seed"] = r.job().seed();
    if (!r.job().outcome().empty()) j["outcome"] = r.job().outcome();
    j["spec"] = nlohmann::json::parse(r.job().spec_json());
    j["results"] = nlohmann::json::object();
    for (const auto& x : r.results()) j["results"][x.name()] = x.value();
    j["columns"] = r.columns();
    j["samples"] = nlohmann::json::array();
    for (const auto& s : r.samples()) j["samples"].push_back(s.values());
    j["snapshots"] = r.snapshots_size();
    std::cout << j.dump(2) << "\n";
    return kOk;
  }
  std::cout << "job " << r.job().id() << ": " << stateName(r.job().state())
            << (r.job().reason().empty() ? "" : " (" + r.job().reason() + ")") << "\n";
  if (!r.job().outcome().empty()) std::printf("  %-24s %s\n", "outcome", r.job().outcome().c_str());
  for (const auto& x : r.results()) std::printf("  %-24s %.6g\n", x.name().c_str(), x.value());
  return kOk;
}

}  // namespace

CLI::App* setupResults(CLI::App& app, ResultsOptions& o) {
  auto* results = app.add_subcommand(
      "results",
      "a job's results and samples; or, with --sweep/--tag, one row per succeeded job of a "
      "sweep or tag: its parameters and results (--csv/--json for scripts)");
  results->add_option("ID", o.id);
  results->add_option("--sweep", o.sweep, "the jobs of this sweep");
  results->add_option("--tag", o.tag, "the jobs with this tag");
  results->add_option("--outcome", o.outcome, kOutcomeHelp);
  results->add_option("--metrics", o.metrics, "only these results (comma-separated)")
      ->delimiter(',');
  results
      ->add_option("--by", o.by,
                   "with --sweep/--tag: one row per value of these spec keys (e.g. cells.alpha), "
                   "over seeds: jobs, succeeded, failed, and per result n, median, q25, q75")
      ->delimiter(',');
  results->add_flag("--json", o.json, "JSON for scripts");
  results->add_flag("--csv", o.csv,
                    "samples as CSV (with ID); the table as CSV (with --sweep/--tag)");
  return results;
}

int runResults(Conn& conn, const ResultsOptions& o) {
  return o.id.empty() ? runTable(conn, o) : runJob(conn, o);
}

}  // namespace activefoam::client
