// One interface for every physical contribution (docs/model.md §2–§5): a term adds forces (and
// returns its energy where it has one), adds its SPD friction to Γ, and may update its state
// after the position update. Terms are listed explicitly in Simulation, not registered by macros.
#pragma once

#include <cstdint>
#include <string_view>

#include <Eigen/Core>

#include "activefoam/cellset.h"
#include "activefoam/friction_operator.h"
#include "activefoam/geometry.h"

namespace activefoam {

struct ContactList;

struct StepContext {
  const CellSet& cells;
  const Geometry& geo;
  const Topology& topo;
  double dt;  // s, this step's length (the integrator's, not the spec's)
  double t;   // s, time at the start of the step
  const ContactList* contacts = nullptr;  // this step's contacts; null in single-cell scenes
  // Factor of the contact springs' linearised normal stiffness K_c in Γ: Δt for the
  // contact-implicit integrator, 0 for the semi-implicit one (the integrator decides).
  double contact_stiffness_dt = 0;
  // How K_c spreads a pair's spring over its vertices: false, one spring at the pair's centroid
  // (w_ik = λ_i^A(c) λ_k^B(c), the friction's weights); true, the consistent stiffness of the
  // spring field, k ∫ λλ dS (ros2: its accuracy at large Δt depends on K_c being the Jacobian).
  bool consistent_stiffness = false;
  // Factor of the surface tension's out-of-plane stiffness in Γ (numerics.tension_implicit):
  // contact_stiffness_dt where the key is on, else 0 (explicit).
  double tension_stiffness_dt = 0;
  // s, time at the end of the step as the stepper counts it (exactly the next step's t); 0: t + dt.
  double t_end = 0;
  double endTime() const { return t_end > 0 ? t_end : t + dt; }
  // For endStep of a two-stage (ros2) step: the geometry at the predicted end of the step, so
  // that per-cell integrals take the trapezoid of start and end (what ROS2 gives them, its
  // Jacobian there being 0). Null: forward Euler with the start (one-stage integrators).
  const Geometry* geo_end = nullptr;
};

// The context c at another geometry (and predicted end), everything else as in c.
inline StepContext atGeometry(const StepContext& c, const Geometry& geo, const Geometry* geo_end) {
  return {c.cells,
          geo,
          c.topo,
          c.dt,
          c.t,
          c.contacts,
          c.contact_stiffness_dt,
          c.consistent_stiffness,
          c.tension_stiffness_dt,
          c.t_end,
          geo_end};
}

class ForceTerm {
 public:
  virtual ~ForceTerm() = default;
  virtual std::string_view name() const = 0;
  // Adds this term's nodal forces (nN) to f (3 × numVertices). Returns the term's energy (nN·µm)
  // for conservative terms, 0 otherwise.
  virtual double addForces(const StepContext& /*ctx*/, Eigen::Matrix3Xd& /*f*/) const { return 0; }
  // Adds this term's friction (nN·s/µm) to this step's Γ: diagonal blocks into op.diagonal(),
  // and for a term that couples vertices its couplings (op.coupling), made from the geometry
  // and contacts of ctx, which do not change while Γ is in use.
  virtual void addFriction(const StepContext& /*ctx*/, FrictionOperator& /*op*/) const {}
  // Updates per-cell state once the step is taken (positions already advanced).
  virtual void endStep(const StepContext& /*ctx*/, CellSet& /*cells*/) const {}
};

}  // namespace activefoam
