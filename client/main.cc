// foam: the activefoam command-line client (DESIGN.md §8). Specs go to the server as text
// (TOML/JSON) plus key=value settings, and the server validates them; of the engine only the VTK
// writer is used (foam export).
//
//   foam [--server HOST:PORT] [--token-file F] [--tls-ca F] COMMAND ...
//        (also FOAM_SERVER, FOAM_TOKEN, FOAM_TLS_CA)
//
// Exit codes: 0 success (with --wait / watch: the job succeeded); 1 the job failed or was
// cancelled; 2 usage error or invalid spec (INVALID_ARGUMENT); 3 server unreachable or another
// RPC error; 4 authentication failed (UNAUTHENTICATED); 5 not found.
#include <grpcpp/grpcpp.h>

#include <sys/wait.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iostream>
#include <map>
#include <memory>
#include <set>
#include <sstream>
#include <thread>

#include <google/protobuf/util/json_util.h>
#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include "activefoam/snapshot_vtk.h"
#include "activefoam/token_file.h"
#include "activefoam/utf8.h"
#include "activefoam/v1/service.grpc.pb.h"
#include "activefoam/vtk.h"
#include "report.h"

namespace v1 = activefoam::v1;

namespace {

namespace fs = std::filesystem;

constexpr int kOk = 0, kJobNotOk = 1, kUsage = 2, kRpc = 3, kAuth = 4, kNotFound = 5;

struct Conn {
  std::string server = "127.0.0.1:50051";
  std::string token;
  std::string tls_ca;  // PEM roots; non-empty: connect with TLS
  std::unique_ptr<v1::Foam::Stub> stub;

  bool loopback() const {
    const std::string host = server.substr(0, server.rfind(':'));
    return host == "localhost" || host == "[::1]" || host.rfind("127.", 0) == 0;
  }
  void connect() {
    // With a token and no TLS the server wants local credentials (loopback): see foamd
    // --token-file.
    std::shared_ptr<grpc::ChannelCredentials> creds;
    if (!tls_ca.empty()) {
      grpc::SslCredentialsOptions o;
      o.pem_root_certs = tls_ca;
      creds = grpc::SslCredentials(o);
    } else if (!token.empty() && loopback()) {
      creds = grpc::experimental::LocalCredentials(LOCAL_TCP);
    } else {
      creds = grpc::InsecureChannelCredentials();
    }
    stub = v1::Foam::NewStub(grpc::CreateChannel(server, creds));
  }
  std::unique_ptr<grpc::ClientContext> ctx(double deadline_s = 30) const {
    auto c = std::make_unique<grpc::ClientContext>();
    if (!token.empty()) c->AddMetadata("authorization", "Bearer " + token);
    if (deadline_s > 0)
      c->set_deadline(std::chrono::system_clock::now() +
                      std::chrono::milliseconds(static_cast<long>(deadline_s * 1000)));
    return c;
  }
};

int rpcError(const grpc::Status& s, const std::string& what) {
  std::cerr << "foam: " << what << ": " << s.error_message() << " (" << s.error_code() << ")\n";
  switch (s.error_code()) {
    case grpc::StatusCode::INVALID_ARGUMENT:
    case grpc::StatusCode::FAILED_PRECONDITION:
    case grpc::StatusCode::RESOURCE_EXHAUSTED:  // a request beyond the server's size limit
      return kUsage;
    case grpc::StatusCode::UNAUTHENTICATED:
      return kAuth;
    case grpc::StatusCode::NOT_FOUND:
      return kNotFound;
    default:
      return kRpc;
  }
}

// "preset draft (Δt 0.5 s, 320 triangles, ε_CG 0.001), chosen for the accuracy target contact
// angle ≤ 2°" from a job's resolved spec.
std::string fidelityText(const std::string& spec_json) {
  try {
    const nlohmann::json spec = nlohmann::json::parse(spec_json);
    const nlohmann::json& n = spec.at("numerics");
    std::ostringstream os;
    os << "preset " << n.value("preset", std::string("?")) << " (" << n.value("integrator", "")
       << ", Δt " << n.value("dt_s", 0.0) << " s, " << n.value("triangles_per_cell", 0)
       << " triangles, ε_CG " << n.value("cg_tol", 0.0) << ")";
    // Unset targets are null in a resolved spec.
    const nlohmann::json a = spec.value("accuracy", nlohmann::json::object());
    const bool angle = a.contains("contact_angle_deg") && a["contact_angle_deg"].is_number();
    const bool path = a.contains("trajectory_deg") && a["trajectory_deg"].is_number();
    if (angle || path) os << ", chosen for the accuracy target";
    if (angle) os << " contact angle ≤ " << a["contact_angle_deg"].get<double>() << "°";
    if (path) os << " θ(t) RMS ≤ " << a["trajectory_deg"].get<double>() << "°";
    return os.str();
  } catch (const std::exception&) {
    return "?";
  }
}

std::string stateName(v1::JobState s) {
  std::string n = v1::JobState_Name(s);
  n = n.substr(std::string("JOB_STATE_").size());
  for (char& c : n) c = static_cast<char>(std::tolower(c));
  return n;
}

// A spec beyond this is a mistake (a data file given as the spec), refused before it is sent.
constexpr std::uintmax_t kMaxSpecBytes = 1 << 20;

std::string readFile(const std::string& path) {
  std::error_code ec;
  if (std::filesystem::is_directory(path, ec))
    throw std::runtime_error("'" + path + "' is a directory, not a file");
  if (const auto size = std::filesystem::file_size(path, ec); !ec && size > kMaxSpecBytes)
    throw std::runtime_error("'" + path + "' has " + std::to_string(size) +
                             " bytes; a spec or certificate file has at most 1 MiB");
  std::ifstream in(path, std::ios::binary);
  if (!in) throw std::runtime_error("cannot read '" + path + "'");
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

std::string fmtDuration(double s) {
  char b[64];
  if (s < 0)
    return "?";
  else if (s < 60)
    std::snprintf(b, sizeof b, "%.1fs", s);
  else if (s < 3600)
    std::snprintf(b, sizeof b, "%dm%02ds", static_cast<int>(s / 60), static_cast<int>(s) % 60);
  else
    std::snprintf(b, sizeof b, "%dh%02dm", static_cast<int>(s / 3600),
                  static_cast<int>(s / 60) % 60);
  return b;
}

std::string toJsonText(const google::protobuf::Message& m) {
  std::string s;
  google::protobuf::util::JsonPrintOptions o;
  o.preserve_proto_field_names = true;
  (void)google::protobuf::util::MessageToJsonString(m, &s, o);
  return s;
}

// Follows a job's events to its end, reconnecting (from the last sequence number seen) when the
// stream breaks. Progress on stderr. Returns the final job, or nullopt on a non-retryable error.
std::optional<v1::Job> watch(Conn& conn, const std::string& id, bool quiet, int& rc) {
  std::int64_t last = 0;
  std::vector<std::string> columns;
  std::string latest;                    // latest observable, "name = value"
  std::int64_t rejected_in_samples = 0;  // Σ of the samples' steps_rejected (Slurm tasks' too)
  std::optional<v1::Job> final;
  int failures = 0;
  const bool tty = isatty(2);
  for (;;) {
    v1::WatchJobRequest req;
    req.set_job_id(id);
    req.set_from_seq(last);
    req.set_follow(true);
    auto ctx = conn.ctx(0);
    auto reader = conn.stub->WatchJob(ctx.get(), req);
    v1::JobEvent ev;
    while (reader->Read(&ev)) {
      failures = 0;
      last = ev.seq();
      if (ev.has_state()) {
        if (!quiet)
          std::cerr << (tty ? "\r\033[K" : "") << "foam: " << id << " "
                    << stateName(ev.state().state())
                    << (ev.state().reason().empty() ? "" : ": " + ev.state().reason()) << "\n";
        if (activefoam::v1::JobState s = ev.state().state(); s == v1::JOB_STATE_SUCCEEDED ||
                                                             s == v1::JOB_STATE_FAILED ||
                                                             s == v1::JOB_STATE_CANCELLED)
          final = ev.state();
      } else if (ev.has_sample()) {
        if (ev.columns_size() > 0) columns.assign(ev.columns().begin(), ev.columns().end());
        const auto& v = ev.sample().values();
        // The scene's first observable follows the columns every scene has (run.h).
        constexpr int kCommonColumns = 7;
        if (v.size() > kCommonColumns && static_cast<int>(columns.size()) > kCommonColumns) {
          char b[128];
          std::snprintf(b, sizeof b, "%s = %.4g", columns[kCommonColumns].c_str(),
                        v[kCommonColumns]);
          latest = b;
        }
        for (int k = 0; k < v.size() && k < static_cast<int>(columns.size()); ++k)
          if (columns[static_cast<std::size_t>(k)] == "steps_rejected" && std::isfinite(v[k]))
            rejected_in_samples += static_cast<std::int64_t>(v[k]);
      } else if (ev.has_progress() && !quiet) {
        const auto& p = ev.progress();
        const int width = 30;
        const int filled = static_cast<int>(std::lround(p.fraction() * width));
        std::string bar(static_cast<std::size_t>(filled), '#');
        bar.resize(width, '.');
        char b[256];
        const std::int64_t rejected = std::max(p.steps_rejected(), rejected_in_samples);
        char rej[48] = "";
        if (rejected > 0)
          std::snprintf(rej, sizeof rej, "  rejected %lld", static_cast<long long>(rejected));
        std::snprintf(b, sizeof b, "[%s] %5.1f%%  t = %.4g s  ETA %s%s  %s", bar.c_str(),
                      100 * p.fraction(), p.t_s(), fmtDuration(p.eta_s()).c_str(), rej,
                      latest.c_str());
        std::cerr << (tty ? "\r\033[K" : "") << b << (tty ? "" : "\n") << std::flush;
      }
    }
    const grpc::Status st = reader->Finish();
    if (final) return final;
    if (st.ok()) {  // stream ended without a terminal state (server going down): follow again
    } else if (st.error_code() != grpc::StatusCode::UNAVAILABLE &&
               st.error_code() != grpc::StatusCode::CANCELLED) {
      rc = rpcError(st, "watch " + id);
      return std::nullopt;
    }
    if (++failures > 600) {
      rc = rpcError(st, "watch " + id + " (gave up reconnecting)");
      return std::nullopt;
    }
    if (!quiet && failures == 1)
      std::cerr << "\nfoam: connection lost; reconnecting and resuming after event " << last
                << "\n";
    std::this_thread::sleep_for(std::chrono::milliseconds(500));
  }
}

int jobExit(const v1::Job& j) {
  return j.state() == v1::JOB_STATE_SUCCEEDED ? kOk : kJobNotOk;
}

// Every recorded snapshot of a job as VTK PolyData (DIR/snap_NNNNNN.vtp) and a ParaView time
// series (DIR/series.pvd). Returns an error text, empty on success.
std::string exportSnapshots(v1::Foam::Stub& stub,
                            const std::function<std::unique_ptr<grpc::ClientContext>()>& newCtx,
                            const v1::JobResults& r, const fs::path& dir) {
  if (r.snapshots_size() == 0)
    return "the job has no snapshots (snapshot_every_s = 0, or none recorded yet)";
  std::error_code ec;
  fs::create_directories(dir, ec);
  if (ec) return "cannot create " + dir.string() + ": " + ec.message();
  std::vector<std::pair<double, std::string>> series;
  for (const v1::SnapshotInfo& info : r.snapshots()) {
    v1::GetSnapshotRequest req;
    req.set_job_id(r.job().id());
    req.set_index(info.index());
    auto ctx = newCtx();
    auto reader = stub.GetSnapshot(ctx.get(), req);
    v1::SnapshotChunk chunk;
    std::string data, compression;
    bool first = true;
    while (reader->Read(&chunk)) {
      if (first) compression = chunk.compression();
      first = false;
      data += chunk.data();
    }
    if (const grpc::Status st = reader->Finish(); !st.ok())
      return "snapshot " + std::to_string(info.index()) + ": " + st.error_message();
    activefoam::VtkMesh snap;
    if (std::string err = activefoam::decodeSnapshot(info, compression, std::move(data), snap);
        !err.empty())
      return err;
    char name[32];
    std::snprintf(name, sizeof name, "snap_%06d.vtp", info.index());
    std::ofstream out(dir / name);
    try {
      activefoam::writeVtp(out, snap);
    } catch (const std::exception& e) {
      return std::string(name) + ": " + e.what();
    }
    if (!out) return "cannot write " + (dir / name).string();
    series.emplace_back(snap.t_s, name);
  }
  std::ofstream pvd(dir / "series.pvd");
  activefoam::writePvd(pvd, series);
  if (!pvd) return "cannot write " + (dir / "series.pvd").string();
  return "";
}

// Runs a gnuplot script; an error text, empty on success.
std::string runGnuplot(const std::string& script) {
  FILE* g = popen("gnuplot 2>&1", "w");
  if (!g) return "cannot start gnuplot";
  std::fwrite(script.data(), 1, script.size(), g);
  const int rc = pclose(g);
  if (rc != 0)
    return "gnuplot failed (exit " + std::to_string(WEXITSTATUS(rc)) +
           "; is it installed? apt-get install gnuplot-nox)";
  return "";
}

// A PNG of one sample column against time with gnuplot; for θ(t) of a fusion job also the fitted
// Eq. 1 and Eq. 2 curves from the job's results. Returns an error text, empty on success.
std::string plotSamples(const v1::JobResults& r, const std::string& column,
                        const std::string& out) {
  int col = -1, tcol = -1;
  for (int i = 0; i < r.columns_size(); ++i) {
    if (r.columns(i) == column) col = i;
    if (r.columns(i) == "t_s") tcol = i;
  }
  if (col < 0 || tcol < 0) {
    std::string cols;
    for (const auto& c : r.columns()) cols += (cols.empty() ? "" : ", ") + c;
    return "no sample column '" + column + "' (columns: " + cols + ")";
  }
  if (r.samples_size() == 0) return "the job has no samples yet";
  std::map<std::string, double> res;
  for (const auto& x : r.results()) res[x.name()] = x.value();
  auto has = [&](std::initializer_list<const char*> names) {
    for (const char* n : names)
      if (!res.count(n) || !std::isfinite(res[n])) return false;
    return true;
  };
  std::ostringstream gp;
  gp.precision(10);
  gp << "set terminal pngcairo size 900,600 enhanced font 'DejaVu Sans,11'\n"
     << "set output '" << out << "'\n"
     << "set title 'job " << r.job().id() << " (" << r.job().scene() << ", seed " << r.job().seed()
     << ")' noenhanced\n"
     << "set xlabel 't (min)'\nset ylabel '" << column << "' noenhanced\nset grid\n"
     << "set key bottom right\n$data << EOD\n";
  for (const auto& smp : r.samples())
    if (std::isfinite(smp.values(col)))
      gp << smp.values(tcol) / 60 << " " << smp.values(col) << "\n";
  gp << "EOD\nplot [0:] $data using 1:2 with points pt 7 ps 0.8 lc rgb '#1f77b4' title '" << column
     << "' noenhanced";
  if (column == "theta_deg" && res["eq1_ok"] == 1 &&
      has({"theta_eq_deg", "theta0_deg", "tau_f_s"})) {
    const double te = res["theta_eq_deg"], t0 = res["theta0_deg"], tf = res["tau_f_s"];
    gp << ", \\\n  " << te << " + (" << t0 << " - " << te << ") * exp(-x * 60 / " << tf
       << ") lw 2 lc rgb '#d62728' title sprintf('Eq. 1: θ_{eq} = %.1f°, τ_f = %.0f s', " << te
       << ", " << tf << ")";
  }
  if (column == "theta_deg" && res["eq2_ok"] == 1 &&
      has({"tau_gamma_s", "tau_eps_s", "eq2_theta0_deg"})) {
    // Closed form of Eq. 2 in u = cos θ (DESIGN.md §7).
    const double tg = res["tau_gamma_s"], tpe = res["tau_eps_s"];
    const double k = tpe / tg, root = std::sqrt(k * k + 4);
    const double up = (root - k) / 2, um = (-root - k) / 2, lam = root / (2 * tpe);
    const double u0 = std::cos(res["eq2_theta0_deg"] * M_PI / 180), c = (u0 - up) / (u0 - um);
    gp << ", \\\n  acos((" << up << " - (" << um << ") * " << c << " * exp(-" << lam
       << " * x * 60)) / (1 - " << c << " * exp(-" << lam
       << " * x * 60))) * 180 / pi lw 2 dt 2 lc rgb '#2ca02c' title sprintf('Eq. 2: τ_Γ = %.0f "
          "s, τ_ε = %.0f s', "
       << tg << ", " << tpe << ")";
  }
  gp << "\n";
  return runGnuplot(gp.str());
}

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

// QueryResults as a table: one row per job, its parameters then its results (columns: the
// union over rows, sorted; a job without a value shows nan / null).
// Each job's resolved spec as dotted key → value (scalars only).
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

// Quantile q of sorted values, linear between order statistics (numpy's and R's default).
double quantile(const std::vector<double>& sorted, double q) {
  if (sorted.empty()) return std::nan("");
  const double pos = q * static_cast<double>(sorted.size() - 1);
  const auto lo = static_cast<std::size_t>(std::floor(pos));
  const std::size_t hi = std::min(lo + 1, sorted.size() - 1);
  return sorted[lo] + (pos - static_cast<double>(lo)) * (sorted[hi] - sorted[lo]);
}

struct Group {
  int jobs = 0, succeeded = 0, failed = 0;            // failed: failed or cancelled
  std::map<std::string, std::vector<double>> values;  // finite values of each result, sorted
};

// Groups the jobs by the values of the spec keys in `by` (dotted, read from each job's resolved
// spec); `rows` (QueryResults) gives the succeeded jobs' results. Sets `err` for a key that a
// job's spec does not have as a number.
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

// Every job of a sweep or tag (ListJobs, by pages) and the results of its succeeded jobs
// (QueryResults, only `names` when given). Returns 0, or the exit status of a failed call.
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

// gnuplot's enhanced text reads '_' as a subscript: a spec key or result name keeps its '_'.
std::string escapeEnhanced(const std::string& key) {
  std::string out;
  for (char c : key) out += c == '_' ? std::string("\\_") : std::string(1, c);
  return out;
}

// Axis labels with units; the reduced names (DESIGN.md §3) where the key is one.
std::string axisLabel(const std::string& key) {
  static const std::map<std::string, std::string> labels = {
      {"cells.alpha", "α (relative cell–cell tension)"},
      {"cells.gamma", "γ (nN/µm)"},
      {"cells.p_a", "p_a (kPa)"},
      {"cells.pa_reduced", "p_a r/2γ"},
      {"cells.tau_p_s", "τ_p (s)"},
      {"cells.xi", "ξ (kPa·s/µm)"},
      {"cells.eta", "η (nN·s/µm)"},
      {"cells.radius_mean_um", "r (µm)"},
      {"scene.n_cells", "N (cells per spheroid)"},
      {"numerics.dt_s", "Δt (s)"},
      {"theta_eq_deg", "θ_{eq} (°, Eq. 1)"},
      {"tau_f_s", "τ_f (s, Eq. 1)"},
      {"theta_deg", "θ at the end (°)"},
      {"mixing_time_s", "mixing time (s)"},
      {"shape_index_mean", "shape index"},
      {"unique_contacts_norm", "normalised unique contacts"},
      {"contact_angle_deg", "θ_c (°)"},
      {"gsi", "GSI"},
      {"wall_s", "wall time (s)"}};
  const std::string raw = escapeEnhanced(key);
  const auto it = labels.find(key);
  return it == labels.end() ? raw : it->second + "  [" + raw + "]";
}

// The result must exist on some succeeded job; else an error naming it and the known ones.
std::string checkResult(const std::map<std::vector<double>, Group>& groups, const std::string& y) {
  std::set<std::string> known;
  for (const auto& [key, g] : groups)
    for (const auto& [name, v] : g.values) known.insert(name);
  if (known.count(y)) return "";
  std::string list;
  for (const auto& k : known) list += (list.empty() ? "" : ", ") + k;
  return "--y: '" + y + "' is not a result of this sweep's succeeded jobs" +
         (list.empty() ? std::string(" (none has results)") : " (known: " + list + ")");
}

// --y against --x: median line and IQR band over seeds, one per value of --by.
std::string plotSweep(const std::vector<v1::Job>& jobs, const v1::QueryResultsResponse& resp,
                      const std::string& x, const std::string& by, const std::string& y,
                      const std::string& out) {
  if (x.empty() || y.empty()) return "--sweep needs --x KEY and --y RESULT (or --heatmap)";
  std::vector<std::string> keys{x};
  if (!by.empty()) keys.push_back(by);
  std::string err;
  const auto groups = aggregateBy(jobs, resp, keys, err);
  if (!err.empty()) return err;
  if (err = checkResult(groups, y); !err.empty()) return err;
  // One gnuplot data block per --by value: x median q25 q75.
  std::map<double, std::ostringstream> series;
  for (const auto& [key, g] : groups) {
    const auto it = g.values.find(y);
    if (it == g.values.end() || it->second.empty()) continue;
    series[by.empty() ? 0.0 : key[1]] << key[0] << ' ' << quantile(it->second, 0.5) << ' '
                                      << quantile(it->second, 0.25) << ' '
                                      << quantile(it->second, 0.75) << '\n';
  }
  std::ostringstream gp;
  gp << "set terminal pngcairo size 900,600 enhanced font 'DejaVu Sans,11'\n"
     << "set output '" << out << "'\nset grid\nset key outside right\n"
     << "set xlabel '" << axisLabel(x) << "'\nset ylabel '" << axisLabel(y) << "'\n"
     << "set title 'median and interquartile range over seeds'\n";
  int k = 0;
  for (const auto& [v, data] : series) gp << "$d" << k++ << " << EOD\n" << data.str() << "EOD\n";
  gp << "plot ";
  k = 0;
  for (const auto& [v, data] : series) {
    const std::string name = by.empty() ? std::string("median") : escapeEnhanced(by) + " = " + [&] {
      std::ostringstream s;
      s << v;
      return s.str();
    }();
    gp << (k ? ", " : "") << "$d" << k << " u 1:3:4 w filledcurves fs transparent solid 0.25 lc "
       << k + 1 << " notitle, $d" << k << " u 1:2 w lp pt 7 lw 2 lc " << k + 1 << " title '" << name
       << "'";
    ++k;
  }
  gp << "\n";
  return runGnuplot(gp.str());
}

// The mean of --y per (KEY1, KEY2) cell of the grid, as coloured squares (Fig. 15).
std::string plotHeatmap(const std::vector<v1::Job>& jobs, const v1::QueryResultsResponse& resp,
                        const std::vector<std::string>& keys, const std::string& y,
                        const std::string& out) {
  if (keys.size() != 2) return "--heatmap wants two keys: KEY1,KEY2";
  if (y.empty()) return "--heatmap needs --y RESULT";
  std::string err;
  const auto groups = aggregateBy(jobs, resp, keys, err);
  if (!err.empty()) return err;
  if (err = checkResult(groups, y); !err.empty()) return err;
  std::ostringstream data;
  for (const auto& [key, g] : groups) {
    const auto it = g.values.find(y);
    if (it == g.values.end() || it->second.empty()) continue;
    double mean = 0;
    for (double v : it->second) mean += v / static_cast<double>(it->second.size());
    data << key[0] << ' ' << key[1] << ' ' << mean << '\n';
  }
  std::ostringstream gp;
  gp << "set terminal pngcairo size 900,700 enhanced font 'DejaVu Sans,11'\n"
     << "set output '" << out << "'\nset view map\nset grid front\nunset key\n"
     << "set xlabel '" << axisLabel(keys[0]) << "'\nset ylabel '" << axisLabel(keys[1])
     << "'\nset cblabel '" << axisLabel(y)
     << " (mean over seeds)'\nset offsets graph 0.08, graph 0.08, graph 0.08, graph 0.08\n"
     << "set palette rgb 33,13,10\n$d << EOD\n"
     << data.str() << "EOD\n"
     << "plot $d u 1:2:3 w points pt 5 ps 7 palette, $d u 1:2:(sprintf('%.3g', $3)) w labels\n";
  return runGnuplot(gp.str());
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"foam: activefoam client (submit, watch, list, show, cancel, results, plot, sweep)"};
  app.footer(
      "exit status: 0 ok (job succeeded for --wait/watch), 1 job failed or cancelled, 2 usage or "
      "invalid spec, 3 server unreachable / RPC error, 4 unauthenticated, 5 not found");
  app.require_subcommand(1);
  Conn conn;
  if (const char* s = std::getenv("FOAM_SERVER"); s && *s) conn.server = s;
  if (const char* t = std::getenv("FOAM_TOKEN"); t && *t) conn.token = t;
  std::string token_file, tls_ca_file;
  if (const char* c = std::getenv("FOAM_TLS_CA"); c && *c) tls_ca_file = c;
  app.add_option("--server", conn.server, "server HOST:PORT (env FOAM_SERVER)");
  app.add_option("--token-file", token_file, "file holding the bearer token (env FOAM_TOKEN)");
  app.add_option("--tls-ca", tls_ca_file,
                 "connect with TLS, trusting the certificate(s) in this PEM file (env "
                 "FOAM_TLS_CA; for foamd --tls-cert, its certificate or its CA)");
  app.set_config("--config", "", "TOML config file (server = ..., token-file = ..., tls-ca = ...)");

  // submit
  auto* submit = app.add_subcommand("submit", "submit a job; prints its id on the first line");
  std::string spec_file, scene, tag, idem;
  std::vector<std::string> settings;
  int priority = 0;
  bool wait = false, quiet = false;
  submit->add_option("SPEC", spec_file, "spec file (TOML or JSON, DESIGN.md §10; - = stdin)");
  submit->add_option("--scene", scene, "scene (cell|doublet|spheroid|fusion) instead of a file");
  submit->add_option("--set", settings, "override a key: --set cells.alpha=0.5 (repeatable)");
  std::string preset;
  std::vector<std::string> accuracy;
  const char* kPresetHelp =
      "fidelity preset: draft | standard (the default) | reference (docs/study/presets.md); "
      "--set numerics.* keys win over it";
  const char* kAccuracyHelp =
      "accuracy target instead of numerics, e.g. --accuracy contact_angle_deg=2 or "
      "trajectory_deg=5: foamd runs the cheapest preset that promises it (repeatable)";
  submit->add_option("--preset", preset, kPresetHelp);
  submit->add_option("--accuracy", accuracy, kAccuracyHelp);
  submit->add_option("--priority", priority, "higher runs first");
  submit->add_option("--tag", tag, "free text to filter on");
  submit->add_option("--idempotency-key", idem,
                     "resubmitting with the same key returns the same job");
  submit->add_flag("--wait", wait, "follow the job; exit 0 only if it succeeded");
  submit->add_flag("--quiet,-q", quiet, "no progress on stderr");

  auto* watchc = app.add_subcommand("watch", "follow a job: progress, ETA, latest observable");
  std::string id;
  watchc->add_option("ID", id)->required();
  watchc->add_flag("--quiet,-q", quiet);

  auto* list = app.add_subcommand("list", "list jobs, newest first");
  std::vector<std::string> states;
  std::string sweep_filter;
  int limit = 50;
  bool json = false, csv = false;
  list->add_option("--state", states, "queued|running|succeeded|failed|cancelled");
  list->add_option("--tag", tag);
  list->add_option("--sweep", sweep_filter);
  std::string outcome;
  const char* kOutcomeHelp = "fusion outcome: fused|arrested|separated|no-contact";
  list->add_option("--outcome", outcome, kOutcomeHelp);
  list->add_option("--limit", limit, "page size")->check(CLI::Range(1, 1000));
  list->add_flag("--json", json);

  auto* show = app.add_subcommand("show", "print a job's state (first line), then its details");
  show->add_option("ID", id)->required();
  show->add_flag("--json", json);

  auto* cancel = app.add_subcommand("cancel", "cancel a queued or running job");
  cancel->add_option("ID", id)->required();

  auto* results = app.add_subcommand(
      "results",
      "a job's results and samples; or, with --sweep/--tag, one row per succeeded job of a "
      "sweep or tag: its parameters and results (--csv/--json for scripts)");
  std::vector<std::string> metrics;
  results->add_option("ID", id);
  results->add_option("--sweep", sweep_filter, "the jobs of this sweep");
  results->add_option("--tag", tag, "the jobs with this tag");
  results->add_option("--outcome", outcome, kOutcomeHelp);
  results->add_option("--metrics", metrics, "only these results (comma-separated)")->delimiter(',');
  std::vector<std::string> by;
  results
      ->add_option("--by", by,
                   "with --sweep/--tag: one row per value of these spec keys (e.g. cells.alpha), "
                   "over seeds: jobs, succeeded, failed, and per result n, median, q25, q75")
      ->delimiter(',');
  results->add_flag("--json", json, "JSON for scripts");
  results->add_flag("--csv", csv,
                    "samples as CSV (with ID); the table as CSV (with --sweep/--tag)");

  auto* plot = app.add_subcommand("plot",
                                  "PNG chart of a sample column over time (gnuplot); "
                                  "θ(t) of a fusion job with its Eq. 1 / Eq. 2 fits");
  std::string plot_out, plot_column = "theta_deg";
  plot->add_option("ID", id);
  plot->add_option("--out,-o", plot_out, "PNG file (default: job-ID-COLUMN.png)");
  plot->add_option("--column", plot_column, "sample column")->capture_default_str();
  std::string plot_x, plot_y, plot_by;
  std::vector<std::string> heatmap;
  plot->add_option("--sweep", sweep_filter,
                   "a sweep's chart instead of a job's: --y RESULT against --x KEY, median and "
                   "IQR band over seeds, one line per value of --by (the supplement's Fig. 8)");
  plot->add_option("--x", plot_x, "with --sweep: spec key on the x axis, e.g. cells.alpha");
  plot->add_option("--y", plot_y, "with --sweep: result, e.g. theta_eq_deg");
  plot->add_option("--by", plot_by, "with --sweep: spec key, one line per value");
  plot->add_option("--heatmap", heatmap,
                   "with --sweep: KEY1,KEY2 — the mean of --y per grid cell (Fig. 15)")
      ->delimiter(',');

  auto* exportc = app.add_subcommand(
      "export", "write a job's snapshots as VTK PolyData (.vtp) + series.pvd for ParaView");
  std::string export_dir;
  exportc->add_option("ID", id)->required();
  exportc->add_option("--out,-o", export_dir, "folder (default: job-ID)");

  auto* sweep = app.add_subcommand("sweep", "submit a grid sweep; prints the sweep id");
  std::vector<std::string> grid;
  std::vector<std::uint64_t> seeds;
  sweep->add_option("SPEC", spec_file, "base spec file");
  sweep->add_option("--scene", scene);
  sweep->add_option("--set", settings);
  sweep->add_option("--preset", preset, kPresetHelp);
  sweep->add_option("--accuracy", accuracy, kAccuracyHelp);
  sweep->add_option("--grid", grid, "key=v1,v2,... (repeatable; cartesian product)");
  sweep->add_option("--seeds", seeds, "seeds (each parameter set runs once per seed)")
      ->delimiter(',');
  sweep->add_option("--tag", tag);
  sweep->add_flag("--wait", wait, "follow every job; exit 0 only if all succeeded");

  auto* report = app.add_subcommand(
      "report",
      "run foam-run for a job placed outside foamd's pool (a Slurm task) and report its "
      "outputs to foamd; exits with foam-run's status (deploy/slurm/README.md)");
  activefoam::client::ReportArgs rargs;
  report->add_option("JOB", rargs.job_id, "job id")->required();
  report->add_option("RUN", rargs.run_dir, "foam-run's --out folder")->required();
  report->add_option("COMMAND", rargs.command, "-- foam-run SPEC --out RUN ...")->required();
  report->add_option("--attempt", rargs.attempt, "the executor's handle of this task")->required();
  report->add_option("--every", rargs.every_s, "seconds between reads of the folder")
      ->check(CLI::Range(0.05, 3600.0));
  report
      ->add_option("--give-up-after", rargs.give_up_after_s,
                   "seconds of foamd being unreachable before giving up (exit 75)")
      ->check(CLI::Range(1.0, 1e7));

  // Every argument may end up in a request (a tag, a setting, an id): non-UTF-8 text (a Latin-1
  // shell, say) would be refused by the server's protobuf parser without a word.
  for (int k = 1; k < argc; ++k)
    if (const std::size_t at = activefoam::invalidUtf8At(argv[k]); at != std::string::npos) {
      const bool value = k > 1 && std::string_view(argv[k - 1]).rfind("--", 0) == 0;
      std::cerr << "foam: argument " << k
                << (value ? " (the value of " + std::string(argv[k - 1]) + ")" : std::string())
                << " is not valid UTF-8 (byte " << at << "); foamd takes UTF-8 text only\n";
      return kUsage;
    }
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e) == 0 ? kOk : kUsage;
  }
  try {
    if (!tls_ca_file.empty()) conn.tls_ca = readFile(tls_ca_file);
    if (!token_file.empty()) {
      conn.token = activefoam::readTokenFile(token_file);
    }
  } catch (const std::exception& e) {
    std::cerr << "foam: " << e.what() << "\n";
    return kUsage;
  }
  conn.connect();

  // --preset and --accuracy are settings like --set ones (the spec's order does not matter).
  if (!preset.empty()) settings.insert(settings.begin(), "numerics.preset=" + preset);
  for (const auto& a : accuracy) settings.insert(settings.begin(), "accuracy." + a);

  auto specText = [&]() -> std::string {
    if (spec_file.empty()) return "";
    std::string text;
    if (spec_file == "-") {
      std::ostringstream s;
      s << std::cin.rdbuf();
      text = s.str();
    } else {
      text = readFile(spec_file);
    }
    if (const std::size_t at = activefoam::invalidUtf8At(text); at != std::string::npos) {
      const auto line = 1 + std::count(text.begin(), text.begin() + static_cast<long>(at), '\n');
      throw std::runtime_error("'" + spec_file + "': not valid UTF-8 at byte " +
                               std::to_string(at) + " (line " + std::to_string(line) +
                               "); save the spec as UTF-8");
    }
    return text;
  };

  if (*report)
    return activefoam::client::reportTask(
        *conn.stub, [&] { return conn.ctx(120); }, rargs);

  try {
    if (*submit) {
      if (spec_file.empty() && scene.empty()) {
        std::cerr << "foam: submit needs SPEC or --scene\n";
        return kUsage;
      }
      v1::SubmitJobRequest req;
      req.set_spec_text(specText());
      if (!scene.empty()) req.add_settings("scene=" + scene);
      for (const auto& s : settings) req.add_settings(s);
      req.set_priority(priority);
      req.set_tag(tag);
      req.set_idempotency_key(idem);
      v1::SubmitJobResponse resp;
      auto ctx = conn.ctx();
      const grpc::Status st = conn.stub->SubmitJob(ctx.get(), req, &resp);
      if (!st.ok()) return rpcError(st, "submit");
      std::cout << resp.job_id() << std::endl;
      if (!resp.created()) std::cerr << "foam: already submitted (same idempotency key)\n";
      if (!wait) return kOk;
      int rc = kRpc;
      auto final = watch(conn, resp.job_id(), quiet, rc);
      return final ? jobExit(*final) : rc;
    }
    if (*watchc) {
      int rc = kRpc;
      auto final = watch(conn, id, quiet, rc);
      if (!final) return rc;
      std::cout << stateName(final->state()) << "\n";
      return jobExit(*final);
    }
    if (*list) {
      v1::ListJobsRequest req;
      for (const auto& s : states) {
        v1::JobState st;
        std::string u = "JOB_STATE_";
        for (char c : s) u += static_cast<char>(std::toupper(c));
        if (!v1::JobState_Parse(u, &st)) {
          std::cerr << "foam: --state: unknown state '" << s << "'\n";
          return kUsage;
        }
        req.add_states(st);
      }
      req.set_tag(tag);
      req.set_sweep_id(sweep_filter);
      req.set_outcome(outcome);
      req.set_page_size(limit);
      v1::ListJobsResponse resp;
      auto ctx = conn.ctx();
      const grpc::Status st = conn.stub->ListJobs(ctx.get(), req, &resp);
      if (!st.ok()) return rpcError(st, "list");
      if (json) {
        std::cout << toJsonText(resp) << "\n";
        return kOk;
      }
      std::printf("%-16s %-10s %-8s %-10s %6s %7s %-24s %s\n", "ID", "STATE", "SCENE", "OUTCOME",
                  "SEED", "PROG", "CREATED", "TAG");
      for (const auto& j : resp.jobs())
        std::printf("%-16s %-10s %-8s %-10s %6llu %6.1f%% %-24s %s\n", j.id().c_str(),
                    stateName(j.state()).c_str(), j.scene().c_str(),
                    j.outcome().empty() ? "-" : j.outcome().c_str(),
                    static_cast<unsigned long long>(j.seed()), 100 * j.progress(),
                    j.created_utc().c_str(), j.tag().c_str());
      if (resp.total() > resp.jobs_size())
        std::cerr << "foam: " << resp.jobs_size() << " of " << resp.total() << " jobs shown\n";
      return kOk;
    }
    if (*show) {
      v1::GetJobRequest req;
      req.set_job_id(id);
      v1::Job j;
      auto ctx = conn.ctx();
      const grpc::Status st = conn.stub->GetJob(ctx.get(), req, &j);
      if (!st.ok()) return rpcError(st, "show " + id);
      if (json) {
        std::cout << toJsonText(j) << "\n";
        return kOk;
      }
      std::cout << stateName(j.state()) << "\n"
                << "id:        " << j.id() << "\n"
                << "scene:     " << j.scene() << " (seed " << j.seed() << ")\n"
                << "progress:  " << 100 * j.progress() << " % (t = " << j.t_s() << " s, "
                << j.steps() << " steps)\n"
                << "created:   " << j.created_utc() << "\n"
                << "started:   " << j.started_utc() << "\n"
                << "finished:  " << j.finished_utc() << "\n"
                << "attempts:  " << j.attempts() << "\n"
                << "engine:    " << j.engine_version() << "\n";
      std::cout << "fidelity:  " << fidelityText(j.spec_json()) << "\n";
      if (!j.executor_ref().empty()) std::cout << "executor:  " << j.executor_ref() << "\n";
      if (!j.outcome().empty()) std::cout << "outcome:   " << j.outcome() << "\n";
      if (!j.reason().empty()) std::cout << "reason:    " << j.reason() << "\n";
      if (!j.tag().empty()) std::cout << "tag:       " << j.tag() << "\n";
      if (!j.sweep_id().empty()) std::cout << "sweep:     " << j.sweep_id() << "\n";
      return kOk;
    }
    if (*cancel) {
      v1::CancelJobRequest req;
      req.set_job_id(id);
      req.set_reason("cancelled with foam cancel");
      v1::Job j;
      auto ctx = conn.ctx();
      const grpc::Status st = conn.stub->CancelJob(ctx.get(), req, &j);
      if (!st.ok()) return rpcError(st, "cancel " + id);
      // A running job stops at its next step: the answer is the request, not the state yet.
      std::cout << (j.state() == v1::JOB_STATE_RUNNING ? std::string("cancelling")
                                                       : stateName(j.state()))
                << "\n";
      return kOk;
    }
    if (*results && id.empty()) {
      if (sweep_filter.empty() && tag.empty()) {
        std::cerr << "foam: results: give a job ID, or --sweep ID / --tag TAG for a table\n";
        return kUsage;
      }
      std::vector<v1::Job> jobs;
      v1::QueryResultsResponse resp;
      if (const int rc = fetchTable(conn, sweep_filter, tag, outcome, metrics, jobs, resp))
        return rc;
      const TableFormat format = json  ? TableFormat::Json
                                 : csv ? TableFormat::Csv
                                       : TableFormat::Text;
      if (by.empty()) {
        printResultsTable(jobs, resp, format);
        return kOk;
      }
      std::string err;
      const auto groups = aggregateBy(jobs, resp, by, err);
      if (!err.empty()) {
        std::cerr << "foam: results --by: " << err << "\n";
        return kUsage;
      }
      printAggregate(groups, by, format);
      return kOk;
    }
    if (*results) {
      v1::GetResultsRequest req;
      req.set_job_id(id);
      req.set_with_samples(json || csv);
      v1::JobResults r;
      auto ctx = conn.ctx();
      const grpc::Status st = conn.stub->GetResults(ctx.get(), req, &r);
      if (!st.ok()) return rpcError(st, "results " + id);
      if (csv) {
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
      if (json) {
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
      if (!r.job().outcome().empty())
        std::printf("  %-24s %s\n", "outcome", r.job().outcome().c_str());
      for (const auto& x : r.results()) std::printf("  %-24s %.6g\n", x.name().c_str(), x.value());
      return kOk;
    }
    if (*exportc) {
      v1::GetResultsRequest req;
      req.set_job_id(id);
      v1::JobResults r;
      auto ctx = conn.ctx();
      const grpc::Status st = conn.stub->GetResults(ctx.get(), req, &r);
      if (!st.ok()) return rpcError(st, "export " + id);
      if (export_dir.empty()) export_dir = "job-" + id;
      if (const std::string err = exportSnapshots(
              *conn.stub, [&] { return conn.ctx(); }, r, export_dir);
          !err.empty()) {
        std::cerr << "foam: export " << id << ": " << err << "\n";
        return kJobNotOk;
      }
      std::cout << (fs::path(export_dir) / "series.pvd").string() << "\n";
      return kOk;
    }
    if (*plot && !sweep_filter.empty()) {
      std::vector<v1::Job> jobs;
      v1::QueryResultsResponse resp;
      if (const int rc = fetchTable(conn, sweep_filter, "", "", {plot_y}, jobs, resp)) return rc;
      if (plot_out.empty()) plot_out = "sweep-" + sweep_filter + "-" + plot_y + ".png";
      const std::string err = heatmap.empty()
                                  ? plotSweep(jobs, resp, plot_x, plot_by, plot_y, plot_out)
                                  : plotHeatmap(jobs, resp, heatmap, plot_y, plot_out);
      if (!err.empty()) {
        std::cerr << "foam: plot --sweep " << sweep_filter << ": " << err << "\n";
        return kUsage;
      }
      std::cout << plot_out << "\n";
      return kOk;
    }
    if (*plot) {
      if (id.empty()) {
        std::cerr << "foam: plot: give a job ID, or --sweep ID with --x and --y\n";
        return kUsage;
      }
      v1::GetResultsRequest req;
      req.set_job_id(id);
      req.set_with_samples(true);
      v1::JobResults r;
      auto ctx = conn.ctx();
      const grpc::Status st = conn.stub->GetResults(ctx.get(), req, &r);
      if (!st.ok()) return rpcError(st, "plot " + id);
      if (plot_out.empty()) plot_out = "job-" + id + "-" + plot_column + ".png";
      if (const std::string err = plotSamples(r, plot_column, plot_out); !err.empty()) {
        std::cerr << "foam: plot " << id << ": " << err << "\n";
        return kUsage;
      }
      std::cout << plot_out << "\n";
      return kOk;
    }
    if (*sweep) {
      v1::SubmitSweepRequest req;
      req.set_spec_text(specText());
      if (!scene.empty()) req.add_settings("scene=" + scene);
      for (const auto& s : settings) req.add_settings(s);
      for (const auto& g : grid) {
        const auto eq = g.find('=');
        if (eq == std::string::npos) {
          std::cerr << "foam: --grid wants key=v1,v2,...\n";
          return kUsage;
        }
        auto* axis = req.add_grid();
        axis->set_key(g.substr(0, eq));
        std::stringstream vs(g.substr(eq + 1));
        for (std::string v; std::getline(vs, v, ',');) axis->add_values(v);
      }
      for (auto s : seeds) req.add_seeds(s);
      req.set_tag(tag);
      v1::SubmitSweepResponse resp;
      auto ctx = conn.ctx();
      const grpc::Status st = conn.stub->SubmitSweep(ctx.get(), req, &resp);
      if (!st.ok()) return rpcError(st, "sweep");
      std::cout << resp.sweep_id() << std::endl;
      std::cerr << "foam: " << resp.job_ids_size() << " jobs\n";
      if (!wait) return kOk;
      int worst = kOk;
      for (const auto& jid : resp.job_ids()) {
        int rc = kRpc;
        auto final = watch(conn, jid, true, rc);
        const int e = final ? jobExit(*final) : rc;
        if (final) std::cerr << "foam: " << jid << " " << stateName(final->state()) << "\n";
        worst = std::max(worst, e);
      }
      return worst;
    }
  } catch (const std::exception& e) {
    std::cerr << "foam: " << e.what() << "\n";
    return kUsage;
  }
  return kUsage;
}
