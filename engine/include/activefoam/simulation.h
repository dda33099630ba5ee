// One running scene: the packed cell state, the force terms, and the time step (the order of a
// step is in ARCHITECTURE.md).
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "activefoam/block_matrix.h"
#include "activefoam/cellset.h"
#include "activefoam/contacts.h"
#include "activefoam/failure_kind.h"
#include "activefoam/force_term.h"
#include "activefoam/geometry.h"
#include "activefoam/remesh_policy.h"
#include "activefoam/solver.h"
#include "activefoam/spec.h"
#include "activefoam/step_guards.h"
#include "activefoam/terms.h"
#include "activefoam/time_scheme.h"
#include "activefoam/time_stepper.h"
#include "activefoam/velocity_solver.h"

namespace activefoam {

struct StepReport {
  FailureKind failure = FailureKind::None;
  std::string reason;
  double dt = 0;     // length of the step taken (or, on failure, of the last one tried), s
  int rejected = 0;  // tries of this step that failed a guard and were undone (adaptive Δt)
  // The first rejected try's failure (when rejected > 0): what the run would have ended with
  // without the adaptive step.
  FailureKind rejected_kind = FailureKind::None;
  std::string rejected_reason;
  SolveStats cg;
  int contacts = 0;               // active triangle pairs this step
  int remesh_ops = 0;             // operations of a remesh done at the end of this step
  double remesh_volume_jump = 0;  // max over cells of |ΔV|/V across that remesh
  bool ok() const { return failure == FailureKind::None; }
};

// Builds the cells of a scene (radii from the Gamma law with the spec's seed).
CellSet buildScene(const SceneSpec& spec);
// The cell scene's starting shape: an icosphere with the mesh volume exactly V* = 4/3 π r³,
// stretched to semi-axes (q, 1, 1/q)·r_eff (volume-preserving), centred at `centre`.
TriMesh ellipsoidCell(double radius, double axes_ratio, int triangles, const Vec3& centre);

// Centres for N spheres of the given radii packed into a compact ball without overlap: random
// start, then an overdamped soft-sphere relaxation with a weak pull towards the centre, then the
// pull is switched off until no pair overlaps by more than 1e-3 of the mean radius. Neighbours
// end up touching. Deterministic in (radii, seed).
std::vector<Vec3> packSpheres(const std::vector<double>& radii, std::uint64_t seed);

class Simulation {
 public:
  // `spec` must be validated and resolved.
  explicit Simulation(const SceneSpec& spec);
  Simulation(const SceneSpec& spec, CellSet cells);
  // With a time scheme of the caller's instead of numerics.integrator's (tests of new schemes).
  Simulation(const SceneSpec& spec, CellSet cells, std::unique_ptr<TimeScheme> scheme);

  // One accepted time step. With numerics.adaptive, a try that fails a guard is undone (cells,
  // PI integrals, polarities, counters, contacts: all as at the start of the step) and retried at
  // half the length, down to numerics.dt_min_s; the report says how many tries were rejected and
  // the length taken. A failure at the floor, or any failure without numerics.adaptive, ends the
  // step with the state left as it was found failing.
  StepReport step();
  // Remeshes every cell now (also done automatically every remesh_every_s, and for a single
  // cell as soon as one of its triangles shrinks below half of A_m).
  StepReport remeshAll();
  // Remeshes the cells c with which[c] != 0.
  StepReport remeshCells(const std::vector<char>& which);

  const SceneSpec& spec() const { return spec_; }
  const CellSet& cells() const { return cells_; }
  const Geometry& geometry() const { return geo_; }
  const ContactList& contacts() const { return contacts_; }
  bool hasContacts() const { return with_contacts_; }
  double time() const { return stepper_.time(); }
  std::int64_t steps() const { return stepper_.steps(); }
  // The time step schedule: the next step's length, the time in ticks of the smallest step.
  const TimeStepper& stepper() const { return stepper_; }
  double dt() const { return stepper_.dt(); }
  // Tries undone and retried over the whole run (adaptive Δt).
  std::int64_t stepsRejected() const { return steps_rejected_; }
  double pressure(int c) const { return pressure_->pressure(cells_, geo_, c); }
  const PhaseTimes& phaseTimes() const { return times_; }
  // The broad phase's reuse between steps (rebuilt cells, swept and reused pairs of cells).
  const CandidateCache::Stats& candidateStats() const { return candidates_.stats(); }
  // Skin of the broad phase's Verlet lists (CandidateCache): results do not depend on it, only
  // the cost — see docs/benchmarks.md for the measurement that chose it.
  static constexpr double kCandidateSkinUm = 0.4;
  std::int64_t remeshOps() const { return remesh_ops_; }
  // Cell remeshes that ran the rescue (numerics.remesh_repair) over the run: while it is 0 the
  // run has the bits it would have without the key.
  std::int64_t remeshRescues() const { return remesh_rescues_; }
  // Cell meshes rebuilt (numerics.remesh_repair = rescue-rebuild) over the run: while it is 0 the
  // run has the bits it would have without the key.
  std::int64_t remeshRebuilds() const { return remesh_rebuilds_; }
  // Collapses and rebuilds refused for entering a neighbour (numerics.remesh_keep_out_um) over the
  // run: while it is 0 the run has the bits it would have without the key.
  std::int64_t remeshKeptOut() const { return remesh_kept_out_; }
  // The force terms built for this spec, in evaluation order (terms whose parameters vanish are
  // not built).
  std::vector<std::string_view> termNames() const {
    std::vector<std::string_view> names;
    for (const auto& t : terms_) names.push_back(t->name());
    return names;
  }
  // The step guards, in order (standardGuards), and one more at the end of its phase (tests
  // force failures with one).
  std::vector<std::string_view> guardNames() const {
    std::vector<std::string_view> names;
    for (const auto& g : guards_) names.push_back(g->name());
    return names;
  }
  void addGuard(std::unique_ptr<StepGuard> guard) { guards_.push_back(std::move(guard)); }
  // Called in every try of a step once its scheme has solved the velocity at the step's start
  // (StartSolve), before the guards judge the try; it must not change anything it is shown.
  // Empty: none (the default).
  void onStartSolve(StartSolveObserver observer) { start_solve_ = std::move(observer); }

  // Pieces of a step, exposed for tests and benchmarks. Geometry must be current.
  void detect();                              // contacts of the current geometry
  double computeForces(Eigen::Matrix3Xd& f);  // returns the sum of term energies
  // Γ as a step uses it: the assembled blocks of the cells (pattern: mesh edges) with the
  // contacts' diagonal blocks, and the contact couplings applied as a product.
  void prepareFriction() { solver_.prepareFriction(context(), terms_); }
  const BlockMatrix& frictionMatrix() const { return solver_.frictionMatrix(); }
  void applyFriction(const double* v, double* y) const { solver_.applyFriction(v, y); }
  void forEachFrictionBlock(const BlockSink& sink) const { solver_.forEachFrictionBlock(sink); }
  const TimeScheme& scheme() const { return *scheme_; }
  // The whole Γ as one matrix, couplings included (tests and tools).
  SpMat assembleFriction();
  // Empty, or the reason why two cells interpenetrate beyond numerics.max_penetration_um in the
  // current contacts (a guard checks it after every step).
  std::string interpenetration();
  // Replaces positions (tests: finite differences, perturbations) and refreshes geometry.
  void setPositions(const Eigen::Matrix3Xd& x);

  // The complete dynamic state (cells, time, step schedule, counters) as a versioned byte
  // string, and its inverse: a simulation of the same spec restored from it continues
  // bit-identically. `extra` carries the caller's own state (runScene's accumulators) through
  // the checkpoint.
  std::string saveState(const std::string& extra = {}) const;
  // Returns `extra`. Throws std::invalid_argument if the bytes are malformed, of another format
  // version, or of a different spec.
  std::string loadState(const std::string& bytes);

 private:
  void init();
  StepContext context() const {
    const double dt = stepper_.dt();
    return {cells_,
            geo_,
            topo_,
            dt,
            time(),
            with_contacts_ ? &contacts_ : nullptr,
            scheme_->contactStiffnessDt(dt),
            scheme_->consistentStiffness(),
            spec_.numerics.tension_implicit ? scheme_->contactStiffnessDt(dt) : 0.0,
            stepper_.timeAt(stepper_.ticks() + stepper_.stepTicks())};
  }
  // One try of a step of length stepper_.dt(); the schedule is advanced by the caller.
  StepReport tryStep();
  std::optional<StepFailure> runGuards(StepGuard::Phase phase, const GuardView& view);
  void resetGuardCounts();
  // The state a rejected try is undone to (what the try can change; geometry and contacts are
  // recomputed from it: both are functions of the cells alone).
  void saveRollback();
  void rollback();

  SceneSpec spec_;
  CellSet cells_;
  Geometry geo_, geo_prev_;
  Topology topo_;
  bool with_contacts_ = false;
  ContactLaw law_;
  ContactList contacts_;
  CandidateCache candidates_{kCandidateSkinUm};
  std::vector<std::unique_ptr<ForceTerm>> terms_;
  const CytoplasmPressure* pressure_ = nullptr;
  TimeStepper stepper_;
  std::unique_ptr<TimeScheme> scheme_;
  VelocitySolver solver_;
  RemeshPolicy remesh_;
  std::vector<std::unique_ptr<StepGuard>> guards_;
  Eigen::Matrix3Xd f_;
  Eigen::VectorXd v_;
  std::int64_t remesh_ops_ = 0;
  std::int64_t remesh_rescues_ = 0;
  std::int64_t remesh_rebuilds_ = 0;
  std::int64_t remesh_kept_out_ = 0;
  std::int64_t steps_rejected_ = 0;
  PhaseTimes times_;
  StartSolveObserver start_solve_;
  PenetrationScratch penetration_;  // scratch of interpenetration()
  struct Saved {
    CellSet cells;
    std::int64_t remesh_ops = 0;
    std::int64_t remesh_rescues = 0;
    std::int64_t remesh_rebuilds = 0;
    std::int64_t remesh_kept_out = 0;
  } saved_;
};

}  // namespace activefoam
