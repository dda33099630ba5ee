// Time integration of the overdamped dynamics Γ v = F (DESIGN.md §5): who owns Δt, how a step's
// velocities are found, which checks a step must pass, and when meshes are remeshed. Simulation
// (simulation.h) strings these together; the order of a step is in ARCHITECTURE.md.
#pragma once

#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include <Eigen/Core>

#include "activefoam/block_matrix.h"
#include "activefoam/cellset.h"
#include "activefoam/contact_geometry.h"
#include "activefoam/failure_kind.h"
#include "activefoam/force_term.h"
#include "activefoam/geometry.h"
#include "activefoam/solver.h"
#include "activefoam/spec.h"

namespace activefoam {

struct ContactList;

// The step length and simulated time. Time is counted in ticks of Δt/2^K, the smallest step the
// schedule may take (K: the halvings from numerics.dt_s down to numerics.dt_min_s), so that half
// steps add up exactly and samples fall on the same times as in a run that never halved:
// t = ticks · Δt/2^K is bit-identical to steps · Δt while no step was halved.
//
// Adaptive schedule: a step that fails is retried at half the length (level + 1), recursively, as
// long as the level stays ≤ K; after `wait` accepted steps at a level (4 at first), the next step
// is doubled again, but only where the time is a multiple of the doubled length, so a step never
// straddles a step of the spec's Δt (sample and remesh times stay where they were). Growth that
// fails again soon (within max(4 × wait, kRecent) steps) doubles the wait, up to kMaxWait: a Δt
// that keeps failing is tried geometrically less often, so little time is spent at it. kRecent
// covers the guards that need many steps to see a failure: the semi-implicit doublet at
// Δt = 0.1 s trips the oscillation guard ~20 steps after each growth, and without the window it
// spent 90 % of its steps at that unstable Δt. Twice that window without a failure halves the
// wait again.
class TimeStepper {
 public:
  static constexpr int kGrowAfter = 4;
  static constexpr int kMaxWait = 4096;
  static constexpr int kRecent = 64;
  static constexpr int kSaturated = 4 * kMaxWait;
  TimeStepper(double dt_s, double dt_min_s, bool adaptive);

  double dt() const { return level_dt_; }  // length of the next step, s
  double baseDt() const { return dt_; }    // numerics.dt_s
  double minDt() const;                    // the floor Δt/2^K
  int level() const { return level_; }
  int maxLevel() const { return max_level_; }
  bool adaptive() const { return adaptive_; }
  std::int64_t ticks() const { return ticks_; }
  std::int64_t ticksPerBaseStep() const { return std::int64_t{1} << max_level_; }
  std::int64_t stepTicks() const { return ticksPerBaseStep() >> level_; }
  // Ticks of a duration given in seconds, rounded to whole steps of the spec's Δt.
  std::int64_t ticksFor(double seconds) const;
  // Ticks of a period (sampling, snapshots, remeshing, a preparation's window): as ticksFor,
  // but at least one step of the spec's Δt. The adaptive schedule never steps across one, so
  // what happens every period happens at the same times whatever the schedule did.
  std::int64_t periodTicks(double seconds) const;
  double time() const { return timeAt(ticks_); }
  double timeAt(std::int64_t ticks) const { return static_cast<double>(ticks) * tick_s_; }
  std::int64_t steps() const { return steps_; }  // accepted steps

  bool canHalve() const { return adaptive_ && level_ < max_level_; }
  // The step just tried failed and was undone: the next one is half as long.
  void halve();
  // The step of length dt() was taken.
  void accept();

  // Everything that a checkpoint must carry to continue the same schedule.
  struct State {
    std::int64_t ticks = 0, steps = 0;
    std::int32_t level = 0, good = 0, wait = kGrowAfter, since_growth = kSaturated, calm = 0;
    std::int32_t unused = 0;  // no padding bytes in checkpoints
  };
  State state() const { return {ticks_, steps_, level_, good_, wait_, since_growth_, calm_, 0}; }
  int growthWait() const { return wait_; }
  void setState(const State& s);

 private:
  void setLevel(int level);
  std::int64_t baseSteps(double seconds) const;  // seconds in whole steps of Δt, rounded
  double dt_, tick_s_, level_dt_;
  int max_level_ = 0;
  bool adaptive_;
  std::int64_t ticks_ = 0, steps_ = 0;
  int level_ = 0, good_ = 0;
  int wait_ = kGrowAfter;          // good steps before the next growth
  int since_growth_ = kSaturated;  // accepted steps since the last growth (saturating)
  int calm_ = 0;                   // accepted steps since the last failure or relaxation
};

// One failed check: the kind and one line saying what, where and when.
struct StepFailure {
  FailureKind kind = FailureKind::None;
  std::string reason;
};

// What a guard may look at. Pointers are null in phases where the thing does not exist yet.
struct GuardView {
  const SceneSpec& spec;
  const CellSet& cells;
  const Geometry& geo;                      // current (after the move from `Moved` on)
  const Geometry* geo_before = nullptr;     // the step's start geometry (from `Moved` on)
  const ContactList* contacts = nullptr;    // the step's start contacts, new ones in `Detected`
  const Eigen::VectorXd* v = nullptr;       // the solved velocities (`Solved`)
  const Eigen::Matrix3Xd* force = nullptr;  // F of the step (`Solved`)
  const SolveStats* cg = nullptr;           // (`Solved`)
  const ContactLaw* law = nullptr;          // scenes with contacts
  double t = 0;                             // time at the start of the step
  double dt = 0;                            // the step's length
  double step_error_um = -1;  // ros2's error estimate of the step (`Solved`); −1: none
};

// A check that a step must pass, run at one point of the step. A failed check rejects the step:
// with adaptive stepping it is undone and retried at half the length.
class StepGuard {
 public:
  enum class Phase {
    Solved,   // velocities found, nothing moved yet
    Moved,    // positions advanced, geometry recomputed, before remeshing
    Detected  // after remeshing and contact detection: the step's final state
  };
  virtual ~StepGuard() = default;
  virtual std::string_view name() const = 0;
  virtual Phase phase() const = 0;
  virtual std::optional<StepFailure> check(const GuardView& view) = 0;
  // A guard that counts over consecutive steps: the count (checkpointed), and its reset when the
  // step length changes (a count at another Δt says nothing about this one).
  virtual std::int64_t count() const { return 0; }
  virtual void setCount(std::int64_t) {}
};

// Empty, or why two cells interpenetrate beyond `limit` µm in `contacts` (at time t, for the
// message): per pair of cells, the area-weighted mean gap of their contact pairs. `scratch` keeps
// its buffer between calls.
struct PairGap {
  std::uint64_t key;  // (cell a << 32) | cell b, a < b
  double gap_area, area;
};
std::string interpenetration(const CellSet& cells, const ContactList& contacts, double limit,
                             double t, std::vector<PairGap>& scratch);

// The guards every simulation runs, in order: non-finite force or velocity, CG not converged,
// contact oscillation (scenes with contacts), inverted triangle, volume drift, and
// interpenetration (scenes with contacts).
std::vector<std::unique_ptr<StepGuard>> standardGuards(bool with_contacts);
// ros2 with numerics.max_step_error_um > 0: rejects a step whose error estimate exceeds it, except
// at the floor of the adaptive schedule (an accuracy check, not a failure: it never ends a run).
std::unique_ptr<StepGuard> stepErrorGuard();

// When to remesh (numerics.remesh_every_s): every cell at multiples of τ_r, and in between any
// cell with a triangle below half of A_m (contacts zipping up squeeze rim triangles from A_m to
// zero area in a few seconds, less than τ_r, and then they invert).
class RemeshPolicy {
 public:
  RemeshPolicy(const SceneSpec& spec, const TimeStepper& stepper);
  // Cells to remesh at the end of a step that ended at `ticks`; empty when none is due.
  // `all` is set when it is the periodic remesh of every cell.
  std::vector<char> due(std::int64_t ticks, const CellSet& cells, const Geometry& geo,
                        bool& all) const;
  double minTriangleArea(const CellSet& cells, int c) const;  // A_m of cell c

 private:
  std::int64_t interval_ticks_ = 0;  // 0: never
  double min_area_factor_;
  double triangles_;
};

// The velocity solve of one step: the force sum F, the friction operator Γ (assembled cell
// blocks + contact couplings applied as a product) and preconditioned CG on Γ v = F. For the
// contact-implicit integrator Γ carries Δt K_c, the linearised normal stiffness of the contact
// springs (γ Δt K_c for ros2); the step context says so (StepContext::contact_stiffness_dt),
// terms never read the spec's Δt.
class Integrator {
 public:
  explicit Integrator(const NumericsParams& numerics);
  IntegratorKind kind() const { return kind_; }
  // The factor of K_c in Γ for a step of length dt: dt (contact-implicit), γ dt (ros2) or 0.
  double contactStiffnessDt(double dt) const {
    switch (kind_) {
      case IntegratorKind::ContactImplicit:
        return dt;
      case IntegratorKind::Ros2:
        return kRos2Gamma * dt;
      case IntegratorKind::SemiImplicit:
        break;
    }
    return 0.0;
  }
  // ROS2 (Verwer, Spee, Blom & Hundsdorfer 1999) is a linearly implicit two-stage method of
  // order 2 for any approximation of the Jacobian (a W-method) and L-stable with γ = 1 + 1/√2:
  //   (Γ₀ + γΔt K₀) k₁ = F(x₀)
  //   (Γ* + γΔt K*) k₂ = F(x*) − 2 Γ* k₁,   x* = x₀ + Δt k₁ (geometry and contacts re-evaluated)
  //   x₁ = x₀ + Δt (3/2 k₁ + 1/2 k₂)
  // Stage 2 takes its matrix at the predicted state: the W-matrix may change by O(Δt) between
  // stages without losing the order, and Γ* k₁ is what the mass-matrix form needs there.
  static constexpr double kRos2Gamma = 1.7071067811865476;
  bool twoStage() const { return kind_ == IntegratorKind::Ros2; }

  using Terms = std::vector<std::unique_ptr<ForceTerm>>;
  // F = Σ terms' forces (3 × vertices); returns the sum of their energies.
  double computeForces(const StepContext& ctx, const Terms& terms, Eigen::Matrix3Xd& f) const;
  // Γ of this step: pattern rebuilt when the topology changed, values overwritten.
  void prepareFriction(const StepContext& ctx, const Terms& terms);
  const BlockMatrix& frictionMatrix() const { return gamma_; }
  void applyFriction(const double* v, double* y) const;  // y = Γ v
  // Γ as blocks: the assembled lower triangle, then the product's couplings (what the
  // incomplete-Cholesky factor is built from).
  void forEachFrictionBlock(const BlockSink& sink) const;
  // Solves Γ v = F; v holds the warm start on entry. With the incomplete-Cholesky
  // preconditioner the factor of this Γ is built first, unless `reuse_factor` asks for the one
  // of the previous solve (ros2's second stage, whose Γ* differs from Γ₀ by O(Δt)): nothing of
  // the factor outlives a step, so rollback and resume need not know about it.
  SolveStats solve(const Eigen::Matrix3Xd& f, Eigen::VectorXd& v, bool reuse_factor = false);

 private:
  IntegratorKind kind_;
  BlockMatrix gamma_;
  std::uint64_t pattern_version_ = ~std::uint64_t{0};
  std::vector<const ForceTerm*> product_terms_;  // terms with a coupling product
  LinearSolver solver_;
  PreconditionerKind preconditioner_;
  IncompleteCholesky factor_;
  std::vector<int> cell_vertex_begin_;  // of the cells Γ was prepared for
};

}  // namespace activefoam
