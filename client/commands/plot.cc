// foam plot: PNG charts drawn by gnuplot, of one job's samples over time or of a sweep's results
// against its parameters.
#include <sys/wait.h>

#include <cmath>
#include <cstdio>
#include <initializer_list>
#include <iostream>
#include <map>
#include <set>
#include <sstream>

#include <CLI/CLI.hpp>

#include "../commands.h"
#include "../table.h"

namespace activefoam::client {
namespace {

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
    // Closed form of Eq. 2 in u = cos θ (docs/model.md §8.3).
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

// gnuplot's enhanced text reads '_' as a subscript: a spec key or result name keeps its '_'.
std::string escapeEnhanced(const std::string& key) {
  std::string out;
  for (char c : key) out += c == '_' ? std::string("\\_") : std::string(1, c);
  return out;
}

// Axis labels with units; the reduced names (docs/model.md §9.2) where the key is one.
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

int runSweepPlot(Conn& conn, const PlotOptions& o) {
  std::vector<v1::Job> jobs;
  v1::QueryResultsResponse resp;
  if (const int rc = fetchTable(conn, o.sweep, "", "", {o.y}, jobs, resp)) return rc;
  const std::string out = o.out.empty() ? "sweep-" + o.sweep + "-" + o.y + ".png" : o.out;
  const std::string err = o.heatmap.empty() ? plotSweep(jobs, resp, o.x, o.by, o.y, out)
                                            : plotHeatmap(jobs, resp, o.heatmap, o.y, out);
  if (!err.empty()) {
    std::cerr << "foam: plot --sweep " << o.sweep << ": " << err << "\n";
    return kUsage;
  }
  std::cout << out << "\n";
  return kOk;
}

int runJobPlot(Conn& conn, const PlotOptions& o) {
  if (o.id.empty()) {
    std::cerr << "foam: plot: give a job ID, or --sweep ID with --x and --y\n";
    return kUsage;
  }
  v1::GetResultsRequest req;
  req.set_job_id(o.id);
  req.set_with_samples(true);
  v1::JobResults r;
  auto ctx = conn.ctx();
  const grpc::Status st = conn.stub->GetResults(ctx.get(), req, &r);
  if (!st.ok()) return rpcError(st, "plot " + o.id);
  const std::string out = o.out.empty() ? "job-" + o.id + "-" + o.column + ".png" : o.out;
  if (const std::string err = plotSamples(r, o.column, out); !err.empty()) {
    std::cerr << "foam: plot " << o.id << ": " << err << "\n";
    return kUsage;
  }
  std::cout << out << "\n";
  return kOk;
}

}  // namespace

CLI::App* setupPlot(CLI::App& app, PlotOptions& o) {
  auto* plot = app.add_subcommand("plot",
                                  "PNG chart of a sample column over time (gnuplot); "
                                  "θ(t) of a fusion job with its Eq. 1 / Eq. 2 fits");
  plot->add_option("ID", o.id);
  plot->add_option("--out,-o", o.out, "PNG file (default: job-ID-COLUMN.png)");
  plot->add_option("--column", o.column, "sample column")->capture_default_str();
  plot->add_option("--sweep", o.sweep,
                   "a sweep's chart instead of a job's: --y RESULT against --x KEY, median and "
                   "IQR band over seeds, one line per value of --by (the supplement's Fig. 8)");
  plot->add_option("--x", o.x, "with --sweep: spec key on the x axis, e.g. cells.alpha");
  plot->add_option("--y", o.y, "with --sweep: result, e.g. theta_eq_deg");
  plot->add_option("--by", o.by, "with --sweep: spec key, one line per value");
  plot->add_option("--heatmap", o.heatmap,
                   "with --sweep: KEY1,KEY2 — the mean of --y per grid cell (Fig. 15)")
      ->delimiter(',');
  return plot;
}

int runPlot(Conn& conn, const PlotOptions& o) {
  return o.sweep.empty() ? runJobPlot(conn, o) : runSweepPlot(conn, o);
}

}  // namespace activefoam::client
