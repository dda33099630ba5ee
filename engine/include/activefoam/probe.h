// Probes: what a study asks of a run beyond the scene's observables, each turned on by a key of
// the spec's [observe] table (docs/scenes.md). A probe appends named columns to every sample
// (sampleColumns(spec) lists them after the scene's). It reads the simulation and never changes
// it, so the run's other columns keep their bits; what it remembers (the aggregate at t = 0)
// travels in the run's checkpoints.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "activefoam/mesh.h"
#include "activefoam/spec.h"
#include "activefoam/time_scheme.h"

namespace activefoam {

class Simulation;

class Probe {
 public:
  virtual ~Probe() = default;
  virtual std::vector<std::string> columns() const = 0;
  // Whether it reads the velocity solve of the step (StartSolve): runScene then shows it the
  // solve of every try of a step that ends on a sample. A try that is undone is followed by
  // another that ends on the sample, so the last one shown before sample() is the step taken.
  // (Every scheme of numerics.integrator shows its solve; a caller's scheme that does not leaves
  // such a probe's columns NaN.)
  virtual bool readsSolve() const { return false; }
  virtual void solved(const StartSolve& /*s*/) {}
  // Its values at this sample (t = 0, or the end of the step just taken), one per column.
  virtual void sample(const Simulation& sim, std::vector<double>& out) = 0;
  // Its state as bytes (checkpoints) and back; restore throws std::invalid_argument on
  // malformed bytes.
  virtual std::string save() const { return {}; }
  virtual void restore(const std::string& /*bytes*/) {}
};

// The probes a resolved spec asks for that its scene reads (SpecField::scenes: front ends refuse
// the others), in the key table's order.
std::vector<std::unique_ptr<Probe>> makeProbes(const SceneSpec& spec);
// Their columns, in that order.
std::vector<std::string> probeColumns(const SceneSpec& spec);

// observe.rigid_motion: the aggregate's motion as a rigid body from the cells' centroids `from`
// to `to` (the same cells, in the same order): the angle of the rotation that best carries them
// onto each other about their means (bestRotation, Kabsch), and how far their mean moved.
struct RigidMotion {
  double turn_deg = 0;
  double drift_um = 0;
};
RigidMotion rigidMotion(const std::vector<Vec3>& from, const std::vector<Vec3>& to);

// observe.dissipation: the power of one velocity solve Γ v = F, nW (nN·µm/s). The motion is
// overdamped, so the power the forces put in, vᵀF, leaves through the friction terms, each
// vᵀΓ_term v with Γ_term made by the term's own addFriction from the solve's context; they sum
// to vᵀΓv, which equals vᵀF up to the CG residual, |vᵀ(Γv − F)| ≤ ε_CG |v| |F|.
struct Dissipation {
  double medium = 0;      // MediumDrag
  double cortex = 0;      // CortexViscosity
  double friction_t = 0;  // ContactFriction across the contact plane (ξ∥)
  double friction_n = 0;  // ContactFriction along the normal (ξ⊥)
  // The contact springs' stiffness that Γ carries (Δt vᵀK_c v, γΔt for ros2; 0 for the
  // semi-implicit integrator): no dissipation of the model, the springs' force taken at the end
  // of the step.
  double springs = 0;
  double forces = 0;  // vᵀF
  double active = 0;  // vᵀF_active, ActiveMigration's forces alone
};
Dissipation dissipation(const StartSolve& s);
// vᵀΓ_term v, Γ_term made by the term alone from `ctx`.
double frictionPower(const ForceTerm& term, const StepContext& ctx, const Eigen::VectorXd& v);

}  // namespace activefoam
