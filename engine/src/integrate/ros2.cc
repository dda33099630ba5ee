// ROS2 (Verwer, Spee, Blom & Hundsdorfer 1999): a linearly implicit two-stage method of order 2
// for any approximation of the Jacobian (a W-method), L-stable with γ = 1 + 1/√2:
//   (Γ₀ + γΔt K₀) k₁ = F(x₀)
//   (Γ* + γΔt K*) k₂ = F(x*) − 2 Γ* k₁,   x* = x₀ + Δt k₁ (geometry and contacts re-evaluated)
//   x₁ = x₀ + Δt (3/2 k₁ + 1/2 k₂)
// Stage 2 takes its matrix at the predicted state: the W-matrix may change by O(Δt) between
// stages without losing the order, and Γ* k₁ is what the mass-matrix form needs there. K is the
// consistent stiffness of the contact springs (its accuracy at large Δt depends on K being the
// Jacobian).
#include <algorithm>
#include <cmath>
#include <sstream>

#include "activefoam/spec.h"
#include "activefoam/terms.h"
#include "activefoam/time_scheme.h"

namespace activefoam {
namespace {

class Ros2 : public TimeScheme {
 public:
  Ros2(const NumericsParams& n, bool consistent) : cg_tol_(n.cg_tol), consistent_(consistent) {}
  std::string_view name() const override { return "ros2"; }
  double contactStiffnessDt(double dt) const override { return kRos2Gamma * dt; }
  bool consistentStiffness() const override { return consistent_; }
  // With numerics.max_step_error_um > 0: rejects a step whose error estimate exceeds it.
  void addGuards(const NumericsParams& n,
                 std::vector<std::unique_ptr<StepGuard>>& guards) const override {
    if (n.max_step_error_um > 0) guards.push_back(stepErrorGuard());
  }
  SchemeResult solve(SchemeState& s, const StepContext& ctx) override;
  // x₀ + Δt v: the stages left the cells at x*.
  void advance(CellSet& cells, double dt) const override {
    cells.x = x0_;
    cells.x += dt * cells.v;
  }
  // x* is the end of the step as the first stage predicts it: per-cell integrals take the
  // trapezoid of start and end (what ROS2 gives them, its Jacobian there being 0).
  const Geometry* predictedEnd(const SchemeState& s) const override { return &s.geo; }

 private:
  double cg_tol_;
  bool consistent_;
  Eigen::Matrix3Xd x0_, k1_, f2_;  // start positions, first stage, second stage's F
  Eigen::VectorXd g_, k2_;         // Γ* k₁, the second stage
  std::vector<double> pi0_;        // the PI integrals at the start of the step
};

SchemeResult Ros2::solve(SchemeState& s, const StepContext& ctx) {
  SchemeResult r;
  const double dt = ctx.dt;
  timed(s.times.forces, [&] { s.solver.computeForces(ctx, s.terms, s.f); });
  timed(s.times.matrix, [&] { s.solver.prepareFriction(ctx, s.terms); });
  timed(s.times.solve, [&] { r.cg = s.solver.solve(s.f, s.v); });
  // What an observer sees of the step: the first stage, (Γ₀ + γΔt K₀) k₁ = F(x₀), the one solve
  // at the start (the step moves by 3/2 k₁ + 1/2 k₂, which differs from k₁ by O(Δt)).
  s.startSolved(ctx);
  s.keepStart();

  // Stage 1 must be usable before anything is evaluated at x*: NaNs in the broad phase, or a
  // prediction from an unconverged solve, would only produce a later, less clear failure.
  std::ostringstream why;
  if (!s.v.allFinite() || !s.f.allFinite()) {
    why << "non-finite " << (s.f.allFinite() ? "velocity" : "force")
        << " in the first stage at t=" << ctx.t << " s";
    r.failure = StepFailure{FailureKind::NonFinite, why.str()};
    return r;
  }
  if (!r.cg.converged) {
    why << "CG did not reach the tolerance " << cg_tol_ << " in " << r.cg.iterations
        << " iterations in the first stage (relative residual " << r.cg.residual
        << ") at t=" << ctx.t << " s";
    r.failure = StepFailure{FailureKind::CgNotConverged, why.str()};
    return r;
  }
  CellSet& cells = s.cells;
  x0_ = cells.x;
  k1_ = Eigen::Map<const Eigen::Matrix3Xd>(s.v.data(), 3, cells.numVertices());
  cells.x = x0_ + dt * k1_;
  timed(s.times.geometry, [&] { computeGeometry(cells, s.geo); });
  timed(s.times.contacts, [&] { s.detect(); });

  StepContext predicted = atGeometry(ctx, s.geo, nullptr);
  // The pressure at x* with the PI integral predicted as ROS2 predicts every state variable,
  // I* = I₀ + Δt ε₀; I₀ is restored for the end of the step.
  pi0_ = cells.pi_integral;
  for (const auto& term : s.terms)
    if (const auto* p = dynamic_cast<const CytoplasmPressure*>(term.get()))
      p->endStep(atGeometry(predicted, s.geo_start, nullptr), cells);
  timed(s.times.forces, [&] { s.solver.computeForces(predicted, s.terms, f2_); });
  cells.pi_integral = pi0_;
  // Γ* k₁ without the spring stiffness, then Γ* + γΔt K* for the solve.
  timed(s.times.matrix, [&] {
    const double stiffness = predicted.contact_stiffness_dt;
    predicted.contact_stiffness_dt = 0;
    s.solver.prepareFriction(predicted, s.terms);
    g_.resize(k1_.size());
    s.solver.applyFriction(k1_.data(), g_.data());
    predicted.contact_stiffness_dt = stiffness;
    s.solver.prepareFriction(predicted, s.terms);
  });
  f2_ -= 2 * Eigen::Map<const Eigen::Matrix3Xd>(g_.data(), 3, cells.numVertices());
  SolveStats s2;
  timed(s.times.solve, [&] {
    k2_ = -s.v;  // k₂ ≈ −k₁ where the forces change little over the step
    s2 = s.solver.solve(f2_, k2_, /*reuse_factor=*/true);
  });
  r.cg.iterations += s2.iterations;
  r.cg.converged = r.cg.converged && s2.converged;
  r.cg.residual = std::max(r.cg.residual, s2.residual);
  // x₁ − (x₀ + Δt k₁) = Δt/2 (k₁ + k₂): the embedded first-order step's distance, the estimate.
  double e2 = 0;
  for (Eigen::Index i = 0; i < s.v.size(); i += 3)
    e2 = std::max(e2, (s.v.segment<3>(i) + k2_.segment<3>(i)).squaredNorm());
  r.step_error_um = 0.5 * dt * std::sqrt(e2);
  s.v = 1.5 * s.v + 0.5 * k2_;  // the step's effective velocity: x₁ = x₀ + Δt v
  return r;
}

}  // namespace

std::unique_ptr<TimeScheme> makeRos2(const NumericsParams& numerics, bool consistent_stiffness) {
  return std::make_unique<Ros2>(numerics, consistent_stiffness);
}

}  // namespace activefoam
