// The quick version of the speed/accuracy study (the full one is
// docs/study/): the orderings the study relies on, measured on the doublet
// against a finer reference (Δt = 0.025 s, ε_CG = 1e-6) — the equilibrium contact angle θ_c, and
// the θ_c(t) trajectory on the way there.
#include <algorithm>
#include <cmath>
#include <iostream>

#include <gtest/gtest.h>

#include "activefoam/doublet_study.h"

using namespace activefoam;

namespace {

// Measured noise floors (docs/study/doublet.md): θ_c at equilibrium jitters by ~0.2° with
// remeshing; the trajectory's RMS error by ~1° with the timing of the first contacts (discrete
// events: which vertex pair closes the gap first). "Never larger" is judged beyond them.
constexpr double kEquilibriumNoiseDeg = 0.25;
constexpr double kTrajectoryNoiseDeg = 1.0;

struct Errors {
  double equilibrium, trajectory_rms;
};

class AccuracyStudy : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    NumericsParams n;
    n.dt_s = 0.025;
    n.cg_tol = 1e-6;
    reference_ = new DoubletEquilibrium(run(n));
  }
  static void TearDownTestSuite() { delete reference_; }

  static DoubletEquilibrium run(NumericsParams n) {
    n.cg_max_iter = 100000;
    const DoubletEquilibrium e = measureDoubletEquilibrium(doubletStudySpec(n));
    std::cout << "[ study    ] Δt " << n.dt_s << " s, " << n.triangles_per_cell << " triangles, ε "
              << n.cg_tol << ", " << toString(n.contact_quadrature) << ": θ_c = " << e.theta_c_deg
              << "° (" << e.wall_s << " s)" << (e.failure.empty() ? "" : " " + e.failure) << "\n";
    return e;
  }

  static Errors errors(const NumericsParams& n) {
    const DoubletEquilibrium e = run(n);
    EXPECT_TRUE(e.failure.empty()) << e.reason;
    const auto& a = reference_->theta_c_series_deg;
    const auto& b = e.theta_c_series_deg;
    const std::size_t m = std::min(a.size(), b.size());
    double ss = 0;
    for (std::size_t k = 0; k < m; ++k) ss += (a[k] - b[k]) * (a[k] - b[k]);
    const Errors err{std::abs(e.theta_c_deg - reference_->theta_c_deg),
                     m ? std::sqrt(ss / static_cast<double>(m)) : 1e9};
    std::cout << "[ study    ]   error: equilibrium " << err.equilibrium << "°, θ_c(t) RMS "
              << err.trajectory_rms << "°\n";
    return err;
  }

  // `finer` is not less accurate than `coarser`, beyond the noise floors.
  static void expectNoWorse(const Errors& finer, const Errors& coarser, const char* what) {
    EXPECT_LE(finer.equilibrium, coarser.equilibrium + kEquilibriumNoiseDeg) << what;
    EXPECT_LE(finer.trajectory_rms, coarser.trajectory_rms + kTrajectoryNoiseDeg) << what;
  }

  static DoubletEquilibrium* reference_;
};

DoubletEquilibrium* AccuracyStudy::reference_ = nullptr;

NumericsParams with(void (*set)(NumericsParams&)) {
  NumericsParams n;
  set(n);
  return n;
}

}  // namespace

TEST_F(AccuracyStudy, TheReferenceReachesArccosAlpha) {
  ASSERT_TRUE(reference_->failure.empty()) << reference_->reason;
  EXPECT_NEAR(reference_->theta_c_deg, std::acos(CellParams{}.alpha) * 180 / M_PI, 1.0);
}

TEST_F(AccuracyStudy, SmallerTimeStepsAreNeverLessAccurate) {
  const Errors e005 = errors(with([](NumericsParams& n) { n.dt_s = 0.05; }));
  const Errors e05 = errors(with([](NumericsParams& n) { n.dt_s = 0.5; }));
  const Errors e1 = errors(with([](NumericsParams& n) { n.dt_s = 1.0; }));
  expectNoWorse(e005, e05, "Δt 0.05 vs 0.5 s");
  expectNoWorse(e05, e1, "Δt 0.5 vs 1 s");
  EXPECT_GT(e1.trajectory_rms, e005.trajectory_rms);  // the study's clearest trend
}

TEST_F(AccuracyStudy, FinerMeshesTighterTolerancesAndExactQuadratureAreNeverLessAccurate) {
  const Errors standard = errors(NumericsParams{});
  const Errors coarse = errors(with([](NumericsParams& n) { n.triangles_per_cell = 80; }));
  expectNoWorse(standard, coarse, "320 vs 80 triangles");
  // 80 triangles reach the junction too, but ~600 s later: far off on the way.
  EXPECT_GT(coarse.trajectory_rms, standard.trajectory_rms + 5);

  const Errors tight = errors(with([](NumericsParams& n) { n.cg_tol = 1e-6; }));
  const Errors loose = errors(with([](NumericsParams& n) { n.cg_tol = 1e-2; }));
  expectNoWorse(tight, loose, "ε_CG 1e-6 vs 1e-2");

  const Errors d7 =
      errors(with([](NumericsParams& n) { n.contact_quadrature = ContactQuadrature::Dunavant7; }));
  const Errors centroid =
      errors(with([](NumericsParams& n) { n.contact_quadrature = ContactQuadrature::Centroid; }));
  expectNoWorse(standard, d7, "exact vs 7-point quadrature");
  expectNoWorse(d7, centroid, "7-point vs centroid quadrature");
}
