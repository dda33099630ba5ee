// Why does the shape index rise with cell–cell friction? The supplement's Fig. 14E has it fall
// weakly with friction; in ours (fig14-reduced at α 0.75) it rises, by 0.6 % from L_η/r 2 to
// 0.25, and the gap is there from the first minutes (docs/science/fig14-friction/, §6). This
// driver takes the question apart:
//   - the preparation against the run: the aggregate is prepared once, at the key=value
//     settings' L_η/r; every configuration then runs from it with its own L_η/r and the same
//     polarity noise (one Wiener path per cell, a function of time); invocations with the
//     preparation at different L_η/r cross the preparation with the run;
//   - where on the cells: the shape index S/V^{2/3} of the raw mesh, of the mesh smoothed at the
//     vertex scale (Taubin λ|μ, four passes: ripples of a few edges removed, the cell's shape
//     kept), so that raw − smoothed is the vertex-scale roughness's share; and each cell's
//     elongation, the square root of its largest over smallest second moment (cell scale);
//   - which cells: with STUDY_SHAPE_CELLS=FILE set, each cell's values go to FILE as well, with
//     its contact fraction (its contacts' area over its surface: how buried it is).
// Per configuration and sample it prints the means over cells, the mean contact fraction, the
// fusion angle and the step count.
//
//   OMP_NUM_THREADS=1 build/release/bench/study_shape CACHE_DIR n_cells seed T_s sample_s
//       integrator:Δt:preconditioner[:ε_CG] l_eta_1[:key=value…][,l_eta_2…] [key=value …]
//
// The key=value settings at the end apply to every configuration and to the preparation; those
// after a configuration's L_η/r to it alone (0.25:cells.pa_reduced=0), the aggregate unchanged.
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <optional>
#include <string>
#include <vector>

#include "activefoam/geometry.h"
#include "activefoam/observables.h"
#include "activefoam/probe.h"
#include "activefoam/simulation.h"
#include "activefoam/spec_io.h"
#include "activefoam/spheroid.h"
#include "base_point.h"
#include "scheme_config.h"

using namespace activefoam;

namespace {}  // namespace

int main(int argc, char** argv) {
  const auto driver = bench::configDriver(argc, argv, "study_shape");
  if (!driver) return 2;
  const bench::BasePoint* point = &driver->point;
  const std::vector<bench::Config>& configs = driver->configs;

  std::printf(
      "config,prep_l_eta_reduced,l_eta_reduced,t_s,theta_deg,q,q_smooth,elong,contact_fraction,"
      "steps,wall_s\n");
  std::FILE* per_cell = nullptr;
  if (const char* path = std::getenv("STUDY_SHAPE_CELLS")) {
    per_cell = std::fopen(path, "w");
    if (!per_cell) {
      std::fprintf(stderr, "STUDY_SHAPE_CELLS: cannot write %s\n", path);
      return 2;
    }
    std::fprintf(per_cell, "config,t_s,cell,label,q,q_smooth,elong,contact_fraction\n");
  }
  for (const bench::Config& config : configs) {
    bench::SchemeConfig scheme;
    const std::optional<SceneSpec> resolved =
        bench::configSpec(*point, config, driver->step, scheme);
    if (!resolved) return 2;
    const SceneSpec& s = *resolved;
    Simulation sim(s, point->cells, scheme.scheme(s));
    const auto t0 = std::chrono::steady_clock::now();
    long steps = 0;
    int k = 0;
    auto sample = [&]() {
      sim.detect();
      const CellSet& c = sim.cells();
      const Geometry& g = sim.geometry();
      const ContactList& con = sim.contacts();
      const int nc = c.numCells();
      std::vector<double> contact_area(nc, 0.0);
      for (const ContactPair& p : con.pairs) {
        contact_area[c.tri_cell[p.ta]] += p.c.area;
        contact_area[c.tri_cell[p.tb]] += p.c.area;
      }
      Topology topo;
      updateTopology(c, topo);
      const CellSet cs = taubinSmoothed(c, topo, 4);  // the observe.shape probe's
      Geometry gs;
      computeGeometry(cs, gs);
      double q_sum = 0, qs_sum = 0, el_sum = 0, fraction = 0;
      for (int cell = 0; cell < nc; ++cell) {
        const double q = shapeIndex(g, cell), qs = shapeIndex(gs, cell);
        const double el = surfaceElongation(c, g, cell);  // the observe.shape probe's
        const double f = std::min(1.0, contact_area[cell] / g.cell_area[cell]);
        fraction += f;
        if (per_cell)
          std::fprintf(per_cell, "%s,%g,%d,%d,%.6f,%.6f,%.6f,%.5f\n", config.label.c_str(),
                       sim.time(), cell, c.label[cell], q, qs, el, f);
        q_sum += q;
        qs_sum += qs;
        el_sum += el;
      }
      const FusionAngle angle = fusionAngle(c, con);
      const double wall =
          std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
      std::printf("%s,%g,%g,%g,%.4f,%.6f,%.6f,%.6f,%.5f,%ld,%.1f\n", config.label.c_str(),
                  point->spec.cells.l_eta_reduced.value_or(std::nan("")), config.l_eta, sim.time(),
                  angle.ok ? angle.theta_deg : std::nan(""), q_sum / nc, qs_sum / nc, el_sum / nc,
                  fraction / nc, steps, wall);
      std::fflush(stdout);
      ++k;
    };
    sample();
    while (sim.time() < point->duration_s - 1e-9) {
      const StepReport r = sim.step();
      ++steps;
      if (!r.ok()) {
        std::fprintf(stderr, "%s: failed at t = %g s: %s\n", config.label.c_str(), sim.time(),
                     std::string(toString(r.failure)).c_str());
        break;
      }
      if (sim.time() + 1e-9 >= k * point->sample_s) sample();
    }
  }
  if (per_cell) std::fclose(per_cell);
  return 0;
}
