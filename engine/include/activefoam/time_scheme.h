// How a step finds its velocity (docs/model.md §6.2): one TimeScheme per integrator, each in a file
// of its own (one_stage.cc, ros2.cc). makeTimeScheme is the one place that maps
// numerics.integrator to a scheme; Simulation takes any scheme (tests add their own). Simulation
// tries a step, runs the guards, rolls back and remeshes; a scheme decides only what is solved
// for the velocity v of x₁ = x₀ + Δt v, and what Γ carries besides friction.
#pragma once

#include <chrono>
#include <functional>
#include <memory>
#include <optional>
#include <string_view>
#include <utility>
#include <vector>

#include <Eigen/Core>

#include "activefoam/cellset.h"
#include "activefoam/force_term.h"
#include "activefoam/geometry.h"
#include "activefoam/solver.h"
#include "activefoam/step_guards.h"
#include "activefoam/velocity_solver.h"

namespace activefoam {

struct NumericsParams;

// Accumulated wall time per phase, seconds.
struct PhaseTimes {
  double geometry = 0, contacts = 0, forces = 0, matrix = 0, solve = 0, remesh = 0;
};

// Adds the wall time of f() to `seconds`.
template <class F>
void timed(double& seconds, F&& f) {
  const auto t0 = std::chrono::steady_clock::now();
  std::forward<F>(f)();
  seconds += std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

// The velocity solve at the start of a step, as a scheme shows it to an observer
// (Simulation::onStartSolve; the dissipation probe): valid during the call only.
struct StartSolve {
  const StepContext& ctx;     // the start: geometry, contacts, Δt, what Γ carries
  const Eigen::Matrix3Xd& f;  // F(x₀)
  const Eigen::VectorXd& v;   // solved from Γ(x₀) v = F(x₀) (ros2: the first stage, k₁)
  const ForceTerms& terms;    // the terms that made F and Γ
  const FrictionOperator& friction;  // Γ(x₀) as solved
};
using StartSolveObserver = std::function<void(const StartSolve&)>;

// The simulation's state as a scheme works on it during one try of a step. On entry `geo` and
// the contacts (StepContext::contacts) are those of cells.x, the step's start.
struct SchemeState {
  CellSet& cells;
  Geometry& geo;
  Geometry& geo_start;  // free on entry; keepStart() moves the start's geometry here
  const ForceTerms& terms;
  VelocitySolver& solver;
  Eigen::Matrix3Xd& f;  // out: the step's force (its evaluation at the start)
  Eigen::VectorXd& v;   // in: the warm start (the last step's velocity); out: the step's velocity
  PhaseTimes& times;
  std::function<void()> detect;  // the contacts of `geo`, into the context's contact list
  bool start_kept = false;
  const StartSolveObserver* on_start_solve = nullptr;  // null: nobody watches
  // A scheme calls this once it has solved Γ(x₀) v = F(x₀) into v, before it moves the cells or
  // keeps the start (ctx must still describe x₀); it reads and changes nothing.
  void startSolved(const StepContext& ctx) const {
    if (on_start_solve && *on_start_solve) (*on_start_solve)({ctx, f, v, terms, solver.friction()});
  }
  // A scheme that evaluates the cells elsewhere than at the start calls this first: the start's
  // geometry is kept for the end of the step and the guards, and `geo` is free.
  void keepStart() {
    if (start_kept) return;
    std::swap(geo, geo_start);
    start_kept = true;
  }
};

struct SchemeResult {
  std::optional<StepFailure> failure;  // found within the scheme (ros2's first stage)
  SolveStats cg;                       // the step's solves together
  double step_error_um = -1;           // the scheme's error estimate of the step; −1: none
};

class TimeScheme {
 public:
  virtual ~TimeScheme() = default;
  virtual std::string_view name() const = 0;
  // The factor of the contact springs' linearised normal stiffness K_c in Γ for a step of length
  // dt (StepContext::contact_stiffness_dt); 0 leaves the springs explicit.
  virtual double contactStiffnessDt(double /*dt*/) const { return 0; }
  // K_c as the consistent stiffness of the spring field (the contacts then carry their moments,
  // ContactLaw::stiffness_moments) rather than one spring at each pair's centroid.
  virtual bool consistentStiffness() const { return false; }
  // The scheme's own guards, run after the standard ones of their phase.
  virtual void addGuards(const NumericsParams& /*numerics*/,
                         std::vector<std::unique_ptr<StepGuard>>& /*guards*/) const {}
  // Finds the step's velocity into s.v; `ctx` is the context of the start of the step.
  virtual SchemeResult solve(SchemeState& s, const StepContext& ctx) = 0;
  // The positions at the end of the step, x₁ = x₀ + Δt v, with v in cells.v.
  virtual void advance(CellSet& cells, double dt) const { cells.x += dt * cells.v; }
  // The geometry of the predicted end of the step, for the per-cell integrals of the terms'
  // endStep (StepContext::geo_end); null: forward Euler from the start.
  virtual const Geometry* predictedEnd(const SchemeState& /*s*/) const { return nullptr; }
};

// semi-implicit (K_c explicit) and contact-implicit (Γ + Δt K_c): one solve a step.
// `consistent_stiffness` (contact-implicit only): the consistent stiffness of the spring field in
// Γ (ros2's) instead of one spring per pair (docs/science/motion-convergence.md).
std::unique_ptr<TimeScheme> makeOneStage(bool contact_implicit, bool consistent_stiffness = false);
// ROS2 (Verwer, Spee, Blom & Hundsdorfer 1999): two linearly implicit stages, order 2,
// L-stable with γ = kRos2Gamma = 1 + 1/√2 (ros2.cc).
inline constexpr double kRos2Gamma = 1.7071067811865476;
// `consistent_stiffness` = false puts contact-implicit's one spring per pair in W instead of the
// consistent stiffness of the spring field: still order 2 as Δt → 0 (a W-method), but at the
// studies' steps it moves motile cells as little as contact-implicit does; the study drivers keep
// it for that comparison (docs/science/motion-convergence.md).
std::unique_ptr<TimeScheme> makeRos2(const NumericsParams& numerics,
                                     bool consistent_stiffness = true);
// The scheme of numerics.integrator.
std::unique_ptr<TimeScheme> makeTimeScheme(const NumericsParams& numerics);

}  // namespace activefoam
