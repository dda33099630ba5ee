// The contact law's facing bound (numerics.contact_max_facing_deg) on the supplement's
// calibration: passive doublets of equal cells settle at θ_c = arccos α (Fig. 7E;
// docs/validation.md). The bound drops triangle pairs whose normals are more than φ from
// antiparallel; at a junction those are the pairs at its rim, which is where the doublet's angle
// is read, so this is where a bound would bias the calibration if it did.
//
// Same scene, numerics (`standard`) and durations as the test
// Alphas/PassiveDoublet.ContactAngleIsArccosAlphaAtStandard; one row per (α, φ):
//   OMP_NUM_THREADS=1 build/release/bench/study_facing [φ...]     (default φ: 90 75 60 45)
// Prints a Markdown table (θ_c, its error against arccos α and the change from 90°, the
// largest volume error, the wall time). ~3 min per φ on one core.
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <map>
#include <vector>

#include "activefoam/doublet_study.h"
#include "activefoam/simulation.h"
#include "activefoam/spec.h"

using namespace activefoam;

int main(int argc, char** argv) {
  std::vector<double> phis;
  for (int i = 1; i < argc; ++i) phis.push_back(std::atof(argv[i]));
  if (phis.empty()) phis = {90, 75, 60, 45};
  struct Case {
    double alpha, duration_s;
  };
  const std::vector<Case> cases = {{0.15, 800}, {0.3, 800}, {0.6, 1500}, {0.9, 4500}};
  std::printf("| α | arccos α | φ | θ_c | error | change from 90° | volume error max | wall |\n");
  std::printf("|---|---|---|---|---|---|---|---|\n");
  std::map<double, double> at90;
  for (const Case& c : cases) {
    for (double phi : phis) {
      SceneSpec s;
      s.scene = SceneKind::Doublet;
      s.cells.radius_gamma_k = 0;
      s.cells.p_a = 0;
      s.cells.alpha = c.alpha;
      s.numerics.contact_max_facing_deg = phi;
      if (!validate(s).empty()) {
        std::fprintf(stderr, "invalid spec at α = %g, φ = %g\n", c.alpha, phi);
        return 2;
      }
      const DoubletEquilibrium e = measureDoubletEquilibrium(resolve(s), c.duration_s, 300);
      const double target = std::acos(c.alpha) * 180 / M_PI;
      if (!e.failure.empty()) {
        std::printf("| %g | %.2f° | %g° | failed: %s | | | | |\n", c.alpha, target, phi,
                    e.failure.c_str());
        continue;
      }
      if (phi == 90) at90[c.alpha] = e.theta_c_deg;
      char change[32] = "";
      if (at90.count(c.alpha) && phi != 90)
        std::snprintf(change, sizeof change, "%+.2f°", e.theta_c_deg - at90[c.alpha]);
      std::printf("| %g | %.2f° | %g° | %.2f° | %+.2f° | %s | %.3f %% | %.0f s |\n", c.alpha,
                  target, phi, e.theta_c_deg, e.theta_c_deg - target, change,
                  100 * e.volume_error_max, e.wall_s);
      std::fflush(stdout);
    }
  }
}
