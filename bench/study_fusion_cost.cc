// Cost of the reference fusion scene (2 × 100 cells, 320 triangles per cell, Table 1/2
// parameters) per integrator and time step: wall time per step and per simulated minute, split
// by phase, and the projected wall time of a 24 h run. The spheroids come from the cache that
// the reference run filled (bench/specs/fusion_reference.toml), so only the fused scene is timed;
// every configuration starts from the same touching spheroids and runs `steps` steps (after 3
// warm-up steps that build the matrix pattern).
//
// Run (about 10 minutes on the 2-core machine):
//   build/release/runner/foam-run bench/specs/fusion_reference.toml --out /tmp/ref
//       --spheroid-cache /tmp/ref-cache     (prepares and caches the two spheroids)
//   OMP_NUM_THREADS=1 build/release/bench/study_fusion_cost /tmp/ref-cache [steps] [n_cells]
//       [prep_max_s] [configs]
// configs: comma-separated integrator:Δt:preconditioner[:ε_CG], e.g.
// "contact-implicit:0.5:jacobi,ros2:0.5:incomplete-cholesky,contact-implicit:0.5:jacobi:1e-2"
// (default: contact-implicit, block-Jacobi, at 0.1 s, ε_CG 1e-3 and at 0.5 s, 1e-2 — the same
// with Jacobi — and semi-implicit at 0.005 s, Jacobi, 1e-3).
// prep_max_s = 0 times the packed, unrelaxed spheroids (no preparation needed; contacts are
// fewer than in relaxed ones, so it underestimates the cost per step).
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <sstream>
#include <string>
#include <vector>

#include "activefoam/simulation.h"
#include "activefoam/spheroid.h"
#include "scheme_config.h"

using namespace activefoam;

int main(int argc, char** argv) {
  if (argc < 2) {
    std::fprintf(stderr,
                 "usage: study_fusion_cost CACHE_DIR [steps] [n_cells] [prep_max_s] [configs]\n");
    return 2;
  }
  const SpheroidCache cache(argv[1]);
  const int steps = argc > 2 ? std::atoi(argv[2]) : 40;
  const int n = argc > 3 ? std::atoi(argv[3]) : 100;
  const double prep = argc > 4 ? std::atof(argv[4]) : 600;
  SceneSpec base;
  base.scene = SceneKind::Fusion;
  base.seed = 1;
  base.scene_params.n_cells = n;
  base.scene_params.prep_max_s = prep;  // 600 as in bench/specs/fusion_reference.toml
  base.numerics.triangles_per_cell = 320;
  base = resolve(base);
  const CellSet cells = buildFusionCells(
      base, &cache, {[](const std::string& l) { std::fprintf(stderr, "%s\n", l.c_str()); }});

  std::printf(
      "| integrator | Δt (s) | preconditioner | ε_CG | CG iters/step | ms/step | geometry | "
      "contacts | "
      "forces | "
      "matrix | solve | remesh | wall per simulated min | projected 24 h |\n");
  std::printf("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|\n");
  std::vector<std::string> configs = {
      "contact-implicit:0.1:block-jacobi:1e-3", "contact-implicit:0.5:block-jacobi:1e-2",
      "contact-implicit:0.1:jacobi:1e-3", "contact-implicit:0.5:jacobi:1e-2",
      "semi-implicit:0.005:jacobi:1e-3"};
  if (argc > 5) {
    configs.clear();
    std::stringstream list(argv[5]);
    for (std::string item; std::getline(list, item, ',');) configs.push_back(item);
  }
  for (const std::string& config : configs) {
    SceneSpec s = base;
    bench::SchemeConfig scheme;
    if (const std::string error = bench::applySchemeConfig(config, s, scheme); !error.empty()) {
      std::fprintf(stderr, "%s: %s\n", config.c_str(), error.c_str());
      return 2;
    }
    struct {
      IntegratorKind integrator;
      double dt;
    } c{s.numerics.integrator, s.numerics.dt_s};
    s = resolve(s);
    Simulation sim(s, cells, scheme.scheme(s));
    for (int k = 0; k < 3; ++k) sim.step();
    const PhaseTimes before = sim.phaseTimes();
    long iters = 0;
    const auto t0 = std::chrono::steady_clock::now();
    int done = 0;
    std::string failure;
    for (; done < steps; ++done) {
      const StepReport r = sim.step();
      if (!r.ok()) {
        failure = std::string(toString(r.failure));
        break;
      }
      iters += r.cg.iterations;
    }
    const double wall =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    const PhaseTimes& p = sim.phaseTimes();
    const double per = done ? wall / done : 0;
    auto ms = [&](double now, double then) { return done ? 1e3 * (now - then) / done : 0.0; };
    const double per_min = per * 60 / c.dt, per_day = per * 86400 / c.dt;
    std::printf(
        "| %s | %g | %s | %g | %.1f | %.0f | %.1f | %.1f | %.1f | %.1f | %.1f | %.1f | %.1f min | "
        "%.0f h |%s\n",
        std::string(toString(c.integrator)).c_str(), c.dt,
        std::string(toString(s.numerics.preconditioner)).c_str(), s.numerics.cg_tol,
        done ? double(iters) / done : 0.0, 1e3 * per, ms(p.geometry, before.geometry),
        ms(p.contacts, before.contacts), ms(p.forces, before.forces), ms(p.matrix, before.matrix),
        ms(p.solve, before.solve), ms(p.remesh, before.remesh), per_min / 60, per_day / 3600,
        failure.empty() ? "" : (" failed: " + failure).c_str());
    std::fflush(stdout);
  }
  return 0;
}
