// The one-stage schemes: forward Euler in the positions with the velocity of the start,
// Γ(x₀) v = F(x₀). Semi-implicit leaves the contact springs explicit (stable only while Δt is
// below their time scale, docs/stability-doublet.md); contact-implicit adds their linearised
// normal stiffness, (Γ + Δt K_c) v = F, a backward-Euler step of the springs.
#include "activefoam/time_scheme.h"

namespace activefoam {
namespace {

class OneStage : public TimeScheme {
 public:
  explicit OneStage(bool contact_implicit) : implicit_(contact_implicit) {}
  std::string_view name() const override {
    return implicit_ ? "contact-implicit" : "semi-implicit";
  }
  double contactStiffnessDt(double dt) const override { return implicit_ ? dt : 0.0; }
  SchemeResult solve(SchemeState& s, const StepContext& ctx) override {
    SchemeResult r;
    timed(s.times.forces, [&] { s.solver.computeForces(ctx, s.terms, s.f); });
    timed(s.times.matrix, [&] { s.solver.prepareFriction(ctx, s.terms); });
    timed(s.times.solve, [&] { r.cg = s.solver.solve(s.f, s.v); });
    return r;
  }

 private:
  bool implicit_;
};

}  // namespace

std::unique_ptr<TimeScheme> makeOneStage(bool contact_implicit) {
  return std::make_unique<OneStage>(contact_implicit);
}

}  // namespace activefoam
