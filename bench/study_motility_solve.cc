// How much of the cells' motile velocity does one step's solve keep, per step? The
// preset-fitness study (docs/science/presets.md) found the MSRD of the contact-implicit step at
// Δt 0.5 s, ε_CG 1e-2 far below that at Δt 0.1 s, ε_CG 1e-3; they differ in two things, Δt
// (Γ carries Δt K_c, the contact springs' stiffness) and ε_CG. This separates them on one state
// of a fusing 2 × N aggregate: the motile velocity is v(F) − v(F without migration), and per cell
// its centroid (what the MSRD integrates). Exact solves (ε 1e-12) at Δt 0.1 and 0.5 s measure
// what Δt K_c does; solves at ε 1e-2 and 1e-3 from the step's warm start what the tolerance
// loses.
//
//   build/release/bench/study_motility_solve CACHE_DIR [n_cells] [relax_s] [seed]
//
// CACHE_DIR keeps the prepared spheroids (as foam-run --spheroid-cache).
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>

#include "activefoam/simulation.h"
#include "activefoam/spheroid.h"

using namespace activefoam;

namespace {

// Area-weighted mean of a velocity field per cell (3 × cells).
Eigen::Matrix3Xd cellVelocities(const Simulation& sim, const Eigen::VectorXd& v) {
  const CellSet& c = sim.cells();
  const Geometry& g = sim.geometry();
  Eigen::Matrix3Xd out = Eigen::Matrix3Xd::Zero(3, c.numCells());
  for (int k = 0; k < c.numCells(); ++k) {
    double area = 0;
    for (int i = c.cell_vertex_begin[k]; i < c.cell_vertex_begin[k + 1]; ++i) {
      out.col(k) += g.vertex_area[i] * v.segment<3>(3 * i);
      area += g.vertex_area[i];
    }
    out.col(k) /= area;
  }
  return out;
}

// Γ v = F for this simulation's Γ (its Δt's K_c) from `start`, to `tol`.
Eigen::VectorXd solve(Simulation& sim, const Eigen::Matrix3Xd& f, const Eigen::VectorXd& start,
                      double tol, int* iterations = nullptr) {
  sim.prepareFriction();
  Eigen::VectorXd x = start;
  const Eigen::VectorXd b = Eigen::Map<const Eigen::VectorXd>(f.data(), f.size());
  LinearSolver cg(PreconditionerKind::BlockJacobi, tol, 100000);
  const SolveStats s = cg.solve([&](const double* in, double* out) { sim.applyFriction(in, out); },
                                sim.frictionMatrix(), b, x);
  if (iterations) *iterations = s.iterations;
  return x;
}

double rms(const Eigen::Matrix3Xd& m) {
  return std::sqrt(m.colwise().squaredNorm().mean());
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 2) {
    std::fprintf(stderr, "usage: study_motility_solve CACHE_DIR [n_cells] [relax_s] [seed]\n");
    return 2;
  }
  const SpheroidCache cache(argv[1]);
  const int n = argc > 2 ? std::atoi(argv[2]) : 20;
  const double relax_s = argc > 3 ? std::atof(argv[3]) : 600;
  const std::uint64_t seed = argc > 4 ? std::strtoull(argv[4], nullptr, 10) : 1;

  SceneSpec spec;
  spec.scene = SceneKind::Fusion;
  spec.seed = seed;
  spec.scene_params.n_cells = n;
  // The contact-implicit step at Δt 0.5 s, ε_CG 1e-2, the supplement's law.
  spec.numerics.integrator = IntegratorKind::ContactImplicit;
  spec.numerics.dt_s = 0.5;
  spec.numerics.cg_tol = 1e-2;
  spec.numerics.contact_law = ContactLawKind::Supplement;
  spec = resolve(spec);
  CellSet cells = buildFusionCells(spec, &cache);
  // A fusing aggregate: `relax_s` of those steps from the touching spheroids.
  Simulation run(spec, std::move(cells));
  while (run.time() < relax_s - 1e-9)
    if (!run.step().ok()) return std::fprintf(stderr, "the relaxation failed\n"), 3;
  std::printf(
      "# Motile velocity kept by one solve: 2 x %d cells, seed %llu, after %.0f s of "
      "draft steps\n\n",
      n, static_cast<unsigned long long>(seed), relax_s);

  SceneSpec passive = spec;
  passive.cells.p_a = 0;
  std::printf(
      "| Δt (s) | ε_CG | CG iterations | rms cell motile velocity (µm/min) | rms cell "
      "velocity error / rms motile | vertex velocity error / vertex motile |\n");
  std::printf("|---|---|---|---|---|---|\n");
  for (double dt : {0.1, 0.5}) {
    SceneSpec s = spec, s0 = passive;
    s.numerics.dt_s = s0.numerics.dt_s = dt;
    Simulation sim(s, run.cells()), bare(s0, run.cells());
    Eigen::Matrix3Xd f, f0;
    sim.computeForces(f);
    bare.computeForces(f0);
    const Eigen::VectorXd zero = Eigen::VectorXd::Zero(f.size());
    const Eigen::VectorXd v = solve(sim, f, zero, 1e-12), v0 = solve(bare, f0, zero, 1e-12);
    const Eigen::VectorXd act = v - v0;
    const Eigen::Matrix3Xd act_cells = cellVelocities(sim, act);
    std::printf("| %.1f | exact | — | %.4f | — | — |\n", dt, 60 * rms(act_cells));
    // The step's warm start is the last step's velocity.
    const Eigen::VectorXd warm =
        Eigen::Map<const Eigen::VectorXd>(run.cells().v.data(), run.cells().v.size());
    for (double tol : {1e-3, 1e-2}) {
      int iters = 0;
      const Eigen::VectorXd vt = solve(sim, f, warm, tol, &iters);
      const Eigen::Matrix3Xd err_cells = cellVelocities(sim, vt - v);
      std::printf("| %.1f | %.0e | %d | — | %.3f | %.3f |\n", dt, tol, iters,
                  rms(err_cells) / rms(act_cells), (vt - v).norm() / act.norm());
    }
  }
  return 0;
}
