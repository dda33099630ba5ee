// A time scheme is one file: Heun's method (the explicit trapezoid) written here, outside the
// engine, and handed to Simulation, is second order on a relaxing cell.
#include <array>
#include <cmath>
#include <iostream>
#include <memory>
#include <string>

#include <gtest/gtest.h>

#include "activefoam/run.h"
#include "activefoam/terms.h"
#include "activefoam/time_scheme.h"
#include "test_support.h"

namespace activefoam {
namespace {

// Heun: k₁ = Γ(x₀)⁻¹ F(x₀), k₂ = Γ(x*)⁻¹ F(x*) at x* = x₀ + Δt k₁, x₁ = x₀ + Δt (k₁ + k₂)/2.
// Contact springs explicit; the PI integral is predicted at x* as ros2 predicts it.
class Heun : public TimeScheme {
 public:
  std::string_view name() const override { return "heun"; }
  SchemeResult solve(SchemeState& s, const StepContext& ctx) override {
    SchemeResult r;
    s.solver.computeForces(ctx, s.terms, s.f);
    s.solver.prepareFriction(ctx, s.terms);
    r.cg = s.solver.solve(s.f, s.v);
    s.keepStart();
    x0_ = s.cells.x;
    k1_ = s.v;
    s.cells.x = x0_ + ctx.dt * Eigen::Map<const Eigen::Matrix3Xd>(k1_.data(), 3, x0_.cols());
    computeGeometry(s.cells, s.geo);
    s.detect();
    const StepContext predicted = atGeometry(ctx, s.geo, nullptr);
    const std::vector<double> pi0 = s.cells.pi_integral;
    for (const auto& term : s.terms)
      if (const auto* p = dynamic_cast<const CytoplasmPressure*>(term.get()))
        p->endStep(atGeometry(predicted, s.geo_start, nullptr), s.cells);
    s.solver.computeForces(predicted, s.terms, f2_);
    s.cells.pi_integral = pi0;
    s.solver.prepareFriction(predicted, s.terms);
    const SolveStats s2 = s.solver.solve(f2_, s.v);  // warm start: k₁
    r.cg.iterations += s2.iterations;
    r.cg.converged = r.cg.converged && s2.converged;
    s.v = 0.5 * (k1_ + s.v);
    return r;
  }
  void advance(CellSet& cells, double dt) const override {
    cells.x = x0_;
    cells.x += dt * cells.v;
  }
  const Geometry* predictedEnd(const SchemeState& s) const override { return &s.geo; }

 private:
  Eigen::Matrix3Xd x0_, f2_;
  Eigen::VectorXd k1_;
};

// An elongated cell relaxing (tension, pressure with its PI integral, cortex viscosity, medium
// drag; no remeshing, no noise): positions after 4 s.
Eigen::Matrix3Xd positionsAfter(std::unique_ptr<TimeScheme> scheme, double dt) {
  SceneSpec s = testing::cellSpec(2.2, 80);
  s.numerics.dt_s = dt;
  s.numerics.remesh_every_s = 0;
  s.numerics.adaptive = false;
  s.numerics.cg_tol = 1e-11;
  s.numerics.cg_max_iter = 5000;
  const double r = s.cells.radius_mean_um;
  CellSet cells;
  cells.addCell(ellipsoidCell(r, 2.2, 80, Vec3::Zero()), r);
  Simulation sim(s, std::move(cells), std::move(scheme));
  while (sim.time() < 4.0 - 1e-9) {
    const StepReport rep = sim.step();
    if (!rep.ok()) ADD_FAILURE() << sim.scheme().name() << " at dt " << dt << ": " << rep.reason;
    if (!rep.ok()) break;
  }
  return sim.cells().x;
}

// Max vertex position errors at Δt, Δt/2, Δt/4 against the same scheme at Δt/32.
template <class Make>
std::array<double, 3> errors(Make make, double dt) {
  const Eigen::Matrix3Xd ref = positionsAfter(make(), dt / 32);
  std::array<double, 3> e{};
  for (int i = 0; i < 3; ++i)
    e[i] = (positionsAfter(make(), std::ldexp(dt, -i)) - ref).colwise().norm().maxCoeff();
  std::cout << "[ order ] " << make()->name() << ": max error " << e[0] << " / " << e[1] << " / "
            << e[2] << " µm, ratios " << e[0] / e[1] << ", " << e[1] / e[2] << "\n";
  return e;
}

}  // namespace

// Against a reference at Δt/32 a first-order scheme's error ratios are 2.1 and 2.3, a second-order
// one's 4.0 and 4.1.
TEST(TimeScheme, AThirdSchemeFromATestFileIsSecondOrder) {
  const auto heun = errors([] { return std::make_unique<Heun>(); }, 0.1);
  EXPECT_GT(heun[0] / heun[1], 3.5);
  EXPECT_GT(heun[1] / heun[2], 3.5);
  // The one-stage scheme through the same driver is first order, and far less accurate.
  const auto euler = errors([] { return makeOneStage(false); }, 0.1);
  EXPECT_LT(euler[0] / euler[1], 2.5);
  EXPECT_LT(20 * heun[0], euler[0]);
  // Without contact stiffness ROS2 is Heun: k₂ = Γ*⁻¹F* − 2k₁, so x₀ + Δt (3/2 k₁ + 1/2 k₂) =
  // x₀ + Δt (k₁ + Γ*⁻¹F*)/2. The engine's ros2 and this file's Heun agree to the CG tolerance.
  NumericsParams ros2;
  ros2.integrator = IntegratorKind::Ros2;
  const auto r = errors([&] { return makeTimeScheme(ros2); }, 0.1);
  for (int i = 0; i < 3; ++i) EXPECT_NEAR(heun[i], r[i], 1e-6 * r[i]);
}

TEST(TimeScheme, EachIntegratorOfTheSpecHasItsScheme) {
  for (IntegratorKind kind : {IntegratorKind::SemiImplicit, IntegratorKind::ContactImplicit,
                              IntegratorKind::Ros2, IntegratorKind::ContactImplicitConsistent}) {
    NumericsParams n;
    n.integrator = kind;
    const auto scheme = makeTimeScheme(n);
    EXPECT_EQ(scheme->name(), toString(kind));
    EXPECT_EQ(scheme->contactStiffnessDt(1.0) > 0, kind != IntegratorKind::SemiImplicit);
    EXPECT_EQ(scheme->consistentStiffness(),
              kind == IntegratorKind::Ros2 || kind == IntegratorKind::ContactImplicitConsistent);
  }
}

// The consistent step at Δt 2 s oscillates (docs/study/stability-map.md: every k_AB and
// motility of the doublet's map) because the tension is explicit: a vertex-scale ripple along
// the normal, damped only by the cortex's out-of-plane viscosity ε_n η, has a time scale near
// 1 s, and forward Euler reverses it every step beyond twice that. With the tension's normal
// stiffness in Γ (numerics.tension_implicit) the same doublet holds 2 s without a step redone.
TEST(TimeScheme, TheImplicitTensionHoldsTheConsistentStepAtTwoSeconds) {
  SceneSpec s;  // examples/doublet.toml: two equal passive cells 50 nm apart
  s.scene = SceneKind::Doublet;
  s.seed = 1;
  s.cells.radius_gamma_k = 0;
  s.cells.p_a = 0;
  s.numerics.dt_s = 2;
  s.numerics.adaptive = false;
  s.duration_s = 240;
  s.sample_every_s = 240;
  s.snapshot_every_s = 0;
  ASSERT_TRUE(validate(s).empty());
  s = resolve(s);
  const RunSummary explicit_tension = runScene(s, RunObserver{});
  EXPECT_EQ(explicit_tension.failure, FailureKind::ContactOscillation)
      << explicit_tension.steps << " steps: " << explicit_tension.reason;
  s.numerics.tension_implicit = true;
  const RunSummary implicit_tension = runScene(s, RunObserver{});
  EXPECT_TRUE(implicit_tension.ok()) << implicit_tension.reason;
  EXPECT_EQ(implicit_tension.steps, 120);
}

}  // namespace activefoam
