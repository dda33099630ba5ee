// Force terms against finite-difference gradients of their energies, and conservation laws.
#include <cmath>
#include <iostream>

#include <gtest/gtest.h>

#include "activefoam/terms.h"
#include "test_support.h"

using namespace activefoam;
using activefoam::testing::cellSpec;
using activefoam::testing::jiggle;

namespace {

struct Fixture {
  CellSet cells;
  Geometry geo;
  Topology topo;
  explicit Fixture(CellSet c) : cells(std::move(c)) { refresh(); }
  void refresh() {
    updateTopology(cells, topo);
    computeGeometry(cells, geo);
  }
  StepContext ctx() const { return {cells, geo, topo, 0.1, 0.0}; }
  double energy(const ForceTerm& term) {
    computeGeometry(cells, geo);
    Eigen::Matrix3Xd f = Eigen::Matrix3Xd::Zero(3, cells.numVertices());
    return term.addForces(ctx(), f);
  }
  Eigen::Matrix3Xd forces(const ForceTerm& term) {
    computeGeometry(cells, geo);
    Eigen::Matrix3Xd f = Eigen::Matrix3Xd::Zero(3, cells.numVertices());
    term.addForces(ctx(), f);
    return f;
  }
};

CellSet deformedCell(std::uint64_t seed, int triangles = 320) {
  const SceneSpec s = cellSpec(1.3, triangles);
  CellSet cells = buildScene(s);
  jiggle(cells, 0.4, seed);
  cells.x.colwise() += Vec3(5.0, -3.0, 2.0);  // away from the origin: no accidental symmetry
  return cells;
}

// Central finite differences of the term's energy over every coordinate; returns
// |F + ∇E| / |F| over the whole force vector.
double gradientError(Fixture& fx, const ForceTerm& term) {
  const Eigen::Matrix3Xd f = fx.forces(term);
  Eigen::Matrix3Xd grad(3, fx.cells.numVertices());
  const double h = 1e-5;  // µm; truncation O(h²) far below roundoff here
  for (int i = 0; i < fx.cells.numVertices(); ++i) {
    for (int k = 0; k < 3; ++k) {
      const double x0 = fx.cells.x(k, i);
      fx.cells.x(k, i) = x0 + h;
      const double ep = fx.energy(term);
      fx.cells.x(k, i) = x0 - h;
      const double em = fx.energy(term);
      fx.cells.x(k, i) = x0;
      grad(k, i) = (ep - em) / (2 * h);
    }
  }
  computeGeometry(fx.cells, fx.geo);
  return (f + grad).norm() / f.norm();
}

}  // namespace

TEST(SurfaceTension, ForceIsMinusGradientOfTensionTimesArea) {
  for (std::uint64_t seed : {1, 2, 3}) {
    Fixture fx(deformedCell(seed));
    SurfaceTension term(cellSpec().cells);
    const double err = gradientError(fx, term);
    EXPECT_LT(err, 1e-6) << "seed " << seed;
    // The energy is γ·area.
    EXPECT_NEAR(fx.energy(term), cellSpec().cells.gamma * fx.geo.cell_area[0], 1e-9);
  }
}

// numerics.tension_implicit: the stiffness the tension adds to Γ (per unit Δt) is the Hessian
// of γ·area for displacements along the surface's normal. On a round cell and a vertex-scale
// normal ripple u = φ_i n̂_i (φ_i = ±1: the mode that oscillated at Δt 2 s), uᵀKu against the
// energy's second difference (E(x + εu) + E(x − εu) − 2E(x)) / ε²: the two differ by the
// sphere's 2φ²/R² term (≈ (h/R)² of the ripple's |∇φ|²) and the bisector's tilt against the
// vertex normals. It adds nothing without the factor, and nothing for a translation.
TEST(SurfaceTension, ImplicitStiffnessIsTheAreasHessianAlongTheNormal) {
  for (int triangles : {320, 1280}) {
    Fixture fx(buildScene(cellSpec(1.0, triangles)));
    const CellParams p = cellSpec().cells;
    SurfaceTension term(p);
    FrictionOperator none;
    none.reset(fx.cells.numVertices(), fx.cells.topology_version);
    term.addFriction(fx.ctx(), none);
    EXPECT_EQ(none.assembled().norm(), 0.0);

    StepContext ctx = fx.ctx();
    ctx.tension_stiffness_dt = 2.0;
    FrictionOperator op;
    op.reset(fx.cells.numVertices(), fx.cells.topology_version);
    term.addFriction(ctx, op);
    const int n = fx.cells.numVertices();
    Rng rng(5, 1);
    Eigen::VectorXd u(3 * n), y(3 * n);
    for (int i = 0; i < n; ++i)
      u.segment<3>(3 * i) = (rng.uniform() < 0.5 ? -1.0 : 1.0) * fx.geo.vertex_normal[i];
    op.apply(u.data(), y.data());
    const double form = u.dot(y) / ctx.tension_stiffness_dt;
    EXPECT_NEAR(u.dot(op.assembled() * u) / ctx.tension_stiffness_dt, form, 1e-12 * form);

    const Eigen::Matrix3Xd x0 = fx.cells.x;
    const double eps = 1e-3;  // µm
    const double e0 = fx.energy(term);
    fx.cells.x = x0 + eps * Eigen::Map<const Eigen::Matrix3Xd>(u.data(), 3, n);
    const double ep = fx.energy(term);
    fx.cells.x = x0 - eps * Eigen::Map<const Eigen::Matrix3Xd>(u.data(), 3, n);
    const double em = fx.energy(term);
    fx.cells.x = x0;
    computeGeometry(fx.cells, fx.geo);
    const double hessian = (ep + em - 2 * e0) / (eps * eps);
    std::cout << "[ tension  ] " << triangles << " triangles: uᵀKu " << form << ", uᵀHu " << hessian
              << "\n";
    EXPECT_NEAR(form / hessian, 1.0, 0.02) << triangles << " triangles";  // 0.8 %, 0.2 %

    // A translation moves no vertex relative to another: no force.
    for (int i = 0; i < n; ++i) u.segment<3>(3 * i) = Vec3(0.3, -1.0, 2.0);
    op.apply(u.data(), y.data());
    EXPECT_LT(y.norm(), 1e-12 * op.assembled().norm() * u.norm());
  }
}

TEST(CytoplasmPressure, ForceIsMinusGradientOfPressureWork) {
  for (std::uint64_t seed : {4, 5}) {
    Fixture fx(deformedCell(seed));
    fx.cells.pi_integral[0] = 0.37;  // the frozen integral part acts as a constant pressure
    CytoplasmPressure term(cellSpec().cells);
    EXPECT_LT(gradientError(fx, term), 1e-6) << "seed " << seed;
  }
}

TEST(CytoplasmPressure, PressureLawMatchesS5S6) {
  Fixture fx(deformedCell(6));
  const CellParams p = cellSpec().cells;
  CytoplasmPressure term(p);
  fx.cells.pi_integral[0] = 0.2;
  const double vstar = fx.cells.target_volume[0];
  const double eps = (fx.geo.cell_volume[0] - vstar) / vstar;
  const double expected =
      2 * p.gamma / fx.cells.radius[0] - p.bulk_modulus * eps - p.bulk_modulus / *p.tau_k_s * 0.2;
  EXPECT_NEAR(term.pressure(fx.cells, fx.geo, 0), expected, 1e-14);
}

TEST(InternalForces, SumToZeroAndExertNoTorque) {
  Fixture fx(deformedCell(7));
  fx.cells.pi_integral[0] = -0.1;
  const CellParams p = cellSpec().cells;
  SurfaceTension tension(p);
  CytoplasmPressure pressure(p);
  for (const ForceTerm* term :
       {static_cast<const ForceTerm*>(&tension), static_cast<const ForceTerm*>(&pressure)}) {
    const Eigen::Matrix3Xd f = fx.forces(*term);
    Vec3 sum = Vec3::Zero(), torque = Vec3::Zero();
    double scale = 0;
    for (int i = 0; i < fx.cells.numVertices(); ++i) {
      sum += f.col(i);
      torque += Vec3(fx.cells.x.col(i)).cross(Vec3(f.col(i)));
      scale += f.col(i).norm() * (1 + fx.cells.x.col(i).norm());
    }
    EXPECT_LT(sum.norm(), 1e-12 * scale) << term->name();
    EXPECT_LT(torque.norm(), 1e-12 * scale) << term->name();
  }
}

TEST(FrictionMatrix, DissipativeTermsAreTranslationInvariant) {
  // Viscosity couples velocity differences only: Γ_visc · (uniform v) = 0, so its rows sum to 0,
  // whether applied as the step applies it (diagonal blocks + edge product) or assembled.
  Fixture fx(deformedCell(8));
  const CellParams p = cellSpec().cells;
  CortexViscosity visc(p);
  FrictionOperator op;
  op.reset(fx.cells.numVertices(), fx.cells.topology_version);
  visc.addFriction(fx.ctx(), op);
  const SpMat g = op.assembled();
  Eigen::VectorXd u(3 * fx.cells.numVertices()), y(u.size());
  for (int i = 0; i < fx.cells.numVertices(); ++i) u.segment<3>(3 * i) = Vec3(0.3, -1.0, 2.0);
  EXPECT_LT((g * u).norm(), 1e-12 * g.norm());
  op.apply(u.data(), y.data());
  EXPECT_LT(y.norm(), 1e-12 * g.norm());
}

// The cortex viscosity's dissipation vᵀΓv is Σ over edges of Δvᵀ G Δv, Δv = v_i − v_j and
// G = (η/√3)(n̂n̂ᵀ + t̂t̂ᵀ + ε_n b̂b̂ᵀ) in the edge's frame (S13), built here from the geometry.
TEST(FrictionMatrix, CortexDissipationIsTheSumOverEdges) {
  Fixture fx(deformedCell(8));
  CellParams p = cellSpec().cells;
  p.eps_n = 0.3;  // anisotropic, so that the frame matters
  CortexViscosity visc(p);
  FrictionOperator op;
  op.reset(fx.cells.numVertices(), fx.cells.topology_version);
  visc.addFriction(fx.ctx(), op);
  Rng rng(17, 3);
  Eigen::VectorXd v(3 * fx.cells.numVertices()), y(v.size());
  for (Eigen::Index k = 0; k < v.size(); ++k) v[k] = rng.uniform() - 0.5;
  op.apply(v.data(), y.data());
  double expected = 0;
  for (const Edge& e : fx.topo.edges) {
    const Vec3 n = (fx.cells.x.col(e.j) - fx.cells.x.col(e.i)).normalized();
    const Vec3 b = (fx.geo.tri_normal[e.ta] + fx.geo.tri_normal[e.tb]).normalized();
    const Vec3 bn = (b - b.dot(n) * n).normalized();
    const Vec3 t = bn.cross(n);
    const Vec3 dv = v.segment<3>(3 * e.i) - v.segment<3>(3 * e.j);
    const double dn = dv.dot(n), dt = dv.dot(t), db = dv.dot(bn);
    expected += p.eta / std::sqrt(3.0) * (dn * dn + dt * dt + p.eps_n * db * db);
  }
  EXPECT_NEAR(v.dot(y), expected, 1e-12 * expected);
  EXPECT_NEAR(v.dot(op.assembled() * v), expected, 1e-12 * expected);
}
