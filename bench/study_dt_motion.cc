// Does the cells' motion converge in Δt? The preset-fitness study (docs/science/presets.md) found
// that the contact-implicit step at Δt 0.5 s moves the cells of a fusing 2 × 20 aggregate 2.5–3×
// less than at Δt 0.1 s over 4 h. Ensembles over hours mix discretisation with the motility's
// chaos; this driver separates them. Every configuration starts from the same prepared
// aggregate and is driven by the same polarity noise (one Wiener path per cell, a function of
// time, not of the steps), so over a short run two configurations differ mostly by their
// discretisation, not by independent realisations of the motility. Per configuration and sample
// time it prints the MSRD from the first sample (pairs in contact at t = 0), the normalised unique
// contacts, the RMS distance of the cell centroids from the first configuration's at the same time
// (the reference: list the finest first), the mean Δt taken and the wall time.
//
//   OMP_NUM_THREADS=1 build/release/bench/study_dt_motion CACHE_DIR n_cells seed T_s sample_s
//       integrator:Δt:preconditioner[:ε_CG][,…] [key=value …]
//
// integrator: any of numerics.integrator, or ros2-centroid (ros2 with contact-implicit's
// spring in W).
//
// key=value pairs set spec fields of the scene for every configuration, as foam-run's --set does
// (e.g. cells.k_contact=20).
// CACHE_DIR keeps the prepared spheroids (as foam-run --spheroid-cache); the scene is the
// reduced base point's (Table 1/2 parameters, p_a r/2γ = 0.33).
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <sstream>
#include <string>
#include <vector>

#include "activefoam/observables.h"
#include "activefoam/simulation.h"
#include "activefoam/spec_io.h"
#include "activefoam/spheroid.h"
#include "base_point.h"
#include "scheme_config.h"

using namespace activefoam;

int main(int argc, char** argv) {
  if (argc < 7) {
    std::fprintf(stderr,
                 "usage: study_dt_motion CACHE_DIR n_cells seed T_s sample_s "
                 "integrator:dt:preconditioner[:cg_tol][,...] [key=value ...]\n");
    return 2;
  }
  const auto point = bench::basePoint(argc, argv, 7);
  if (!point) return 2;
  const double duration = point->duration_s, every = point->sample_s;
  const SceneSpec& base = point->resolved;
  const CellSet& cells = point->cells;

  std::vector<std::string> configs;
  std::stringstream list(argv[6]);
  for (std::string item; std::getline(list, item, ',');) configs.push_back(item);

  std::vector<std::vector<Vec3>> reference;  // the first configuration's centroids per sample
  std::printf("config,t_s,msrd_um2,unique_contacts,rms_from_first_um,mean_dt_s,rejected,wall_s\n");
  for (const std::string& config : configs) {
    SceneSpec s = base;
    bench::SchemeConfig scheme;
    if (const std::string error = bench::applySchemeConfig(config, s, scheme); !error.empty()) {
      std::fprintf(stderr, "%s: %s\n", config.c_str(), error.c_str());
      return 2;
    }
    s = resolve(s);
    Simulation sim(s, cells, scheme.scheme(s));
    MsrdTracker msrd;
    ContactHistory history;
    const auto t0 = std::chrono::steady_clock::now();
    const bool first = reference.empty();
    int k = 0;
    auto sample = [&] {
      const std::vector<Vec3>& x = sim.geometry().cell_centroid;
      msrd.addSample(sim.time(), sim.cells(), sim.geometry(), sim.contacts());
      history.add(sim.cells(), sim.contacts());
      double dev = 0;
      if (first) {
        reference.push_back(x);
      } else if (k < static_cast<int>(reference.size())) {
        for (std::size_t c = 0; c < x.size(); ++c) dev += (x[c] - reference[k][c]).squaredNorm();
        dev = std::sqrt(dev / static_cast<double>(x.size()));
      } else {
        dev = NAN;
      }
      const double wall =
          std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
      std::printf("%s,%g,%.6g,%.6g,%.6g,%.6g,%lld,%.1f\n", config.c_str(), sim.time(), msrd.msrd(k),
                  history.normalized(), dev,
                  sim.steps() ? sim.time() / static_cast<double>(sim.steps()) : 0.0,
                  static_cast<long long>(sim.stepsRejected()), wall);
      std::fflush(stdout);
      ++k;
    };
    sim.detect();
    sample();
    while (sim.time() < duration - 1e-9) {
      const StepReport r = sim.step();
      if (!r.ok()) {
        std::fprintf(stderr, "%s: failed at t = %g s: %s\n", config.c_str(), sim.time(),
                     std::string(toString(r.failure)).c_str());
        break;
      }
      if (sim.time() + 1e-9 >= (k)*every) sample();
    }
  }
  return 0;
}
