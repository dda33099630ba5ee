// The supplement's calibration of the model (its Fig. 7E): passive doublets of equal cells
// settle at the Young–Dupré contact angle θ_c = arccos α. Issue 16 asks for α ∈ {0.15, 0.3,
// 0.6, 0.9} within 1.5° at `standard` (the default numerics). Measured 2026-11-24
// (`foam-run examples/doublet.toml --set cells.alpha=A --set duration_s=7000`): 81.8, 73.0,
// 53.8 and 27.08° against 81.37, 72.54, 53.13 and 25.84° — the error grows as the junction
// shrinks (fewer triangles span it). At α = 0.9 the first contact takes ~2500 s to zip open
// (θ_c ≈ 4° until then) and settles by ~4000 s; the durations below leave each case ≥ 500 s
// at its equilibrium.
#include <cmath>
#include <iostream>

#include <gtest/gtest.h>

#include "activefoam/doublet_study.h"

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
  // At equilibrium, not passing through: the angle 300 s before the end is the same.
  const auto& series = e.theta_c_series_deg;  // every 5 s
  ASSERT_GT(series.size(), 60u);
  EXPECT_NEAR(series.back(), series[series.size() - 61], 0.3);
  EXPECT_LT(e.volume_error_max, 0.01);
}

INSTANTIATE_TEST_SUITE_P(Alphas, PassiveDoublet,
                         ::testing::Values(Case{0.15, 800}, Case{0.3, 800}, Case{0.6, 1500},
                                           Case{0.9, 4500}),
                         [](const ::testing::TestParamInfo<Case>& i) {
                           return "alpha_" + std::to_string(static_cast<int>(i.param.alpha * 100));
                         });
