// foam-run's output folder (see run_output.h).
#include "activefoam/run_output.h"

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <ctime>
#include <sstream>
#include <stdexcept>

#include "activefoam/checksum.h"
#include "activefoam/spec_io.h"
#include "activefoam/vtk.h"

namespace activefoam {

namespace fs = std::filesystem;

void writeFileAtomic(const fs::path& path, std::string_view content) {
  fs::path tmp = path;
  tmp += ".tmp";
  {
    std::ofstream out(tmp, std::ios::binary | std::ios::trunc);
    if (!out)
      throw std::runtime_error("cannot write " + tmp.string() + ": " + std::strerror(errno));
    out.write(content.data(), static_cast<std::streamsize>(content.size()));
    out.flush();
    if (!out)
      throw std::runtime_error("cannot write " + tmp.string() + ": " + std::strerror(errno));
  }
  std::error_code ec;
  fs::rename(tmp, path, ec);
  if (ec) {
    fs::remove(tmp, ec);
    throw std::runtime_error("cannot rename " + tmp.string() + " to " + path.string() + ": " +
                             ec.message());
  }
}

std::string checkOutputDir(const fs::path& dir, bool force) {
  // Built by appending: GCC 12 warns falsely (-Wrestrict) on "literal" + std::string&&.
  std::string quoted = "'";
  quoted.append(dir.string()).append("'");
  std::error_code ec;
  const fs::file_status st = fs::status(dir, ec);
  if (!fs::exists(st)) return {};
  if (!fs::is_directory(st)) return quoted.append(" exists and is not a directory");
  if (force) return {};
  const bool empty = fs::is_empty(dir, ec);
  if (ec) return std::string("cannot read ").append(quoted).append(": ").append(ec.message());
  if (!empty)
    return std::string("output directory ")
        .append(quoted)
        .append(" exists and is not empty (use --force)");
  return {};
}

std::string csvLine(const std::vector<double>& values) {
  std::string line;
  for (std::size_t i = 0; i < values.size(); ++i) {
    if (i) line += ',';
    line += formatNumber(values[i]);
  }
  return line;
}

std::string csvLine(const std::vector<std::string>& names) {
  std::string line;
  for (std::size_t i = 0; i < names.size(); ++i) {
    if (i) line += ',';
    line += names[i];
  }
  return line;
}

namespace {

// JSON number, or null where JSON has none (nan, inf).
nlohmann::json number(double v) {
  return std::isfinite(v) ? nlohmann::json(v) : nlohmann::json();
}

}  // namespace

nlohmann::json reducedParameters(const SceneSpec& s) {
  const CellParams& c = s.cells;
  const double r = c.radius_mean_um;
  nlohmann::json j;
  j["tau_gamma_s"] = number(c.eta / c.gamma);
  j["pa_reduced"] = number(c.p_a * r / (2.0 * c.gamma));
  j["alpha"] = number(c.alpha);
  j["l_eta_reduced"] = c.xi > 0 ? number(std::sqrt(c.eta / c.xi) / r) : nlohmann::json();
  j["tau_p_s"] = number(c.tau_p_s);
  j["n_cells"] = sceneCellCount(s);
  return j;
}

nlohmann::json summaryToJson(const RunSummary& summary, const SceneSpec& resolved,
                             const SummaryContext& ctx) {
  nlohmann::json j;
  const bool runner_failed = !ctx.failure_override.empty();
  j["ok"] = summary.ok() && !runner_failed;
  j["failure"] = runner_failed ? ctx.failure_override : std::string(toString(summary.failure));
  j["reason"] = !ctx.reason_override.empty() ? ctx.reason_override : summary.reason;
  j["cancelled"] = !runner_failed && summary.failure == FailureKind::Cancelled;
  j["scene"] = std::string(toString(resolved.scene));
  j["seed"] = resolved.seed;
  j["engine_version"] = ACTIVEFOAM_VERSION;
  j["t_s"] = number(summary.t_s);
  j["duration_s"] = number(resolved.duration_s);
  j["steps"] = summary.steps;
  j["wall_s"] = number(summary.wall_s);
  j["runner_wall_s"] = number(ctx.runner_wall_s);
  j["cg_iters_mean"] = number(summary.cg_iters_mean);
  j["remesh_ops"] = summary.remesh_ops;
  j["remesh_rescues"] = summary.remesh_rescues;
  j["remesh_rebuilds"] = summary.remesh_rebuilds;
  j["remesh_kept_out"] = summary.remesh_kept_out;
  j["steps_rejected"] = summary.steps_rejected;
  j["dt_min_s"] = number(summary.dt_min_s);
  nlohmann::json final_values = nlohmann::json::object();
  for (const auto& [name, v] : summary.final_values) final_values[name] = number(v);
  j["final_values"] = final_values;
  nlohmann::json phases = nlohmann::json::object();
  for (const auto& [name, v] : summary.phase_wall_s) phases[name] = number(v);
  j["phase_wall_s"] = phases;
  if (!summary.outcome.empty()) {
    j["outcome"] = summary.outcome;
    j["outcome_reason"] = summary.outcome_why;
  }
  if (!summary.fits.empty()) {
    // Each fit in full under "fits", and its parameters at the top level (null when the fit
    // failed; "fits" says why) so that a study can read theta_eq_deg directly.
    nlohmann::json fits = nlohmann::json::object();
    for (const auto& [model, f] : summary.fits) {
      nlohmann::json fj;
      fj["ok"] = f.ok;
      if (!f.ok) fj["why"] = f.why;
      nlohmann::json params = nlohmann::json::object();
      for (std::size_t k = 0; k < f.names.size(); ++k) {
        params[f.names[k]] = {
            {"value", number(f.value[k])},
            {"std_error", number(k < f.std_error.size() ? f.std_error[k] : std::nan(""))}};
        j[fitResultName(model, f.names[k])] = f.ok ? number(f.value[k]) : nlohmann::json();
      }
      fj["parameters"] = params;
      fj["n"] = f.n;
      fj["rss"] = number(f.rss);
      fj["r2"] = number(f.r2);
      fits[model] = fj;
    }
    j["fits"] = fits;
  }
  if (!summary.msrd.empty()) {
    nlohmann::json lag = nlohmann::json::array(), value = nlohmann::json::array();
    for (const auto& [l, m] : summary.msrd) {
      lag.push_back(number(l));
      value.push_back(number(m));
    }
    j["msrd"] = {{"lag_s", lag}, {"msrd_um2", value}};
  }
  if (!summary.curves.empty()) {
    // The probes' curves by name, x and y aligned ("msrd" keeps its own place and spelling).
    nlohmann::json curves = nlohmann::json::object();
    for (const RunSummary::Curve& c : summary.curves) {
      nlohmann::json x = nlohmann::json::array(), y = nlohmann::json::array();
      for (double v : c.x) x.push_back(number(v));
      for (double v : c.y) y.push_back(number(v));
      curves[c.name] = {{"x", x}, {"y", y}};
    }
    j["curves"] = curves;
  }
  j["reduced"] = reducedParameters(resolved);
  j["samples"] = ctx.samples_written;
  j["snapshots"] = ctx.snapshots_written;
  if (ctx.resumed_from_t_s >= 0) j["resumed_from_t_s"] = number(ctx.resumed_from_t_s);
  if (!ctx.started_utc.empty()) j["started_utc"] = ctx.started_utc;
  if (!ctx.finished_utc.empty()) j["finished_utc"] = ctx.finished_utc;
  return j;
}

FlatResults flattenSummary(const nlohmann::json& j) {
  auto num = [](const nlohmann::json& v) {
    return v.is_number() ? v.get<double>() : std::nan("");  // null: NaN, as the pool stores it
  };
  FlatResults out;
  auto& results = out.values;
  const nlohmann::json none = nlohmann::json::object();
  const nlohmann::json& final_values = j.contains("final_values") ? j["final_values"] : none;
  for (const auto& [name, v] : final_values.items()) results.emplace_back(name, num(v));
  results.emplace_back("t_s", num(j.value("t_s", nlohmann::json())));
  results.emplace_back("steps", num(j.value("steps", nlohmann::json())));
  results.emplace_back("wall_s", num(j.value("wall_s", nlohmann::json())));
  results.emplace_back("cg_iters_mean", num(j.value("cg_iters_mean", nlohmann::json())));
  results.emplace_back("remesh_ops", num(j.value("remesh_ops", nlohmann::json())));
  results.emplace_back("remesh_rescues", num(j.value("remesh_rescues", nlohmann::json())));
  results.emplace_back("remesh_rebuilds", num(j.value("remesh_rebuilds", nlohmann::json())));
  results.emplace_back("remesh_kept_out", num(j.value("remesh_kept_out", nlohmann::json())));
  results.emplace_back("steps_rejected", num(j.value("steps_rejected", nlohmann::json())));
  results.emplace_back("dt_min_s", num(j.value("dt_min_s", nlohmann::json())));
  const nlohmann::json& fits = j.contains("fits") ? j["fits"] : none;
  for (const auto& [model, f] : fits.items()) {
    const bool ok = f.value("ok", false);
    results.emplace_back(model + "_ok", ok ? 1 : 0);
    if (!ok) continue;
    results.emplace_back(model + "_r2", num(f.value("r2", nlohmann::json())));
    const nlohmann::json& params = f.contains("parameters") ? f["parameters"] : none;
    for (const auto& [param, p] : params.items()) {
      const std::string name = fitResultName(model, param);
      results.emplace_back(name, num(p.value("value", nlohmann::json())));
      results.emplace_back(name + "_se", num(p.value("std_error", nlohmann::json())));
    }
  }
  if (j.contains("outcome") && j["outcome"].is_string())
    out.outcome = j["outcome"].get<std::string>();
  if (j.contains("msrd") && j["msrd"].is_object()) {
    const auto& m = j["msrd"];
    FlatCurve c{"msrd", {}, {}};
    if (m.contains("lag_s") && m.contains("msrd_um2") && m["lag_s"].is_array() &&
        m["msrd_um2"].is_array() && m["lag_s"].size() == m["msrd_um2"].size()) {
      for (std::size_t k = 0; k < m["lag_s"].size(); ++k) {
        c.x.push_back(num(m["lag_s"][k]));
        c.y.push_back(num(m["msrd_um2"][k]));
      }
      out.curves.push_back(std::move(c));
    }
  }
  const nlohmann::json& curves = j.contains("curves") ? j["curves"] : none;
  for (const auto& [name, cj] : curves.items()) {
    if (!cj.is_object() || !cj.contains("x") || !cj.contains("y") || !cj["x"].is_array() ||
        !cj["y"].is_array() || cj["x"].size() != cj["y"].size())
      continue;
    FlatCurve c{name, {}, {}};
    for (std::size_t k = 0; k < cj["x"].size(); ++k) {
      c.x.push_back(num(cj["x"][k]));
      c.y.push_back(num(cj["y"][k]));
    }
    out.curves.push_back(std::move(c));
  }
  return out;
}

VtkMesh toVtkMesh(const Snapshot& snap) {
  VtkMesh m;
  m.t_s = snap.t_s;
  m.step = snap.step;
  m.points.assign(snap.x.data(), snap.x.data() + snap.x.size());
  m.tri.assign(snap.tri.begin(), snap.tri.end());
  m.vertex_cell = snap.vertex_cell;
  m.cell_pressure = snap.cell_pressure;
  m.cell_label = snap.cell_label;
  return m;
}

std::string utcNow() {
  const std::time_t t = std::chrono::system_clock::to_time_t(std::chrono::system_clock::now());
  std::tm tm{};
  gmtime_r(&t, &tm);
  char buf[32];
  std::strftime(buf, sizeof buf, "%Y-%m-%dT%H:%M:%SZ", &tm);
  return buf;
}

// ---- checkpoint.bin ----------------------------------------------------------------------------
// One JSON line (what the folder holds at the checkpoint), then the engine's state, raw, the
// whole sealed by a checksum: a damaged file (a flipped bit in the header's sample count as much
// as in the state) is refused before anything of it is used.

namespace {
constexpr std::string_view kCheckpointMagic = "activefoam-run-checkpoint 2\n";
constexpr std::string_view kCheckpointMagicV1 = "activefoam-run-checkpoint 1\n";
}  // namespace

std::string encodeRunCheckpoint(const RunCheckpoint& c) {
  nlohmann::json h;
  h["t_s"] = c.t_s;
  h["samples"] = c.samples;
  nlohmann::json snaps = nlohmann::json::array();
  for (const auto& [t, name] : c.snapshots) snaps.push_back({t, name});
  h["snapshots"] = snaps;
  h["state_bytes"] = c.state.size();
  std::string out(kCheckpointMagic);
  out += h.dump() + "\n";
  out += c.state;
  return sealed(std::move(out));
}

RunCheckpoint decodeRunCheckpoint(const std::string& bytes, const std::string& what) {
  auto damaged = [&](const std::string& why) {
    return std::runtime_error(what + " is damaged (" + why + "); remove it to start over");
  };
  if (bytes.compare(0, kCheckpointMagicV1.size(), kCheckpointMagicV1) == 0)
    throw damaged("written by an earlier foam-run, without a checksum");
  if (bytes.compare(0, kCheckpointMagic.size(), kCheckpointMagic) != 0)
    throw damaged("not a foam-run checkpoint");
  const auto body = unsealed(bytes);
  if (!body) throw damaged("its checksum does not match its content");
  const std::string_view content = *body;
  const std::size_t eol = content.find('\n', kCheckpointMagic.size());
  if (eol == std::string::npos) throw damaged("no header");
  RunCheckpoint c;
  try {
    const auto h = nlohmann::json::parse(
        content.substr(kCheckpointMagic.size(), eol - kCheckpointMagic.size()));
    c.t_s = h.at("t_s").get<double>();
    c.samples = h.at("samples").get<std::int64_t>();
    for (const auto& s : h.at("snapshots"))
      c.snapshots.emplace_back(s.at(0).get<double>(), s.at(1).get<std::string>());
    const auto n = h.at("state_bytes").get<std::size_t>();
    if (content.size() - eol - 1 != n) throw damaged("truncated");
    c.state = std::string(content.substr(eol + 1));
  } catch (const nlohmann::json::exception& e) {
    throw damaged(e.what());
  }
  if (c.samples < 0) throw damaged("negative sample count");
  return c;
}

// ---- RunOutput ---------------------------------------------------------------------------------

RunOutput::RunOutput(fs::path dir, const SceneSpec& resolved)
    : dir_(std::move(dir)), spec_(resolved) {}

void RunOutput::fail(std::string message) {
  if (error_.empty()) error_ = std::move(message);
}

void RunOutput::start() {
  if (!error_.empty()) return;
  try {
    writeFileAtomic(dir_ / "spec.json", specToJson(spec_).dump(2) + "\n");
  } catch (const std::exception& e) {
    return fail(e.what());
  }
  const fs::path path = dir_ / "samples.csv";
  csv_.open(path, std::ios::binary | std::ios::trunc);
  const std::vector<std::string> columns = sampleColumns(spec_);
  columns_ = columns.size();
  csv_ << csvLine(columns) << '\n';
  csv_.flush();
  if (!csv_) fail("cannot write " + path.string() + ": " + std::strerror(errno));
}

void RunOutput::onSample(const Sample& sample) {
  if (!csv_.is_open()) start();
  if (!error_.empty()) return;
  std::vector<double> values = sample.values;
  if (values.size() != columns_) {
    if (warning_.empty())
      warning_ = "a sample has " + std::to_string(values.size()) + " values for " +
                 std::to_string(columns_) + " columns; rows were padded with nan or cut";
    values.resize(columns_, std::nan(""));
  }
  csv_ << csvLine(values) << '\n';
  csv_.flush();  // a crash leaves complete rows
  if (!csv_)
    return fail("cannot write " + (dir_ / "samples.csv").string() + ": " + std::strerror(errno));
  ++samples_;
}

void RunOutput::onSnapshot(const Snapshot& snap) {
  if (!error_.empty()) return;
  const fs::path sdir = dir_ / "snapshots";
  try {
    std::error_code ec;
    fs::create_directories(sdir, ec);
    if (ec) throw std::runtime_error("cannot create " + sdir.string() + ": " + ec.message());
    char name[32];
    std::snprintf(name, sizeof name, "snap_%06zu.vtp", series_.size());
    std::ostringstream vtp;
    writeVtp(vtp, toVtkMesh(snap));
    writeFileAtomic(sdir / name, vtp.str());
    series_.emplace_back(snap.t_s, name);
    std::ostringstream pvd;
    writePvd(pvd, series_);
    writeFileAtomic(sdir / "series.pvd", pvd.str());
  } catch (const std::exception& e) {
    fail(e.what());
  }
}

void RunOutput::resume(const RunCheckpoint& c) {
  if (!error_.empty()) return;
  const fs::path path = dir_ / "samples.csv";
  try {
    writeFileAtomic(dir_ / "spec.json", specToJson(spec_).dump(2) + "\n");
    std::ifstream in(path, std::ios::binary);
    if (!in) throw std::runtime_error("cannot read " + path.string() + ": " + std::strerror(errno));
    std::string kept, line;
    std::int64_t rows = -1;  // the header first
    while (rows < c.samples && std::getline(in, line)) {
      kept += line + '\n';
      ++rows;
    }
    if (rows < c.samples)
      throw std::runtime_error(path.string() + " has " +
                               std::to_string(std::max<std::int64_t>(rows, 0)) +
                               " rows, the checkpoint expects " + std::to_string(c.samples));
    in.close();
    writeFileAtomic(path, kept);
    columns_ = sampleColumns(spec_).size();
    samples_ = c.samples;
    csv_.open(path, std::ios::binary | std::ios::app);
    if (!csv_)
      throw std::runtime_error("cannot write " + path.string() + ": " + std::strerror(errno));

    series_ = c.snapshots;
    const fs::path sdir = dir_ / "snapshots";
    std::error_code ec;
    if (fs::is_directory(sdir, ec)) {
      for (const auto& entry : fs::directory_iterator(sdir)) {
        const std::string name = entry.path().filename().string();
        const bool kept_snap = std::any_of(series_.begin(), series_.end(),
                                           [&](const auto& s) { return s.second == name; });
        if (!kept_snap && name != "series.pvd") fs::remove(entry.path(), ec);
      }
      std::ostringstream pvd;
      writePvd(pvd, series_);
      writeFileAtomic(sdir / "series.pvd", pvd.str());
    }
    fs::remove(dir_ / "summary.json", ec);
  } catch (const std::exception& e) {
    fail(e.what());
  }
}

void RunOutput::writeCheckpoint(double t_s, const std::string& state) {
  if (!error_.empty()) return;
  RunCheckpoint c;
  c.t_s = t_s;
  c.samples = samples_;
  c.snapshots = series_;
  c.state = state;
  try {
    writeFileAtomic(dir_ / "checkpoint.bin", encodeRunCheckpoint(c));
  } catch (const std::exception& e) {
    fail(e.what());
  }
}

void RunOutput::removeCheckpoint() {
  std::error_code ec;
  fs::remove(dir_ / "checkpoint.bin", ec);
}

void RunOutput::writeSummary(const nlohmann::json& summary) {
  // Written even after an earlier write error: the summary is what says what happened.
  try {
    writeFileAtomic(dir_ / "summary.json", summary.dump(2) + "\n");
  } catch (const std::exception& e) {
    fail(e.what());
  }
}

}  // namespace activefoam
