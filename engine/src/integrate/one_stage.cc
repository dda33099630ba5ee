// The one-stage schemes: forward Euler in the positions with the velocity of the start,
// Γ(x₀) v = F(x₀). Semi-implicit leaves the contact springs explicit (stable only while Δt is
// below their time scale, docs/stability-doublet.md); contact-implicit adds their linearised
// normal stiffness, (Γ + Δt K_c) v = F, a backward-Euler step of the springs: one spring per pair
// at its contact point, or (contact-implicit-consistent) the consistent stiffness of the spring
// field, k ∫ λλ dS, without which the cells' motion depends on Δt as 1/(1 + a Δt)
// (docs/science/motion-convergence.md).
//
// The error estimate: x₁ = x₀ + Δt v₀ is first order, its local error Δt²/2 |dv/dt|; with dv/dt
// from the velocity of the step before (the warm start, carried by the cells through remeshes and
// rollbacks), Δt/2 · max_i |v_i − v_i^prev| (µm). numerics.max_step_error_um rejects a step above
// it (retried at half Δt, adaptive schedule); the first step has no estimate.
#include <cmath>

#include "activefoam/spec.h"
#include "activefoam/step_guards.h"
#include "activefoam/time_scheme.h"

namespace activefoam {
namespace {

class OneStage : public TimeScheme {
 public:
  OneStage(bool contact_implicit, bool consistent)
      : implicit_(contact_implicit), consistent_(consistent) {}
  std::string_view name() const override {
    return !implicit_    ? "semi-implicit"
           : consistent_ ? "contact-implicit-consistent"
                         : "contact-implicit";
  }
  double contactStiffnessDt(double dt) const override { return implicit_ ? dt : 0.0; }
  bool consistentStiffness() const override { return implicit_ && consistent_; }
  void addGuards(const NumericsParams& n,
                 std::vector<std::unique_ptr<StepGuard>>& guards) const override {
    if (n.max_step_error_um > 0) guards.push_back(stepErrorGuard());
  }
  SchemeResult solve(SchemeState& s, const StepContext& ctx) override {
    SchemeResult r;
    timed(s.times.forces, [&] { s.solver.computeForces(ctx, s.terms, s.f); });
    timed(s.times.matrix, [&] { s.solver.prepareFriction(ctx, s.terms); });
    v_prev_ = s.v;
    timed(s.times.solve, [&] { r.cg = s.solver.solve(s.f, s.v); });
    // A cell set that never stepped has no velocity yet (all zero): no estimate.
    if (v_prev_.size() == s.v.size() && v_prev_.any()) {
      double e2 = 0;
      for (Eigen::Index i = 0; i < s.v.size(); i += 3)
        e2 = std::max(e2, (s.v.segment<3>(i) - v_prev_.segment<3>(i)).squaredNorm());
      r.step_error_um = 0.5 * ctx.dt * std::sqrt(e2);
    }
    return r;
  }

 private:
  bool implicit_;
  bool consistent_;
  Eigen::VectorXd v_prev_;  // the warm start: the step before's velocity
};

}  // namespace

std::unique_ptr<TimeScheme> makeOneStage(bool contact_implicit, bool consistent_stiffness) {
  return std::make_unique<OneStage>(contact_implicit, consistent_stiffness);
}

}  // namespace activefoam
