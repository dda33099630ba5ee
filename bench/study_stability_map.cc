// Stability map: for each integrator, the largest stable Δt on the doublet as a function
// of the contact stiffness k_AB and of the motility p_a r/2γ, with the failure kind that ends the
// next larger Δt (blow-up, CG stall, inverted triangles, volume drift, contact oscillation,
// interpenetration, or `separated`: the cells ended out of contact range).
// With ros2, softer contacts (k_AB × 1/16, 1/64) and the adaptive step: the
// fixed-Δt ladders measure where a step fails; the adaptive ladders (numerics.adaptive = true,
// the default) where a run still finishes, at what mean Δt, with how many rejected tries.
// contact-implicit-consistent's refusals rest on its own rows.
//
// A cell of the map: the α = 0.4375 doublet from a gap of min(50 nm, 0.8 h0), equal radii, run for
// max(1000 steps, `duration` s of simulated time) at each Δt of the integrator's ladder; "stable"
// = no failure detected. The largest stable Δt is the largest rung below which every rung was
// stable. Each run is forked (a blow-up cannot take the study down).
//
// Run on the 2-core machine (about 30 minutes):
//   OMP_NUM_THREADS=1 build/release/bench/study_stability_map docs/study [duration_s]
// Writes DIR/stability-map.csv (every run) and DIR/stability-map.md.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "activefoam/doublet_study.h"
#include "activefoam/simulation.h"
#include "forked.h"

using namespace activefoam;

namespace {

struct Outcome {
  char failure[64] = "";
  double t_end = 0, wall = 0;
  long long steps = 0, rejected = 0;
};

SceneSpec mapSpec(IntegratorKind integrator, double dt, double k_factor, double pa_reduced,
                  bool adaptive) {
  NumericsParams n;
  n.integrator = integrator;
  n.dt_s = dt;
  n.adaptive = adaptive;  // fixed: where a step fails; adaptive: where a run still finishes
  return doubletStudySpec(n, pa_reduced, k_factor);
}

Outcome runOne(const SceneSpec& s, double duration) {
  Outcome o;
  Simulation sim(s);
  const auto t0 = std::chrono::steady_clock::now();
  const std::int64_t n = std::max<std::int64_t>(1000, std::llround(duration / s.numerics.dt_s));
  for (std::int64_t k = 0; k < n; ++k) {
    const StepReport r = sim.step();
    if (!r.ok()) {
      std::snprintf(o.failure, sizeof o.failure, "%s", std::string(toString(r.failure)).c_str());
      break;
    }
  }
  o.wall = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  // Cells that an explicit contact spring has thrown out of range end without contact: not a
  // stable doublet, whatever the step checks said.
  if (o.failure[0] == '\0' && sim.contacts().pairs.empty())
    std::snprintf(o.failure, sizeof o.failure, "separated");
  o.t_end = sim.time();
  o.steps = sim.steps();
  o.rejected = sim.stepsRejected();
  return o;
}

Outcome runIsolated(const SceneSpec& s, double duration) {
  if (auto o = bench::runForked([&] { return runOne(s, duration); })) return *o;
  Outcome crashed;
  std::snprintf(crashed.failure, sizeof crashed.failure, "crashed");
  return crashed;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 2) {
    std::fprintf(stderr, "usage: study_stability_map OUT_DIR [duration_s]\n");
    return 2;
  }
  const std::filesystem::path dir = argv[1];
  const double duration = argc > 2 ? std::atof(argv[2]) : 200;
  std::filesystem::create_directories(dir);
  const std::vector<double> k_factors = {1.0 / 64, 1.0 / 16, 0.25, 1, 4};
  const std::vector<double> pas = {0, 0.33, 1};
  struct Ladder {
    IntegratorKind integrator;
    bool adaptive;
    std::vector<double> dts;
  };
  // The explicit spring's limit scales like 1/k_AB: soft contacts need the longer rungs.
  const std::vector<double> implicit = {0.1, 0.25, 0.5, 1, 2, 4};
  const std::vector<Ladder> ladders = {
      {IntegratorKind::SemiImplicit, false, {0.0025, 0.005, 0.01, 0.02, 0.04, 0.08, 0.16, 0.32}},
      {IntegratorKind::ContactImplicit, false, implicit},
      {IntegratorKind::Ros2, false, implicit},
      {IntegratorKind::ContactImplicitConsistent, false, implicit},
      {IntegratorKind::ContactImplicit, true, implicit},
      {IntegratorKind::Ros2, true, implicit},
      {IntegratorKind::ContactImplicitConsistent, true, implicit}};

  std::ofstream csv(dir / "stability-map.csv");
  csv << "integrator,adaptive,k_factor,k_contact,pa_reduced,dt_s,outcome,t_end_s,steps,"
         "steps_rejected,wall_s\n";
  struct Cell {
    double largest = 0;
    std::string next_failure;
    double next_dt = 0;
    double mean_dt = 0;  // adaptive: simulated time per accepted step at `largest`
    long long rejected = 0;
  };
  std::vector<std::vector<std::vector<Cell>>> map(
      ladders.size(),
      std::vector<std::vector<Cell>>(k_factors.size(), std::vector<Cell>(pas.size())));
  for (std::size_t li = 0; li < ladders.size(); ++li)
    for (std::size_t ki = 0; ki < k_factors.size(); ++ki)
      for (std::size_t pi = 0; pi < pas.size(); ++pi) {
        Cell& cell = map[li][ki][pi];
        int failures = 0;
        bool all_stable = true;
        for (double dt : ladders[li].dts) {
          const SceneSpec s =
              mapSpec(ladders[li].integrator, dt, k_factors[ki], pas[pi], ladders[li].adaptive);
          const Outcome o = runIsolated(s, duration);
          const bool ok = o.failure[0] == '\0';
          csv << toString(ladders[li].integrator) << ',' << ladders[li].adaptive << ','
              << k_factors[ki] << ',' << s.cells.k_contact << ',' << pas[pi] << ',' << dt << ','
              << (ok ? "stable" : o.failure) << ',' << o.t_end << ',' << o.steps << ','
              << o.rejected << ',' << o.wall << '\n';
          csv.flush();
          std::fprintf(stderr, "%s%s k×%g pa %g dt %g: %s (t = %g s, %lld rejected, %.1f s)\n",
                       std::string(toString(ladders[li].integrator)).c_str(),
                       ladders[li].adaptive ? " adaptive" : "", k_factors[ki], pas[pi], dt,
                       ok ? "stable" : o.failure, o.t_end, o.rejected, o.wall);
          if (ok && all_stable) {
            cell.largest = dt;
            cell.mean_dt = o.steps > 0 ? o.t_end / static_cast<double>(o.steps) : 0;
            cell.rejected = o.rejected;
          }
          if (!ok && all_stable) {
            cell.next_failure = o.failure;
            cell.next_dt = dt;
          }
          all_stable = all_stable && ok;
          if (!ok && ++failures >= 2) break;  // the trend is clear; larger steps fail too
        }
      }

  std::ofstream md(dir / "stability-map.md");
  const CellParams d;
  md << "# Stability map: largest stable Δt on the doublet\n\n"
     << "The α = 0.4375 doublet (equal radii r = " << d.radius_mean_um
     << " µm, 320 triangles), run for max(1000 steps, " << duration
     << " s) at each Δt of a ladder, from a gap of min(50 nm, 0.8 h0); stable = no failure "
        "detected (non-finite, CG not converged, inverted triangle, volume drift, contact "
        "oscillation, interpenetration) and the cells still in contact at the end (else "
        "`separated`). Each entry is "
        "the largest Δt below which every rung ran stable, and in brackets the failure that "
        "ended the next rung. k_AB in units of the default "
     << d.k_contact << " nN/µm³; motility as p_a r/2γ (0.33 is the supplement's).\n\n"
     << "Generated by `OMP_NUM_THREADS=1 build/release/bench/study_stability_map " << dir.string()
     << " " << duration << "`; every run in stability-map.csv.\n\n"
     << "Fixed Δt (`numerics.adaptive = false`): the largest Δt at which a step never failed. "
        "Adaptive (the default): a failing try is undone and retried at half the step (down to "
        "Δt/64), so the run finishes where a fixed step fails; its entry is the largest asked Δt "
        "whose run (and every smaller rung's) finished, with the mean step it took (simulated "
        "time / accepted steps) and its rejected tries.\n\n";
  for (std::size_t li = 0; li < ladders.size(); ++li) {
    md << "## " << toString(ladders[li].integrator)
       << (ladders[li].adaptive ? ", adaptive" : ", fixed Δt") << " (ladder:";
    for (double dt : ladders[li].dts) md << ' ' << dt;
    md << " s)\n\n| k_AB × | ";
    for (double pa : pas) md << "p_a r/2γ = " << pa << " | ";
    md << "\n|---|";
    for (std::size_t pi = 0; pi < pas.size(); ++pi) md << "---|";
    md << '\n';
    for (std::size_t ki = 0; ki < k_factors.size(); ++ki) {
      char k_label[32];
      if (k_factors[ki] < 0.2)
        std::snprintf(k_label, sizeof k_label, "1/%ld", std::lround(1 / k_factors[ki]));
      else
        std::snprintf(k_label, sizeof k_label, "%g", k_factors[ki]);
      md << "| " << k_label << " | ";
      for (std::size_t pi = 0; pi < pas.size(); ++pi) {
        const Cell& c = map[li][ki][pi];
        if (c.largest > 0 && ladders[li].adaptive) {
          char mean[32];
          std::snprintf(mean, sizeof mean, "%.3g", c.mean_dt);
          md << c.largest << " s (mean " << mean << " s, " << c.rejected << " rejected)";
        } else if (c.largest > 0)
          md << c.largest << " s";
        else
          md << "< " << ladders[li].dts.front() << " s";
        if (!c.next_failure.empty()) md << " (" << c.next_failure << " at " << c.next_dt << " s)";
        md << " | ";
      }
      md << '\n';
    }
    md << '\n';
  }
  return 0;
}
