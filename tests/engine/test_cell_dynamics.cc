// A single cell in time: rest state, relaxation of an ellipsoid, reproducibility.
#include <cmath>
#include <cstring>
#include <iostream>

#include <gtest/gtest.h>

#include <Eigen/Eigenvalues>

#include "test_support.h"

using namespace activefoam;
using activefoam::testing::cellSpec;

namespace {

double aspect(const Simulation& sim) {
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es(cellCovariance(sim.cells(), 0));
  return std::sqrt(es.eigenvalues()(2) / es.eigenvalues()(0));
}

double volumeError(const Simulation& sim) {
  const double vs = sim.cells().target_volume[0];
  return (sim.geometry().cell_volume[0] - vs) / vs;
}

// The discrete Laplace pressure of the current mesh: the P at which pressure balances tension,
// γ ∇S = P ∇V, in the least-squares sense P = γ (∇S·∇V) / |∇V|².
double discreteLaplacePressure(const Simulation& sim) {
  const CellSet& c = sim.cells();
  const Geometry& g = sim.geometry();
  Eigen::Matrix3Xd grad_s = Eigen::Matrix3Xd::Zero(3, c.numVertices());
  Eigen::Matrix3Xd grad_v = Eigen::Matrix3Xd::Zero(3, c.numVertices());
  for (int t = 0; t < c.numTriangles(); ++t) {
    const Tri& f = c.tri[t];
    for (int k = 0; k < 3; ++k) {
      const int i = f[k], j = f[(k + 1) % 3], l = f[(k + 2) % 3];
      grad_s.col(i) += 0.5 * g.tri_normal[t].cross(Vec3(c.x.col(l) - c.x.col(j)));
      grad_v.col(i) += g.tri_area[t] / 3.0 * g.tri_normal[t];
    }
  }
  return sim.spec().cells.gamma * (grad_s.cwiseProduct(grad_v).sum()) / grad_v.squaredNorm();
}

}  // namespace

TEST(CellAtRest, StaysAtRestWithLaplacePressure) {
  const SceneSpec s = cellSpec(1.0, 320);
  Simulation sim(s);
  const Vec3 c0 = sim.geometry().cell_centroid[0];
  const double r = sim.cells().radius[0];
  const double laplace = 2 * s.cells.gamma / r;
  double max_vol_err = 0;
  // 100 s = 35 τ_K: the PI controller has removed the initial discretisation mismatch.
  for (int k = 0; k < 1000; ++k) {
    ASSERT_TRUE(sim.step().ok());
    if (k >= 500) max_vol_err = std::max(max_vol_err, std::abs(volumeError(sim)));
  }
  EXPECT_LT(max_vol_err, 1e-4);
  EXPECT_LT((sim.geometry().cell_centroid[0] - c0).norm(), 1e-6 * r);
  // At rest: no normal motion. Nodes may still slide tangentially (the cortex is a fluid and the
  // icosphere's unequal triangles redistribute), which moves no surface.
  double vn = 0, vt = 0;
  for (int i = 0; i < sim.cells().numVertices(); ++i) {
    const Vec3 v = sim.cells().v.col(i), n = sim.geometry().vertex_normal[i];
    vn = std::max(vn, std::abs(v.dot(n)));
    vt = std::max(vt, (v - v.dot(n) * n).norm());
  }
  std::cout << "[ rest     ] max normal speed " << vn << " µm/s, max tangential " << vt
            << " µm/s\n";
  EXPECT_LT(vn, 1e-5);
  EXPECT_LT(vt, 1e-3);
  // Pressure balances tension: it equals the discrete Laplace pressure of the mesh ...
  const double p = sim.pressure(0);
  EXPECT_NEAR(p, discreteLaplacePressure(sim), 1e-4 * laplace);
  // ... which is 2γ/r up to the discretisation error of a 320-triangle sphere.
  std::cout << "[ rest     ] P = " << p << " kPa, 2γ/r = " << laplace
            << " kPa, relative difference " << (p - laplace) / laplace << "\n";
  EXPECT_NEAR(p, laplace, 0.01 * laplace);
}

TEST(CellAtRest, LaplacePressureConvergesWithMeshRefinement) {
  double prev = 1;
  for (int tris : {80, 320, 1280}) {
    Simulation sim(cellSpec(1.0, tris));
    for (int k = 0; k < 600; ++k) ASSERT_TRUE(sim.step().ok());
    const double laplace = 2 * sim.spec().cells.gamma / sim.cells().radius[0];
    const double err = std::abs(sim.pressure(0) - laplace) / laplace;
    std::cout << "[ laplace  ] " << tris << " triangles: |P − 2γ/r|/(2γ/r) = " << err << "\n";
    EXPECT_LT(err, prev);
    prev = err;
  }
}

TEST(CellRelaxation, EllipsoidBecomesSphere) {
  const SceneSpec s = cellSpec(1.3, 320);
  Simulation sim(s);
  const double tau_gamma = s.cells.eta / s.cells.gamma;
  EXPECT_NEAR(aspect(sim), 1.3 * 1.3, 0.02);     // axes (1.3, 1, 1/1.3) r
  std::vector<std::pair<double, double>> curve;  // (t, ln(AR − 1))
  std::pair<double, double> tail0;
  const int steps = static_cast<int>(std::lround(20 * tau_gamma / s.numerics.dt_s));
  for (int k = 0; k < steps; ++k) {
    ASSERT_TRUE(sim.step().ok()) << "step " << k;
    const double a = aspect(sim) - 1;
    // Fit the shape mode well above the mesh's residual asphericity (≈1% at 320 triangles,
    // O(h²): 3% at 80, 0.3% at 1280), which then decays on the much slower time scale of
    // tangential node redistribution.
    if (a > 0.05 && a < 0.5) curve.emplace_back(sim.time(), std::log(a));
    if (k == steps / 2) tail0 = {sim.time(), a};
  }
  EXPECT_LT(aspect(sim), 1.01);
  EXPECT_LT(std::abs(volumeError(sim)), 1e-3);
  // Exponential decay: least-squares slope of ln(AR − 1) against t.
  ASSERT_GT(curve.size(), 10u);
  double st = 0, sy = 0, stt = 0, sty = 0;
  for (auto [t, y] : curve) {
    st += t;
    sy += y;
    stt += t * t;
    sty += t * y;
  }
  const double n = static_cast<double>(curve.size());
  const double slope = (n * sty - st * sy) / (n * stt - st * st);
  const double tau = -1 / slope;
  // Residual of the straight-line fit: the decay is exponential, not merely monotone.
  const double icpt = (sy - slope * st) / n;
  double rms = 0;
  for (auto [t, y] : curve) rms += (y - icpt - slope * t) * (y - icpt - slope * t);
  rms = std::sqrt(rms / n);
  std::cout << "[ relax    ] aspect-ratio relaxation time τ = " << tau << " s = " << tau / tau_gamma
            << " τ_γ (fit rms in ln(AR−1): " << rms << ")\n";
  const double tail_tau = (sim.time() - tail0.first) / std::log(tail0.second / (aspect(sim) - 1));
  std::cout << "[ relax    ] mesh-residual tail (AR − 1 ≈ " << aspect(sim) - 1
            << "): time constant " << tail_tau << " s\n";
  ::testing::Test::RecordProperty("relaxation_time_s", std::to_string(tau));
  // The shape mode relaxes on the cortical time scale τ_γ = η/γ (a single exponential) ...
  EXPECT_GT(tau, 0.1 * tau_gamma);
  EXPECT_LT(tau, 2 * tau_gamma);
  EXPECT_LT(rms, 0.1);
  // ... far faster than the tail, which is a discretisation effect.
  EXPECT_GT(tail_tau, 10 * tau);
}

TEST(Reproducibility, SameSeedSameSpecBitIdentical) {
  SceneSpec s = cellSpec(1.3, 320);
  s.cells.radius_gamma_k = 37;  // radius drawn from the seed
  s.seed = 42;
  auto run = [](const SceneSpec& spec) {
    Simulation sim(spec);
    for (int k = 0; k < 1000; ++k) EXPECT_TRUE(sim.step().ok());
    return sim.cells().x;
  };
  const Eigen::Matrix3Xd a = run(s), b = run(s);
  ASSERT_EQ(a.size(), b.size());
  EXPECT_EQ(std::memcmp(a.data(), b.data(), sizeof(double) * a.size()), 0);
  s.seed = 43;  // a different seed draws a different radius: the comparison can fail
  const Eigen::Matrix3Xd c = run(s);
  EXPECT_TRUE(c.size() != a.size() || std::memcmp(a.data(), c.data(), sizeof(double) * a.size()));
}
