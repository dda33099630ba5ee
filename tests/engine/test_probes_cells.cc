// Probes of the cells' shape and motion ([observe] shape, dissipation at the cells' scale,
// torque) on states with known answers.
#include <algorithm>
#include <cmath>
#include <limits>

#include <gtest/gtest.h>
#include <Eigen/SparseCholesky>

#include "activefoam/probe.h"
#include "activefoam/simulation.h"
#include "activefoam/spheroid.h"
#include "activefoam/terms.h"
#include "test_support.h"

using namespace activefoam;
using activefoam::testing::cellSpec;
using activefoam::testing::smallFusionSpec;

namespace {

// One cell: a sphere of radius 8 µm stretched along z by `stretch`.
CellSet spheroidCell(double stretch, int triangles) {
  TriMesh m = ellipsoidCell(8.0, 1.0, triangles, Vec3::Zero());
  m.x.row(2) *= stretch;
  CellSet cells;
  cells.addCell(m, 8.0);
  return cells;
}

// A spheroid scene's five cells in contact, as the simulation starts them.
SceneSpec fiveCells() {
  SceneSpec s = cellSpec(1.0, 80);
  s.scene = SceneKind::Spheroid;
  s.scene_params.n_cells = 5;
  return resolve(s);
}

// √(⟨z²⟩ / ⟨x²⟩) over the surface of the spheroid x²/a² + y²/a² + z²/b² = 1 (area-weighted),
// by Simpson's rule in the polar angle: what surfaceElongation measures of it.
double spheroidSurfaceElongation(double a, double b) {
  const int n = 4000;
  double zz = 0, xx = 0;
  for (int k = 0; k <= n; ++k) {
    const double th = M_PI * k / n, s = std::sin(th), c = std::cos(th);
    const double w = (k == 0 || k == n) ? 1 : (k % 2 ? 4 : 2);
    const double ds = a * s * std::sqrt(b * b * s * s + a * a * c * c);
    zz += w * b * b * c * c * ds;
    xx += w * 0.5 * a * a * s * s * ds;
  }
  return std::sqrt(zz / xx);
}

}  // namespace

// ---- observe.shape

// A sphere's mesh, smoothed, has the sphere's shape index (36π)^{1/3} to the mesh's own
// polyhedral excess and elongation 1; ripples of a vertex's size raise the raw index and the
// smoothing takes most of the rise away; stretched to axes a, a, 1.5a the surface's second
// moments give the spheroid's surface value, not 1.5 (that of its volume).
TEST(ProbesCells, ShapeOfASphereAndOfASpheroid) {
  const double sphere = std::cbrt(36 * M_PI);
  CellSet cells = spheroidCell(1.0, 1280);
  Topology topo;
  updateTopology(cells, topo);
  Geometry geo, smooth;
  computeGeometry(cells, geo);
  computeGeometry(taubinSmoothed(cells, topo), smooth);
  EXPECT_NEAR(shapeIndex(smooth, 0), sphere, 0.01 * sphere);
  EXPECT_NEAR(surfaceElongation(cells, geo, 0), 1.0, 1e-3);

  CellSet rough = cells;
  Rng rng(3, 1);
  for (int i = 0; i < rough.numVertices(); ++i)
    rough.x.col(i) *= 1 + 0.04 * (2 * rng.uniform() - 1);
  Geometry rough_geo, rough_smooth;
  computeGeometry(rough, rough_geo);
  computeGeometry(taubinSmoothed(rough, topo), rough_smooth);
  const double rise = shapeIndex(rough_geo, 0) - shapeIndex(geo, 0);
  EXPECT_GT(rise, 0.01);
  EXPECT_LT(shapeIndex(rough_smooth, 0) - shapeIndex(smooth, 0), 0.2 * rise);

  const double expected = spheroidSurfaceElongation(1.0, 1.5);
  ASSERT_GT(std::abs(expected - 1.5), 0.05);
  CellSet stretched = spheroidCell(1.5, 1280);
  computeGeometry(stretched, geo);
  EXPECT_NEAR(surfaceElongation(stretched, geo, 0), expected, 0.005 * expected);
}

// The regression of a line's points is the line (r ±1); a cloud symmetric about its line has
// that line and r from its spread; no line through points of one x.
TEST(ProbesCells, LineFitOfKnownPoints) {
  const std::vector<double> f = {0.2, 0.35, 0.5, 0.61, 0.8};
  std::vector<double> q, down;
  for (double x : f) {
    q.push_back(4.81 + 0.62 * x);
    down.push_back(1 - 2 * x);
  }
  LineFit fit = lineFit(f, q);
  EXPECT_NEAR(fit.slope, 0.62, 1e-12);
  EXPECT_NEAR(fit.intercept, 4.81, 1e-12);
  EXPECT_NEAR(fit.r, 1.0, 1e-12);
  EXPECT_NEAR(lineFit(f, down).r, -1.0, 1e-12);
  // (0, 1 ± e), (1, 3 ± e): the line 1 + 2x; sxx 1, syy 4 (1 + e²), sxy 2: r = 1/√(1 + e²).
  const double e = 0.5;
  fit = lineFit({0, 0, 1, 1}, {1 + e, 1 - e, 3 + e, 3 - e});
  EXPECT_NEAR(fit.slope, 2, 1e-12);
  EXPECT_NEAR(fit.intercept, 1, 1e-12);
  EXPECT_NEAR(fit.r, 1 / std::sqrt(1 + e * e), 1e-12);
  EXPECT_TRUE(std::isnan(lineFit({0.3, 0.3}, {1, 2}).slope));
  EXPECT_TRUE(std::isnan(lineFit({0.3}, {1}).intercept));
  EXPECT_THROW(lineFit({0.3}, {1, 2}), std::invalid_argument);
}

// The probe's columns are the means of cellShapes and the line through its cells; five cells
// in contact touch each other over part of their surface. Fresh cells are identical icospheres
// (one shape index up to rounding, so no line through them): a few steps deform each cell by
// its own contacts.
TEST(ProbesCells, ShapeProbeSummarisesTheCells) {
  SceneSpec s = fiveCells();
  s.observe.shape = true;
  Simulation sim(s);
  for (int k = 0; k < 20; ++k) ASSERT_TRUE(sim.step().ok());
  auto probes = makeProbes(s);
  ASSERT_EQ(probes.size(), 1u);
  std::vector<double> out;
  probes[0]->sample(sim, out);
  ASSERT_EQ(out.size(), 6u);
  Topology topo;
  updateTopology(sim.cells(), topo);
  const CellShapes c = cellShapes(sim.cells(), sim.geometry(), sim.contacts(), topo);
  const std::vector<double> free = freeFractions(sim.geometry(), sim.contacts());
  double qs = 0, el = 0, f = 0;
  for (int k = 0; k < 5; ++k) {
    EXPECT_NEAR(c.contact_fraction[k], 1 - free[k], 1e-15);
    qs += c.shape_index_smoothed[k] / 5;
    el += c.elongation[k] / 5;
    f += c.contact_fraction[k] / 5;
    EXPECT_GE(c.elongation[k], 1.0);
  }
  EXPECT_GT(f, 0.001);
  EXPECT_NEAR(out[0], qs, 1e-12);
  EXPECT_NEAR(out[1], el, 1e-12);
  EXPECT_NEAR(out[2], f, 1e-12);
  const auto [qmin, qmax] = std::minmax_element(c.shape_index.begin(), c.shape_index.end());
  ASSERT_GT(*qmax - *qmin, 1e-6);
  const LineFit fit = lineFit(c.contact_fraction, c.shape_index);
  ASSERT_TRUE(std::isfinite(fit.r));
  EXPECT_EQ(out[3], fit.slope);
  EXPECT_EQ(out[4], fit.intercept);
  EXPECT_EQ(out[5], fit.r);
}

// ---- observe.dissipation at the cells' scale

// Each cell moving as a + B (x − p): the field is its own affine part, so every term dissipates
// on the affine part what it does on all of it; the cells' speeds are their translations'. What
// is left after taking the affine part has none; a uniform translation has no jitter.
TEST(ProbesCells, AffinePartOfACellScaleMotion) {
  const SceneSpec s = fiveCells();
  Simulation sim(s);
  const CellSet& cells = sim.cells();
  const int nv = cells.numVertices(), nc = cells.numCells();
  Rng rng(5, 2);
  auto random = [&] { return 2 * rng.uniform() - 1; };
  std::vector<Vec3> a(nc);
  std::vector<Eigen::Matrix3d> b(nc);
  for (int c = 0; c < nc; ++c) {
    a[c] = Vec3(random(), random(), random());
    for (int k = 0; k < 9; ++k) b[c](k / 3, k % 3) = 0.05 * random();
  }
  Eigen::VectorXd v(3 * nv), noise(3 * nv);
  for (int i = 0; i < nv; ++i) {
    const int c = cells.vertex_cell[i];
    v.segment<3>(3 * i) = a[c] + b[c] * (cells.x.col(i) - Vec3(1, 2, 3));
    for (int k = 0; k < 3; ++k) noise(3 * i + k) = random();
  }
  EXPECT_LT((affinePart(cells, sim.geometry(), v) - v).norm(), 1e-10 * v.norm());

  Topology topo;
  updateTopology(cells, topo);
  const StepContext ctx{cells, sim.geometry(), topo, 0.5, 0.0, &sim.contacts(), 0.0};
  ForceTerms terms;
  terms.push_back(std::make_unique<MediumDrag>(s.cells));
  terms.push_back(std::make_unique<CortexViscosity>(s.cells));
  terms.push_back(std::make_unique<ContactFriction>(s.cells));
  FrictionOperator op;
  const Eigen::Matrix3Xd f = Eigen::Matrix3Xd::Zero(3, nv);
  const Dissipation all = dissipation({ctx, f, v, terms, op});
  const CellScaleDissipation cell = cellScaleDissipation({ctx, f, v, terms, op});
  ASSERT_GT(all.friction_t, 0);
  EXPECT_NEAR(cell.medium_affine, all.medium, 1e-9 * all.medium);
  EXPECT_NEAR(cell.cortex_affine, all.cortex, 1e-9 * all.cortex);
  EXPECT_NEAR(cell.friction_t_affine, all.friction_t, 1e-9 * all.friction_t);
  EXPECT_NEAR(cell.friction_n_affine, all.friction_n, 1e-9 * all.friction_n);
  EXPECT_GT(cell.cortex_jitter, 0);  // a linear field is not its ring's mean at a curved shell

  const Eigen::VectorXd rest = noise - affinePart(cells, sim.geometry(), noise);
  EXPECT_LT(affinePart(cells, sim.geometry(), rest).norm(), 1e-10 * rest.norm());

  Eigen::VectorXd move(3 * nv), same(3 * nv);
  double v2 = 0;
  for (int c = 0; c < nc; ++c) v2 += a[c].squaredNorm() / nc;
  for (int i = 0; i < nv; ++i) {
    move.segment<3>(3 * i) = a[cells.vertex_cell[i]];
    same.segment<3>(3 * i) = a[0];
  }
  const CellSpeeds speeds = cellSpeeds(cells, sim.geometry(), &sim.contacts(), move);
  EXPECT_NEAR(speeds.rms_um_min, 60 * std::sqrt(v2), 1e-12 * speeds.rms_um_min);
  EXPECT_GT(speeds.relative_rms_um_min, 0);
  EXPECT_NEAR(cellSpeeds(cells, sim.geometry(), &sim.contacts(), same).relative_rms_um_min, 0,
              1e-12);
  EXPECT_TRUE(std::isnan(cellSpeeds(cells, sim.geometry(), nullptr, same).relative_rms_um_min));
  EXPECT_LT(ringJitter(topo, same).norm(), 1e-12 * same.norm());
  const CellScaleDissipation moved = cellScaleDissipation({ctx, f, move, terms, op});
  EXPECT_LT(moved.cortex_jitter, 1e-12 * all.cortex);
  EXPECT_NEAR(moved.speeds.rms_um_min, speeds.rms_um_min, 1e-12 * speeds.rms_um_min);
}

// ---- observe.torque

// A rigid motion V + ω × (x − p) is its own rigid part: ω, and the velocity of the centroid.
TEST(ProbesCells, RigidPartOfARigidMotion) {
  Simulation sim(fiveCells());
  const CellSet& cells = sim.cells();
  const Vec3 velocity(0.3, -0.1, 0.2), spin(-0.02, 0.05, 0.01), pivot(4, -2, 1);
  Eigen::VectorXd v(3 * cells.numVertices());
  for (int i = 0; i < cells.numVertices(); ++i)
    v.segment<3>(3 * i) = velocity + spin.cross(Vec3(cells.x.col(i)) - pivot);
  const RigidPart r = rigidPart(cells, sim.geometry(), v);
  EXPECT_LT((r.spin - spin).norm(), 1e-12);
  EXPECT_LT((r.velocity - (velocity + spin.cross(r.centroid - pivot))).norm(), 1e-12);
}

// A passive fusion's forces are the cells' own and their pairs': no net force or torque. Solved
// tightly, the torques of the friction terms on v balance: their shares along the medium's sum
// to 1, the springs' among them where Γ carries the springs.
TEST(ProbesCells, PassiveFusionTorquesBalance) {
  SceneSpec s = smallFusionSpec(5, 3, 4, 4, 1);
  s.cells.p_a = 0;
  s.numerics.integrator = IntegratorKind::ContactImplicitConsistent;
  s.numerics.cg_tol = 1e-10;
  s = resolve(s);
  Simulation sim(s);
  int seen = 0;
  sim.onStartSolve([&](const StartSolve& solve) {
    const BodyTorques b = bodyTorques(solve);
    const RigidPart r = rigidPart(solve.ctx.cells, solve.ctx.geo, solve.v);
    double force = 0, torque = 0;
    for (int i = 0; i < solve.ctx.cells.numVertices(); ++i) {
      force += solve.f.col(i).norm();
      torque += (Vec3(solve.ctx.cells.x.col(i)) - r.centroid).norm() * solve.f.col(i).norm();
    }
    EXPECT_LT(b.net_force_nn, 1e-10 * force);
    EXPECT_LT(b.net_torque_nnum, 1e-10 * torque);
    EXPECT_GT(b.torque_medium_nnum, 0);
    EXPECT_NEAR(b.share_cortex + b.share_friction + b.share_springs, 1.0, 1e-6);
    EXPECT_NE(b.share_springs, 0);
    EXPECT_NEAR(b.rigid_spin_deg_h, 3600 * r.spin.norm() * 180 / M_PI, 1e-12);
    ++seen;
  });
  for (int k = 0; k < 4; ++k) ASSERT_TRUE(sim.step().ok());
  EXPECT_GE(seen, 4);
}
