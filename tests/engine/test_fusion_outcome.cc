// A fusion run's outcome (fused, arrested, separated, no-contact) and the rule that only fused
// and arrested trajectories are fitted: the classifier on trajectories of known
// shape, then on real small spheroids pulled apart, kept apart, and placed touching.
#include <cmath>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "activefoam/fusion_outcome.h"
#include "activefoam/observables.h"
#include "activefoam/run.h"
#include "activefoam/simulation.h"
#include "activefoam/spheroid.h"
#include "test_support.h"

using namespace activefoam;
using activefoam::testing::smallFusionSpec;

namespace {

constexpr double kCellR = 8;  // A_min = 0.01 π 8² ≈ 2.0 µm²

// θ(t) = θ_eq (1 − e^{−t/τ}) sampled every 10 s, in contact throughout, plus a deterministic
// wobble of amplitude `wobble` degrees (motility's fluctuations).
FusionTrajectory relaxing(double theta_eq, double tau, double t_end, double wobble = 0) {
  FusionTrajectory tr;
  for (double t = 0; t <= t_end + 1e-9; t += 10) {
    const double th = theta_eq * (1 - std::exp(-t / tau)) + 2 + wobble * std::sin(0.7 * t);
    tr.t_s.push_back(t);
    tr.theta_deg.push_back(th);
    tr.neck_um.push_back(20 * std::sin(th * M_PI / 180));
    tr.contact_area_um2.push_back(100 + 10 * th);
  }
  return tr;
}

// One sample of the series runScene records.
void record(FusionTrajectory& tr, double t, const Simulation& sim) {
  const FusionAngle fa = fusionAngle(sim.cells(), sim.contacts());
  tr.t_s.push_back(t);
  tr.theta_deg.push_back(fa.ok ? fa.theta_deg : std::nan(""));
  tr.neck_um.push_back(fa.ok ? fa.neck_radius_um : std::nan(""));
  tr.contact_area_um2.push_back(spheroidContactArea(sim.cells(), sim.contacts()));
}

void expectNotFitted(const std::vector<std::pair<std::string, FitResult>>& fits,
                     const std::string& outcome) {
  ASSERT_EQ(fits.size(), 3u);
  for (const auto& [model, f] : fits) {
    EXPECT_FALSE(f.ok) << model;
    EXPECT_NE(f.why.find("the outcome is " + outcome), std::string::npos) << model << ": " << f.why;
    EXPECT_FALSE(f.names.empty()) << model;
    for (double v : f.value) EXPECT_TRUE(std::isnan(v)) << model;
  }
}

}  // namespace

TEST(FusionOutcome, NamesAreTheDocumentedOnes) {
  EXPECT_EQ(toString(FusionOutcome::Fused), "fused");
  EXPECT_EQ(toString(FusionOutcome::Arrested), "arrested");
  EXPECT_EQ(toString(FusionOutcome::Separated), "separated");
  EXPECT_EQ(toString(FusionOutcome::NoContact), "no-contact");
}

TEST(FusionOutcome, StillRisingIsFusedAPlateauIsArrestedCompleteIsFused) {
  // Half-way through a relaxation of τ = 600 s: rising by ~5° over the last quarter.
  FusionClassification c = classifyFusion(relaxing(60, 600, 400), kCellR);
  EXPECT_EQ(c.outcome, FusionOutcome::Fused) << c.why;
  EXPECT_NE(c.why.find("still rising"), std::string::npos) << c.why;
  // Relaxed to 50° long ago, with ±1.5° fluctuations: arrested.
  c = classifyFusion(relaxing(50, 100, 3000, 1.5), kCellR);
  EXPECT_EQ(c.outcome, FusionOutcome::Arrested) << c.why;
  EXPECT_NE(c.why.find("no longer rising"), std::string::npos) << c.why;
  // Fluctuations of ±5° on a plateau are not a rise either.
  c = classifyFusion(relaxing(50, 100, 3000, 5), kCellR);
  EXPECT_EQ(c.outcome, FusionOutcome::Arrested) << c.why;
  // A plateau at 85°: complete fusion.
  c = classifyFusion(relaxing(83, 100, 3000, 1), kCellR);
  EXPECT_EQ(c.outcome, FusionOutcome::Fused) << c.why;
  EXPECT_NE(c.why.find("complete"), std::string::npos) << c.why;
  // Touching and never fusing perceptibly: arrested at a small angle.
  c = classifyFusion(relaxing(0.5, 100, 3000, 0.3), kCellR);
  EXPECT_EQ(c.outcome, FusionOutcome::Arrested) << c.why;
}

TEST(FusionOutcome, ContactLostIsSeparatedNeverTouchingIsNoContact) {
  FusionTrajectory tr = relaxing(40, 300, 600);
  // The last two samples: the contact area drops to nothing and the neck closes.
  for (std::size_t k = tr.t_s.size() - 2; k < tr.t_s.size(); ++k) {
    tr.contact_area_um2[k] = 0;
    tr.neck_um[k] = 0;
    tr.theta_deg[k] = 0;
  }
  FusionClassification c = classifyFusion(tr, kCellR);
  EXPECT_EQ(c.outcome, FusionOutcome::Separated) << c.why;
  EXPECT_FALSE(c.fitted());
  // A contact area below A_min (a sliver of one triangle) at the end counts as apart, too.
  tr.contact_area_um2.back() = 1.5;
  tr.neck_um.back() = 0.3;
  tr.theta_deg.back() = 1;
  EXPECT_EQ(classifyFusion(tr, kCellR).outcome, FusionOutcome::Separated);
  tr.contact_area_um2.back() = 2.5;
  EXPECT_NE(classifyFusion(tr, kCellR).outcome, FusionOutcome::Separated);

  for (auto& a : tr.contact_area_um2) a = 0;
  c = classifyFusion(tr, kCellR);
  EXPECT_EQ(c.outcome, FusionOutcome::NoContact) << c.why;
  EXPECT_FALSE(c.fitted());
  tr.contact_area_um2.pop_back();
  EXPECT_THROW(classifyFusion(tr, kCellR), std::invalid_argument);
}

TEST(FusionOutcome, OnlyFusedAndArrestedTrajectoriesAreFitted) {
  const FusionTrajectory tr = relaxing(60, 300, 1800);
  FusionClassification c = classifyFusion(tr, kCellR);
  ASSERT_TRUE(c.fitted()) << c.why;
  const auto fits = fusionFits(tr, c, 50);
  ASSERT_EQ(fits[0].first, "eq1");
  ASSERT_TRUE(fits[0].second.ok) << fits[0].second.why;
  EXPECT_NEAR(fits[0].second.get("theta_eq_deg"), 62, 0.01);
  EXPECT_NEAR(fits[0].second.get("tau_f_s"), 300, 0.5);
  // The same data, judged separated: nothing is fitted.
  c.outcome = FusionOutcome::Separated;
  expectNotFitted(fusionFits(tr, c, 50), "separated");
}

// Two real spheroids placed touching, sampled for 6 s, then spheroid B moved 4 µm away (a
// forced separation) and sampled for 4 s more: separated, and no fit.
TEST(FusionOutcome, SpheroidsPulledApartAreSeparatedAndNotFitted) {
  const SceneSpec s = smallFusionSpec();
  CellSet cells = buildFusionCells(s, nullptr);
  FusionTrajectory tr;
  Simulation sim(s, cells);
  record(tr, 0, sim);
  for (int k = 1; k <= 12; ++k) {
    ASSERT_TRUE(sim.step().ok());
    if (k % 2 == 0) record(tr, 0.5 * k, sim);
  }
  const FusionClassification touching = classifyFusion(tr, s.cells.radius_mean_um);
  EXPECT_TRUE(touching.fitted()) << toString(touching.outcome) << ": " << touching.why;

  CellSet apart = sim.cells();
  for (Eigen::Index v = 0; v < apart.x.cols(); ++v)
    if (apart.label[apart.vertex_cell[v]] == 1) apart.x(0, v) += 4;
  Simulation sim2(s, apart);
  for (int k = 1; k <= 8; ++k) {
    ASSERT_TRUE(sim2.step().ok());
    if (k % 2 == 0) record(tr, 6 + 0.5 * k, sim2);
  }
  EXPECT_EQ(tr.contact_area_um2.back(), 0);
  const FusionClassification c = classifyFusion(tr, s.cells.radius_mean_um);
  EXPECT_EQ(c.outcome, FusionOutcome::Separated) << c.why;
  expectNotFitted(fusionFits(tr, c, 20), "separated");
}

// Placed 3 µm apart (beyond any adhesion range): the whole run is no-contact, the summary
// says so and carries no fit; placed touching, the same spheroids are fitted.
TEST(FusionOutcome, RunSceneReportsNoContactWithoutFits) {
  SceneSpec s = smallFusionSpec();
  s.duration_s = 4;
  const SceneSpec touching = s;
  s.scene_params.gap_um = 3.0;
  const RunSummary far = runScene(s, {});
  ASSERT_TRUE(far.ok()) << far.reason;
  EXPECT_EQ(far.outcome, "no-contact") << far.outcome_why;
  expectNotFitted(far.fits, "no-contact");
  double area = -1;
  for (const auto& [name, v] : far.final_values)
    if (name == "contact_area_ab_um2") area = v;
  EXPECT_EQ(area, 0);

  const RunSummary near = runScene(touching, {});
  ASSERT_TRUE(near.ok()) << near.reason;
  EXPECT_TRUE(near.outcome == "fused" || near.outcome == "arrested") << near.outcome;
  EXPECT_TRUE(near.fits[0].second.why.find("outcome") == std::string::npos);

  SceneSpec cell;
  cell.scene = SceneKind::Cell;
  cell.numerics.triangles_per_cell = 80;
  cell.duration_s = 1;
  const RunSummary one = runScene(resolve(cell), {});
  ASSERT_TRUE(one.ok()) << one.reason;
  EXPECT_TRUE(one.outcome.empty()) << "a single cell has no fusion outcome";
  EXPECT_TRUE(one.fits.empty());
}
