// The checks a step must pass (docs/model.md §6.4): a failed check rejects the step, which the
// adaptive schedule undoes and retries at half the length.
#pragma once

#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include <Eigen/Core>

#include "activefoam/cellset.h"
#include "activefoam/contact_geometry.h"
#include "activefoam/failure_kind.h"
#include "activefoam/geometry.h"
#include "activefoam/solver.h"
#include "activefoam/spec.h"

namespace activefoam {

struct ContactList;

// One failed check: the kind and one line saying what, where and when.
struct StepFailure {
  FailureKind kind = FailureKind::None;
  std::string reason;
};

// What a guard may look at. Pointers are null in phases where the thing does not exist yet.
struct GuardView {
  const SceneSpec& spec;
  const CellSet& cells;
  const Geometry& geo;                          // current (after the move from `Moved` on)
  const Geometry* geo_before = nullptr;         // the step's start geometry (from `Moved` on)
  const std::vector<char>* remeshed = nullptr;  // `Detected`: the cells this step remeshed
  const CellSet* cells_before = nullptr;        // the step's start (adaptive stepping keeps it;
                                                // from `Moved` on, its own meshes)
  const ContactList* contacts = nullptr;        // the step's start contacts, new ones in `Detected`
  const Eigen::VectorXd* v = nullptr;           // the solved velocities (`Solved`)
  const Eigen::Matrix3Xd* force = nullptr;      // F of the step (`Solved`)
  const SolveStats* cg = nullptr;               // (`Solved`)
  const ContactLaw* law = nullptr;              // scenes with contacts
  double t = 0;                                 // time at the start of the step
  double dt = 0;                                // the step's length
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

// Empty, or why two cells interpenetrate beyond `limit` µm (at time t, for the message): a
// vertex of one cell lies deeper than `limit` inside the other's closed surface (generalised
// winding number > 1/2; depth = distance to its nearest triangle). Checked on the vertices in
// both cells' bounding boxes, for the pairs of cells whose contact's area-weighted mean gap
// reads beyond limit/4: the mean gap alone is no measure — along oblique bisectors facing pairs
// read −0.4 … −1.1 µm where no vertex is 0.1 µm inside (a 24 h fusion stopped on it at 17.1 h) —
// but two spheres that overlap by d read a mean gap of about −d/3 over their lens (−0.77 µm at d
// = 2.4 µm), so an overlap as deep as the limit passes the screen. `scratch` keeps its buffers
// between calls.
struct PairGap {
  std::uint64_t key;  // (cell a << 32) | cell b, a < b
  double gap_area, area;
};
struct PenetrationScratch {
  std::vector<PairGap> pairs;
  std::vector<int> va, vb;  // vertices of one pair of cells in both their boxes
};
// With `before` (the step's start, which adaptive stepping keeps) a pair beyond the limit that
// the step did not deepen passes: the step is not what put it there, and halving it could not
// take it out.
std::string interpenetration(const CellSet& cells, const ContactList& contacts, double limit,
                             double t, PenetrationScratch& scratch, const CellSet* before = nullptr,
                             const std::vector<char>* remeshed = nullptr);

// The generalised winding number of cell c's closed surface around p (1 inside, 0 outside) and
// the distance from p to that surface.
double windingNumber(const CellSet& cells, int c, const Vec3& p);
double distanceToSurface(const CellSet& cells, int c, const Vec3& p);

// The guards every simulation runs, in order: non-finite force or velocity, CG not converged,
// contact oscillation (scenes with contacts), inverted triangle, volume drift, and
// interpenetration (scenes with contacts).
std::vector<std::unique_ptr<StepGuard>> standardGuards(bool with_contacts);
// ros2 with numerics.max_step_error_um > 0: rejects a step whose error estimate exceeds it, except
// at the floor of the adaptive schedule (an accuracy check, not a failure: it never ends a run).
std::unique_ptr<StepGuard> stepErrorGuard();

}  // namespace activefoam
