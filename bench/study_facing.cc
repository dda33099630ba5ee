// The contact law (numerics.contact_law) on the supplement's
// calibration: passive doublets of equal cells settle at θ_c = arccos α (Fig. 7E;
// docs/validation.md). A variant that clips pairs acts on oblique ones; at a junction those are
// the pairs at its rim, which is where the doublet's angle is read, so this is where a variant
// would bias the calibration if it did.
//
// Same scene, numerics (`standard`) and durations as the test
// Alphas/PassiveDoublet.ContactAngleIsArccosAlphaAtStandard; one row per (α, law):
//   OMP_NUM_THREADS=1 build/release/bench/study_facing [90 | prisms | overlap ...]
//                                                     (default: all three)
// `90`: the supplement's law; `prisms`: "prisms", the contact polygon kept where the triangles
// overlie each other; `overlap`: "prisms-overlap" (only the polygon's overlapping part, g < 0,
// bounded).
// Prints a Markdown table (θ_c, its error against arccos α and the change from 90°, the
// largest volume error, the wall time). ~3 min per φ on one core.
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <map>
#include <string>
#include <vector>

#include "activefoam/doublet_study.h"
#include "activefoam/simulation.h"
#include "activefoam/spec.h"

using namespace activefoam;

int main(int argc, char** argv) {
  std::vector<std::string> laws;
  for (int i = 1; i < argc; ++i) laws.emplace_back(argv[i]);
  if (laws.empty()) laws = {"90", "prisms", "overlap"};
  struct Case {
    double alpha, duration_s;
  };
  const std::vector<Case> cases = {{0.15, 800}, {0.3, 800}, {0.6, 1500}, {0.9, 4500}};
  std::printf("| α | arccos α | law | θ_c | error | change from 90° | volume error max | wall |\n");
  std::printf("|---|---|---|---|---|---|---|---|\n");
  std::map<double, double> at90;
  for (const Case& c : cases) {
    for (const std::string& law : laws) {
      const bool overlap = law == "overlap";
      const bool prisms = law == "prisms" || overlap;
      if (!prisms && std::atof(law.c_str()) != 90) {
        std::fprintf(stderr, "the facing bound is retired: give 90, prisms or overlap\n");
        return 2;
      }
      SceneSpec s;
      s.scene = SceneKind::Doublet;
      s.cells.radius_gamma_k = 0;
      s.cells.p_a = 0;
      s.cells.alpha = c.alpha;
      s.numerics.contact_law = overlap  ? ContactLawKind::PrismsOverlap
                               : prisms ? ContactLawKind::Prisms
                                        : ContactLawKind::Supplement;
      if (!validate(s).empty()) {
        std::fprintf(stderr, "invalid spec at α = %g, %s\n", c.alpha, law.c_str());
        return 2;
      }
      const DoubletEquilibrium e = measureDoubletEquilibrium(resolve(s), c.duration_s, 300);
      const double target = std::acos(c.alpha) * 180 / M_PI;
      if (!e.failure.empty()) {
        std::printf("| %g | %.2f° | %s | failed: %s | | | | |\n", c.alpha, target, law.c_str(),
                    e.failure.c_str());
        continue;
      }
      const bool plain = !prisms;
      if (plain) at90[c.alpha] = e.theta_c_deg;
      char change[32] = "";
      if (at90.count(c.alpha) && !plain)
        std::snprintf(change, sizeof change, "%+.2f°", e.theta_c_deg - at90[c.alpha]);
      std::printf("| %g | %.2f° | %s | %.2f° | %+.2f° | %s | %.3f %% | %.0f s |\n", c.alpha, target,
                  prisms ? law.c_str() : (law + "°").c_str(), e.theta_c_deg, e.theta_c_deg - target,
                  change, 100 * e.volume_error_max, e.wall_s);
      std::fflush(stdout);
    }
  }
}
