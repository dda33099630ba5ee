// Fusion observables (docs/model.md §8) on synthetic geometry: fusion angle, shape index, surface
// contact angle, MSRD and mixing time, normalized unique contacts.
#include <cmath>
#include <iostream>
#include <limits>
#include <vector>

#include <gtest/gtest.h>

#include "activefoam/contacts.h"
#include "activefoam/observables.h"
#include "activefoam/rng.h"

using namespace activefoam;

namespace {

constexpr double kDeg = M_PI / 180.0;

// Sphere of radius R centred at the origin, truncated by the plane x = R cos θ (keeps
// x ≤ R cos θ) and closed by the flat disk of radius R sin θ. Built as rings of `m` vertices
// from the disk centre to the pole (−R, 0, 0), with one ring exactly on the rim circle, so the
// neck of two such cells is represented exactly.
TriMesh truncatedSphere(double R, double theta_deg, int m = 96, int sphere_rings = 72,
                        int disk_rings = 12) {
  const double th = theta_deg * kDeg, h = R * std::cos(th), a = R * std::sin(th);
  std::vector<std::pair<double, double>> rings;  // (x, distance from the x axis)
  for (int j = 1; j <= disk_rings; ++j) rings.emplace_back(h, a * j / disk_rings);
  for (int j = 1; j < sphere_rings; ++j) {
    const double phi = th + (M_PI - th) * j / sphere_rings;
    rings.emplace_back(R * std::cos(phi), R * std::sin(phi));
  }
  const int nr = static_cast<int>(rings.size());
  TriMesh mesh;
  mesh.x.resize(3, 2 + nr * m);
  mesh.x.col(0) = Vec3(h, 0, 0);
  for (int r = 0; r < nr; ++r)
    for (int k = 0; k < m; ++k) {
      const double psi = 2 * M_PI * k / m;
      mesh.x.col(1 + r * m + k) =
          Vec3(rings[r].first, rings[r].second * std::cos(psi), rings[r].second * std::sin(psi));
    }
  const int south = 1 + nr * m;
  mesh.x.col(south) = Vec3(-R, 0, 0);
  auto id = [&](int r, int k) { return 1 + r * m + (k % m); };
  for (int k = 0; k < m; ++k) mesh.tri.push_back({0, id(0, k), id(0, k + 1)});
  for (int r = 0; r + 1 < nr; ++r)
    for (int k = 0; k < m; ++k) {
      mesh.tri.push_back({id(r, k), id(r + 1, k), id(r + 1, k + 1)});
      mesh.tri.push_back({id(r, k), id(r + 1, k + 1), id(r, k + 1)});
    }
  for (int k = 0; k < m; ++k) mesh.tri.push_back({south, id(nr - 1, k + 1), id(nr - 1, k)});
  return mesh;
}

// Two equal truncated spheres sharing their cut disk in the plane x = 0 (centres at ∓R cos θ),
// as cells 0 and 1 with spheroid labels 0 and 1.
CellSet truncatedDoublet(double R, double theta_deg) {
  TriMesh m = truncatedSphere(R, theta_deg);
  EXPECT_EQ(checkClosedManifold(m), "");
  const double h = R * std::cos(theta_deg * kDeg);
  m.x.row(0).array() -= h;
  CellSet cells;
  cells.addCell(m, R, 0);
  // The mirror image by a rotation of 180° about z (keeps the orientation outward).
  m.x.row(0) *= -1;
  m.x.row(1) *= -1;
  cells.addCell(m, R, 1);
  return cells;
}

ContactList contactsOf(const CellSet& cells) {
  Geometry geo;
  computeGeometry(cells, geo);
  ContactList contacts;
  detectContacts(cells, geo, ContactLaw{}, ContactQuadrature::Exact, contacts);
  return contacts;
}

TriMesh scaled(TriMesh m, const Vec3& s, const Vec3& shift = Vec3::Zero()) {
  for (int i = 0; i < m.numVertices(); ++i) m.x.col(i) = m.x.col(i).cwiseProduct(s) + shift;
  return m;
}

}  // namespace

// ---------------------------------------------------------------------------------------------
// Fusion angle

class FusionAngleTruncatedSpheres : public ::testing::TestWithParam<double> {};

TEST_P(FusionAngleTruncatedSpheres, RecoversTheta) {
  const double theta = GetParam(), R = 50;
  const CellSet cells = truncatedDoublet(R, theta);
  // No contacts: every vertex is free.
  const FusionAngle f = fusionAngle(cells, ContactList{});
  ASSERT_TRUE(f.ok) << f.why;
  std::cout << "[ fusion   ] θ = " << theta << "°: recovered " << f.theta_deg
            << "°, a = " << f.neck_radius_um << ", L = " << f.length_um << ", d = " << f.distance_um
            << "\n";
  EXPECT_NEAR(f.theta_deg, theta, 1.0);
  EXPECT_NEAR(f.neck_radius_um, R * std::sin(theta * kDeg), 0.01 * R);
  EXPECT_NEAR(f.length_um, 2 * R * (1 + std::cos(theta * kDeg)), 1e-9 * R);
  EXPECT_NEAR(f.neck_position_um, f.distance_um / 2, 0.01 * R);
  // The truncated balls' centroids are symmetric about the cut plane.
  EXPECT_NEAR(f.centroid[0].x(), -f.centroid[1].x(), 1e-9 * R);
  EXPECT_NEAR(f.distance_um, 2 * std::abs(f.centroid[0].x()), 1e-9 * R);

  // With the shared disk in contact (detected): every cell surface (default) still sees the
  // rim; the free surface alone leaves a band without data around the neck.
  const ContactList contacts = contactsOf(cells);
  ASSERT_FALSE(contacts.pairs.empty());
  const FusionAngle g = fusionAngle(cells, contacts);
  ASSERT_TRUE(g.ok) << g.why;
  EXPECT_NEAR(g.theta_deg, theta, 1.0);
  const FusionAngle free_only = fusionAngle(cells, contacts, true);
  ASSERT_TRUE(free_only.ok) << free_only.why;
  std::cout << "[ fusion   ]   with contacts: " << g.theta_deg << "°; free surface only "
            << free_only.theta_deg << "°\n";
  EXPECT_GE(free_only.theta_deg, g.theta_deg - 1e-9);
}

INSTANTIATE_TEST_SUITE_P(Angles, FusionAngleTruncatedSpheres,
                         ::testing::Values(10.0, 45.0, 60.0, 80.0, 89.0));

TEST(FusionAngle, FailsWithoutTwoSpheroids) {
  CellSet cells;
  cells.addCell(scaled(icosphere(2), Vec3::Constant(5)), 5, 0);
  cells.addCell(scaled(icosphere(2), Vec3::Constant(5), Vec3(10, 0, 0)), 5, 0);
  const FusionAngle f = fusionAngle(cells, ContactList{});
  EXPECT_FALSE(f.ok);
  EXPECT_NE(f.why.find("both spheroids"), std::string::npos) << f.why;
  cells.label[1] = 2;
  EXPECT_FALSE(fusionAngle(cells, ContactList{}).ok);
}

TEST(FusionAngle, SeparateSpheresGiveZero) {
  // Two spheres 2 µm apart: no surface crosses the gap, so a = 0 and θ = 0°.
  CellSet cells;
  cells.addCell(scaled(icosphere(3), Vec3::Constant(5), Vec3(-6, 0, 0)), 5, 0);
  cells.addCell(scaled(icosphere(3), Vec3::Constant(5), Vec3(6, 0, 0)), 5, 1);
  const FusionAngle f = fusionAngle(cells, ContactList{});
  ASSERT_TRUE(f.ok) << f.why;
  EXPECT_NEAR(f.distance_um, 12, 1e-6);
  EXPECT_NEAR(f.length_um, 22, 1e-6);
  EXPECT_EQ(f.neck_radius_um, 0.0);
  EXPECT_EQ(f.theta_deg, 0.0);
}

TEST(FusionAngle, OneSphereIsCompleteFusion) {
  // One sphere whose two halves are the two spheroids: a single bulge, no neck: θ = 90°.
  TriMesh half = truncatedSphere(10, 90);
  CellSet cells;
  cells.addCell(half, 10, 0);
  half.x.row(0) *= -1;
  half.x.row(1) *= -1;
  cells.addCell(half, 10, 1);
  const FusionAngle f = fusionAngle(cells, ContactList{});
  ASSERT_TRUE(f.ok) << f.why;
  EXPECT_NEAR(f.distance_um, 2 * 3.0 / 8 * 10, 0.01);
  EXPECT_NEAR(f.theta_deg, 90, 0.1);
}

// ---------------------------------------------------------------------------------------------
// Shape index

TEST(ShapeIndex, SphereAndEllipsoid) {
  CellSet cells;
  cells.addCell(scaled(icosphere(3), Vec3::Constant(7)), 7);
  cells.addCell(scaled(icosphere(3), Vec3(14, 7, 7), Vec3(30, 0, 0)), 7);
  Geometry geo;
  computeGeometry(cells, geo);
  const double sphere = std::cbrt(36 * M_PI);  // 4.836
  EXPECT_NEAR(shapeIndex(geo, 0), sphere, 0.01 * sphere);
  // Prolate 2:1:1 spheroid: S/V^{2/3} = 5.207.
  EXPECT_NEAR(shapeIndex(geo, 1), 5.207, 0.01 * 5.207);
  EXPECT_GT(shapeIndex(geo, 1), shapeIndex(geo, 0));
  EXPECT_NEAR(meanShapeIndex(geo), 0.5 * (shapeIndex(geo, 0) + shapeIndex(geo, 1)), 1e-12);
  EXPECT_TRUE(std::isnan(meanShapeIndex(Geometry{})));
}

// ---------------------------------------------------------------------------------------------
// Surface contact angle

class SurfaceContactAngleDoublet : public ::testing::TestWithParam<double> {};

TEST_P(SurfaceContactAngleDoublet, MatchesTruthAndDoubletAngle) {
  const double theta = GetParam();
  const CellSet cells = truncatedDoublet(10, theta);
  const ContactList contacts = contactsOf(cells);
  ASSERT_FALSE(contacts.pairs.empty());
  const SurfaceContactAngle s = surfaceContactAngle(cells, contacts);
  ASSERT_TRUE(s.ok) << s.why;
  const double doublet = doubletContactAngleDeg(cells, contacts);
  std::cout << "[ contact  ] θ_c = " << theta << "°: surface " << s.theta_deg << "° ("
            << s.junctions << " junctions), doublet " << doublet << "°\n";
  EXPECT_EQ(s.junctions, 1);
  EXPECT_NEAR(s.theta_deg, theta, 2.0);
  EXPECT_NEAR(s.theta_deg, doublet, 2.0);
  EXPECT_NEAR(s.gsi, std::cos(s.theta_deg * kDeg), 1e-12);
}

INSTANTIATE_TEST_SUITE_P(Angles, SurfaceContactAngleDoublet,
                         ::testing::Values(20.0, 45.0, 64.06, 80.0));

TEST(SurfaceContactAngle, UnequalDoublet) {
  // Cells of radii 10 and 15 sharing a flat disk of radius a: their own angles θ_A, θ_B with
  // the interface; the free surfaces meet at ψ = 180° − θ_A − θ_B, so θ_c = (θ_A + θ_B)/2, the
  // mean that doubletContactAngleDeg reports too.
  const double ra = 10, rb = 15, theta_a = 60;
  const double a = ra * std::sin(theta_a * kDeg), theta_b = std::asin(a / rb) / kDeg;
  TriMesh ma = truncatedSphere(ra, theta_a), mb = truncatedSphere(rb, theta_b);
  ma.x.row(0).array() -= ra * std::cos(theta_a * kDeg);
  mb.x.row(0).array() -= rb * std::cos(theta_b * kDeg);
  mb.x.row(0) *= -1;
  mb.x.row(1) *= -1;
  CellSet cells;
  cells.addCell(ma, ra, 0);
  cells.addCell(mb, rb, 1);
  const ContactList contacts = contactsOf(cells);
  const SurfaceContactAngle s = surfaceContactAngle(cells, contacts);
  ASSERT_TRUE(s.ok) << s.why;
  const double expected = 0.5 * (theta_a + theta_b);
  std::cout << "[ contact  ] θ_A = " << theta_a << "°, θ_B = " << theta_b << "°: surface "
            << s.theta_deg << "°, doublet " << doubletContactAngleDeg(cells, contacts) << "°\n";
  EXPECT_NEAR(s.theta_deg, expected, 0.5);
  EXPECT_NEAR(s.theta_deg, doubletContactAngleDeg(cells, contacts), 2.0);
}

TEST(SurfaceContactAngle, NeedsContacts) {
  const CellSet cells = truncatedDoublet(10, 45);
  EXPECT_FALSE(surfaceContactAngle(cells, ContactList{}).ok);
  ContactList none;
  none.vertex_contact_area.assign(cells.numVertices(), 0.0);
  const SurfaceContactAngle s = surfaceContactAngle(cells, none);
  EXPECT_FALSE(s.ok);
  EXPECT_EQ(s.why, "no contacts");
}

// ---------------------------------------------------------------------------------------------
// Contacting pairs, unique contacts

TEST(ContactHistory, CountsDistinctPairsOverInitial) {
  ContactHistory h;
  EXPECT_TRUE(std::isnan(h.normalized()));
  h.add({{0, 1}, {1, 2}, {2, 1}});
  EXPECT_EQ(h.initialCount(), 2);
  EXPECT_DOUBLE_EQ(h.normalized(), 1.0);
  h.add({{1, 2}, {2, 3}});
  h.add({{3, 0}, {1, 0}});
  h.add({});
  EXPECT_EQ(h.distinctCount(), 4);  // 01 12 23 03
  EXPECT_EQ(h.initialCount(), 2);
  EXPECT_DOUBLE_EQ(h.normalized(), 2.0);

  ContactHistory empty_start;
  empty_start.add({});
  empty_start.add({{0, 1}});
  EXPECT_EQ(empty_start.initialCount(), 0);
  EXPECT_TRUE(std::isnan(empty_start.normalized()));
}

TEST(ContactHistory, FromContactList) {
  const CellSet cells = truncatedDoublet(10, 45);
  const ContactList contacts = contactsOf(cells);
  const auto pairs = contactingCellPairs(cells, contacts);
  ASSERT_EQ(pairs.size(), 1u);
  EXPECT_EQ(pairs[0], std::make_pair(0, 1));
  ContactHistory h;
  h.add(cells, contacts);
  EXPECT_EQ(h.initialCount(), 1);
  EXPECT_DOUBLE_EQ(h.normalized(), 1.0);
}

// ---------------------------------------------------------------------------------------------
// MSRD

TEST(Msrd, BallisticPairIsExact) {
  // Cell 1 moves away from cell 0 at v; cell 2 moves wildly but is never in contact.
  const double v = 0.01, dt = 60;
  const int n = 50;
  MsrdTracker m;
  for (int k = 0; k < n; ++k) {
    const double t = k * dt;
    m.addSample(t, {Vec3(0, 0, 0), Vec3(10 + v * t, 0, 0), Vec3(0, 100 * std::sin(t), t)},
                {{1, 0}});
  }
  ASSERT_EQ(m.numSamples(), n);
  EXPECT_DOUBLE_EQ(m.msrd(0), 0.0);
  for (int lag : {1, 7, 30, n - 1})
    EXPECT_NEAR(m.msrd(lag), std::pow(v * lag * dt, 2), 1e-9) << lag;
  EXPECT_TRUE(std::isnan(m.msrd(n)));
  EXPECT_EQ(m.msrdCurve().size(), static_cast<size_t>(n));
  // r = 6 µm is reached at exactly 600 s (lag 10).
  const auto mix = m.mixingTime(6);
  EXPECT_TRUE(mix.reached);
  EXPECT_NEAR(mix.time_s, 600, 1e-9);
  // Between samples: linear in MSRD between lags 10 (36 µm²) and 11 (43.56 µm²).
  const auto mid = m.mixingTime(std::sqrt(39.78));
  EXPECT_NEAR(mid.time_s, 630, 1e-6);
  // Never reached: capped at the run length.
  const auto never = m.mixingTime(100);
  EXPECT_FALSE(never.reached);
  EXPECT_DOUBLE_EQ(never.time_s, (n - 1) * dt);
}

TEST(Msrd, OnlyPairsInContactAtTheOrigin) {
  // Relative position (t², 0, 0) with dt = 1; in contact at sample 0 only: MSRD(k) = k⁴. Were
  // every origin used, MSRD(1) would mix in (t+1)² − t² = 2t + 1 for t > 0.
  MsrdTracker m;
  for (int k = 0; k < 10; ++k)
    m.addSample(
        k, {Vec3::Zero(), Vec3(k * k, 0, 0)},
        k == 0 ? std::vector<std::pair<int, int>>{{0, 1}} : std::vector<std::pair<int, int>>{});
  for (int lag = 0; lag < 10; ++lag) EXPECT_NEAR(m.msrd(lag), std::pow(lag, 4), 1e-9);
  EXPECT_THROW(m.addSample(10, {Vec3::Zero()}, {}), std::invalid_argument);
  EXPECT_THROW(m.addSample(5, {Vec3::Zero(), Vec3::Zero()}, {}), std::invalid_argument);
}

// A cloud of cells turning as a body about a tilted axis while it drifts and swells about its
// centroid: x_k = c + v t + s_k R(ω t) p. Kabsch recovers R exactly for a rotation composed with
// a uniform scaling, so with the turn taken out a pair's relative vector changes only by the
// swelling: |Δ|² = (s_{o+lag} − s_o)² |p_i − p_j|² — and by nothing for a rigid cloud, whose
// MSRD as it is is all turn.
TEST(Msrd, LessRotationTakesOutATurningBodyExactly) {
  Rng rng(11, 3);
  const int nc = 30, n = 40;
  const double dt = 600, omega = 20.0 * M_PI / 180.0 / 3600.0;  // 20° an hour
  std::vector<Vec3> p(nc);
  for (Vec3& x : p) x = Vec3(rng.normal(), rng.normal(), rng.normal()) * 5.0;
  std::vector<std::pair<int, int>> pairs;
  for (int i = 0; i < nc; ++i)
    for (int j = i + 1; j < nc; ++j)
      if ((p[i] - p[j]).norm() < 6) pairs.emplace_back(i, j);
  ASSERT_GT(pairs.size(), 10u);
  const Vec3 axis = Vec3(1, 2, 3).normalized();
  for (double swell : {0.0, 2e-3}) {
    MsrdTracker m;
    auto s = [&](int k) { return 1 + swell * k; };
    for (int k = 0; k < n; ++k) {
      const double t = k * dt;
      const Eigen::Matrix3d rot = Eigen::AngleAxisd(omega * t, axis).toRotationMatrix();
      std::vector<Vec3> x(nc);
      for (int i = 0; i < nc; ++i)
        x[i] = Vec3(3, -1, 2) + Vec3(1e-3, 0, 2e-3) * t + s(k) * (rot * p[i]);
      m.addSample(t, x, pairs);
    }
    for (int lag : {1, 6, 20, n - 1}) {
      double raw = 0, less = 0;
      int count = 0;
      for (int o = 0; o + lag < n; ++o)
        for (const auto& [i, j] : pairs) {
          const Vec3 d = p[i] - p[j];
          const Eigen::AngleAxisd r0(omega * o * dt, axis), r1(omega * (o + lag) * dt, axis);
          raw += (s(o + lag) * (r1 * d) - s(o) * (r0 * d)).squaredNorm();
          less += std::pow(s(o + lag) - s(o), 2) * d.squaredNorm();
          ++count;
        }
      EXPECT_NEAR(m.msrd(lag), raw / count, 1e-9 * raw / count) << swell << " " << lag;
      EXPECT_NEAR(m.msrdLessRotation(lag), less / count, 1e-9 * (raw / count))
          << swell << " " << lag;
      EXPECT_NEAR(m.turnDeg(lag), 20.0 * lag * dt / 3600.0, 1e-7) << swell << " " << lag;
    }
    EXPECT_TRUE(std::isnan(m.msrdLessRotation(n)));
    EXPECT_TRUE(std::isnan(m.turnDeg(n)));
    // The turn alone passes r = 2 µm (the raw MSRD reaches 4 µm² within the run), the swelling
    // less: at 2e-3 a sample, (0.078)² ⟨|d|²⟩ ≈ 0.1 ⟨|d|²⟩ by the last lag.
    const double r = 2;
    ASSERT_GT(m.msrd(n - 1), r * r);
    EXPECT_TRUE(m.mixingTime(r).reached);
    const auto lr = m.mixingTimeLessRotation(r);
    if (swell == 0) {
      EXPECT_FALSE(lr.reached);
      EXPECT_DOUBLE_EQ(lr.time_s, (n - 1) * dt);
    }
  }
}

// Without a turn the best rotation is the identity: the MSRD less the rotation is the MSRD.
TEST(Msrd, LessRotationLeavesAStillAggregateAlone) {
  // Two cells drifting apart along x inside a still cloud.
  MsrdTracker m;
  Rng rng(4, 2);
  std::vector<Vec3> p(20);
  for (Vec3& x : p) x = Vec3(rng.normal(), rng.normal(), rng.normal()) * 10.0;
  for (int k = 0; k < 10; ++k) {
    std::vector<Vec3> x = p;
    x[0] += Vec3(-0.1 * k, 0, 0);
    x[1] += Vec3(0.1 * k, 0, 0);
    m.addSample(k, x, {{0, 1}, {2, 3}});
  }
  for (int lag = 1; lag < 10; ++lag) {
    EXPECT_NEAR(m.msrd(lag), 0.5 * std::pow(0.2 * lag, 2), 1e-12);
    // Kabsch of a cloud whose two cells moved symmetrically along x: a small fitted turn at most.
    EXPECT_NEAR(m.msrdLessRotation(lag), m.msrd(lag), 0.05 * m.msrd(lag)) << lag;
    EXPECT_LT(m.turnDeg(lag), 0.5) << lag;
  }
}

TEST(Msrd, DiffusivePairsGrowLinearly) {
  // 300 pairs of independent Brownian cells (D each): relative D_rel = 2D, MSRD = 12 D lag.
  const int pairs = 300, n = 120;
  const double D = 0.002, dt = 60;
  Rng rng(5, 1);
  std::vector<Vec3> x(2 * pairs, Vec3::Zero());
  std::vector<std::pair<int, int>> contact;
  for (int p = 0; p < pairs; ++p) contact.emplace_back(2 * p, 2 * p + 1);
  MsrdTracker m;
  for (int k = 0; k < n; ++k) {
    m.addSample(k * dt, x, contact);
    for (Vec3& xi : x)
      for (int d = 0; d < 3; ++d) xi(d) += std::sqrt(2 * D * dt) * rng.normal();
  }
  for (int lag : {1, 5, 20}) {
    const double expected = 12 * D * lag * dt;
    EXPECT_NEAR(m.msrd(lag), expected, 0.05 * expected) << lag;
  }
  const double r = 4;  // r² = 16 µm² → 16 / (12 D) = 667 s
  const auto mix = m.mixingTime(r);
  EXPECT_TRUE(mix.reached);
  EXPECT_NEAR(mix.time_s, r * r / (12 * D), 0.1 * r * r / (12 * D));
  // Origins thinned to at most 10: the same curve within noise.
  MsrdTracker thin(10);
  Rng rng2(5, 1);
  std::fill(x.begin(), x.end(), Vec3::Zero());
  for (int k = 0; k < n; ++k) {
    thin.addSample(k * dt, x, contact);
    for (Vec3& xi : x)
      for (int d = 0; d < 3; ++d) xi(d) += std::sqrt(2 * D * dt) * rng2.normal();
  }
  EXPECT_NEAR(thin.msrd(5), 12 * D * 5 * dt, 0.15 * 12 * D * 5 * dt);
}
