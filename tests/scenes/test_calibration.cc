// The supplement's calibration of the model (its Fig. 7E): passive doublets of equal cells
// settle at the Young–Dupré contact angle θ_c = arccos α, here for α ∈ {0.15, 0.3, 0.6, 0.9}
// within 1.5° at `standard` (the default numerics). Measured at the one-spring contact-implicit
// step, Δt 0.1 s, ε_CG 1e-3, the supplement's law (`foam-run examples/doublet.toml --set
// cells.alpha=A --set duration_s=7000` with those numerics keys): 81.8, 73.0, 53.8 and 27.08°
// against 81.37, 72.54, 53.13 and 25.84° — the error grows as the junction shrinks (fewer
// triangles span it). At α = 0.9 the first contact takes ~2500 s to zip open (θ_c ≈ 4° until
// then) and settles by ~4000 s; the durations below leave each case ≥ 500 s at its equilibrium.
#include <algorithm>
#include <cmath>
#include <iostream>
#include <utility>
#include <vector>

#include <gtest/gtest.h>

#include "activefoam/doublet_study.h"
#include "activefoam/observables.h"
#include "activefoam/simulation.h"
#include "activefoam/spec.h"

using namespace activefoam;

namespace {

struct Case {
  double alpha, duration_s;
};
void PrintTo(const Case& c, std::ostream* os) {
  *os << "α = " << c.alpha << ", " << c.duration_s << " s";
}

class PassiveDoublet : public ::testing::TestWithParam<Case> {};

}  // namespace

TEST_P(PassiveDoublet, ContactAngleIsArccosAlphaAtStandard) {
  const Case c = GetParam();
  SceneSpec s;
  s.scene = SceneKind::Doublet;
  s.cells.radius_gamma_k = 0;  // equal cells: the angle compares with arccos α directly
  s.cells.p_a = 0;
  s.cells.alpha = c.alpha;  // the gap: its default, inside the adhesion range at every α
  ASSERT_TRUE(validate(s).empty());
  ASSERT_TRUE(silentlyWrong(s).empty());
  const DoubletEquilibrium e = measureDoubletEquilibrium(resolve(s), c.duration_s, 300);
  ASSERT_TRUE(e.failure.empty()) << e.reason;
  const double target = std::acos(c.alpha) * 180 / M_PI;
  std::cout << "[ calibration ] α = " << c.alpha << ": θ_c = " << e.theta_c_deg
            << "°, arccos α = " << target << "° (" << e.wall_s << " s)\n";
  EXPECT_NEAR(e.theta_c_deg, target, 1.5);
  // At equilibrium, not passing through: the angle 300 s before the end is the same. Means over
  // 60 s, not single samples: a remesh moves the angle of the nearly flat α = 0.15 contact by
  // ±0.3° for a few samples (81.2–81.9° over its last 400 s, with either smoothing), and one
  // sample on such a dip failed the test where the means differ by 0.09°.
  const auto& series = e.theta_c_series_deg;  // every 5 s
  ASSERT_GT(series.size(), 72u);
  const auto mean = [&](std::size_t from, std::size_t to) {
    double sum = 0;
    for (std::size_t i = from; i < to; ++i) sum += series[i];
    return sum / static_cast<double>(to - from);
  };
  const std::size_t n = series.size();
  EXPECT_NEAR(mean(n - 12, n), mean(n - 72, n - 60), 0.3);
  EXPECT_LT(e.volume_error_max, 0.01);
}

INSTANTIATE_TEST_SUITE_P(Alphas, PassiveDoublet,
                         ::testing::Values(Case{0.15, 800}, Case{0.3, 800}, Case{0.6, 1500},
                                           Case{0.9, 4500}),
                         [](const ::testing::TestParamInfo<Case>& i) {
                           return "alpha_" + std::to_string(static_cast<int>(i.param.alpha * 100));
                         });

// Spheroids (the supplement's Fig. 7E): the surface contact angle between neighbouring surface
// cells (`surfaceContactAngle`) of an aggregate of N = 20 cells. Measured (docs/validation.md,
// docs/validation/validation_spheroids.sh: N = 20 and 30, three seeds, the contact-implicit step at
// Δt 0.5 s): passive aggregates settle within 0.6° of arccos α at α = 0.3 … 0.9 (the bound is 3°);
// motile ones (the default p_a) sit 3.3–5.6° below it at every α — the protrusions keep the
// junctions from their passive balance (−1.6° at half p_a, −11.5° at double), a property of the
// active model rather than of the measure. α = 0.9 opens its junctions slowly (≈ 3000 s passive).
namespace {

struct SpheroidCase {
  double alpha, p_a, duration_s;
};
void PrintTo(const SpheroidCase& c, std::ostream* os) {
  *os << "α = " << c.alpha << ", p_a = " << c.p_a << " kPa, " << c.duration_s << " s";
}

struct SpheroidAngle {
  double last_deg = 0, before_deg = 0;  // mean over the last 500 s, and the 500 s before
  double volume_error_max = 0;          // over the last 1000 s
};

// The surface angle every 50 s of a 20-cell spheroid (seed 1), averaged over windows.
SpheroidAngle relaxSpheroid(const SpheroidCase& c) {
  SceneSpec s;
  s.scene = SceneKind::Spheroid;
  s.seed = 1;
  s.scene_params.n_cells = 20;
  s.cells.alpha = c.alpha;
  s.cells.p_a = c.p_a;
  // The step the calibration was measured at: contact-implicit, Δt 0.5 s, ε_CG 1e-2, the
  // supplement's law.
  s.numerics.integrator = IntegratorKind::ContactImplicit;
  s.numerics.dt_s = 0.5;
  s.numerics.cg_tol = 1e-2;
  s.numerics.contact_law = ContactLawKind::Supplement;
  EXPECT_TRUE(validate(s).empty());
  Simulation sim(resolve(s));
  std::vector<std::pair<double, double>> series;  // (t, θ)
  SpheroidAngle out;
  for (double next = 50; next <= c.duration_s + 1e-9; next += 50) {
    while (sim.time() < next - 1e-9) {
      const StepReport r = sim.step();
      EXPECT_TRUE(r.ok()) << r.reason;
      if (!r.ok()) return out;
      if (sim.time() <= c.duration_s - 1000) continue;  // the packed start squeezes cells
      for (int k = 0; k < sim.cells().numCells(); ++k)
        out.volume_error_max =
            std::max(out.volume_error_max,
                     std::abs(sim.geometry().cell_volume[k] - sim.cells().target_volume[k]) /
                         sim.cells().target_volume[k]);
    }
    const SurfaceContactAngle a = surfaceContactAngle(sim.cells(), sim.contacts());
    EXPECT_TRUE(a.ok) << a.why;
    series.emplace_back(sim.time(), a.theta_deg);
  }
  auto mean = [&](double from, double to) {
    double sum = 0;
    int n = 0;
    for (const auto& [t, th] : series)
      if (t > from + 1e-9 && t <= to + 1e-9) sum += th, ++n;
    return n ? sum / n : std::nan("");
  };
  out.last_deg = mean(c.duration_s - 500, c.duration_s);
  out.before_deg = mean(c.duration_s - 1000, c.duration_s - 500);
  return out;
}

class PassiveSpheroid : public ::testing::TestWithParam<SpheroidCase> {};

}  // namespace

TEST_P(PassiveSpheroid, SurfaceContactAngleIsArccosAlpha) {
  const SpheroidCase c = GetParam();
  const SpheroidAngle a = relaxSpheroid(c);
  const double target = std::acos(c.alpha) * 180 / M_PI;
  std::cout << "[ calibration ] spheroid α = " << c.alpha << ": θ_c = " << a.last_deg
            << "° (500 s before: " << a.before_deg << "°), arccos α = " << target << "°\n";
  EXPECT_NEAR(a.last_deg, target, 3.0);        // the bound; measured ≤ 0.6°
  EXPECT_NEAR(a.last_deg, a.before_deg, 1.0);  // settled, not passing through
  EXPECT_LT(a.volume_error_max, 0.01);
}

INSTANTIATE_TEST_SUITE_P(Alphas, PassiveSpheroid,
                         ::testing::Values(SpheroidCase{0.3, 0, 1500}, SpheroidCase{0.6, 0, 1500},
                                           SpheroidCase{0.9, 0, 4000}),
                         [](const ::testing::TestParamInfo<SpheroidCase>& i) {
                           return "alpha_" + std::to_string(static_cast<int>(i.param.alpha * 100));
                         });

// The motile aggregate's offset, pinned to the documented measurement (docs/validation.md):
// below arccos α by 3.3–5.6° over seeds and N; a change of the motility or of the measure that
// moves it out of [2°, 7°] must update that page.
TEST(MotileSpheroid, SurfaceContactAngleSitsBelowArccosAlphaAsDocumented) {
  const SpheroidCase c{0.6, CellParams{}.p_a, 3000};
  const SpheroidAngle a = relaxSpheroid(c);
  const double target = std::acos(c.alpha) * 180 / M_PI;
  std::cout << "[ calibration ] motile spheroid α = " << c.alpha << ": θ_c = " << a.last_deg
            << "° (500 s before: " << a.before_deg << "°), arccos α = " << target << "°\n";
  EXPECT_GT(target - a.last_deg, 2.0);
  EXPECT_LT(target - a.last_deg, 7.0);
}
