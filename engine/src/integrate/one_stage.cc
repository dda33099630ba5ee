// The one-stage schemes: forward Euler in the positions with the velocity of the start,
// Γ(x₀) v = F(x₀). Semi-implicit leaves the contact springs explicit (stable only while Δt is
// below their time scale, docs/stability-doublet.md); contact-implicit adds their linearised
// normal stiffness, (Γ + Δt K_c) v = F, a backward-Euler step of the springs: one spring per pair
// at its contact point, or (contact-implicit-consistent) the consistent stiffness of the spring
// field, k ∫ λλ dS, without which the cells' motion depends on Δt as 1/(1 + a Δt)
// (docs/science/motion-convergence.md).
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
  SchemeResult solve(SchemeState& s, const StepContext& ctx) override {
    SchemeResult r;
    timed(s.times.forces, [&] { s.solver.computeForces(ctx, s.terms, s.f); });
    timed(s.times.matrix, [&] { s.solver.prepareFriction(ctx, s.terms); });
    timed(s.times.solve, [&] { r.cg = s.solver.solve(s.f, s.v); });
    s.startSolved(ctx);
    return r;
  }

 private:
  bool implicit_;
  bool consistent_;
};

}  // namespace

std::unique_ptr<TimeScheme> makeOneStage(bool contact_implicit, bool consistent_stiffness) {
  return std::make_unique<OneStage>(contact_implicit, consistent_stiffness);
}

}  // namespace activefoam
