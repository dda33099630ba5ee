// Probes: what a study asks of a run beyond the scene's observables, each turned on by a key of
// the spec's [observe] table (docs/scenes.md). A probe appends named columns to every sample
// (sampleColumns(spec) lists them after the scene's) and may end the run with curves and final
// values of its own (RunSummary::curves, final_values). It reads the simulation and never
// changes it, so the run's other columns keep their bits; what it remembers (the aggregate at
// t = 0, the samples its curves are pooled from) travels in the run's checkpoints.
#pragma once

#include <array>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "activefoam/contacts.h"
#include "activefoam/geometry.h"
#include "activefoam/mesh.h"
#include "activefoam/observables.h"
#include "activefoam/run.h"
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
  // At the end of the run, however it ended (the summary's own MSRD likewise): its curves, after
  // those already in `summary.curves`, and its final values.
  virtual void finish(RunSummary& /*summary*/) const {}
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
  // The stiffness that Γ carries (the contact springs' Δt vᵀK_c v, γΔt for ros2, 0 for the
  // semi-implicit integrator; with numerics.tension_implicit the tension's Δt vᵀK_γ v too): no
  // dissipation of the model, the elastic forces taken at the end of the step.
  double springs = 0;
  double forces = 0;  // vᵀF
  double active = 0;  // vᵀF_active, ActiveMigration's forces alone
};
Dissipation dissipation(const StartSolve& s);
// Γ_term v and vᵀΓ_term v, Γ_term made by the term alone from `ctx`.
Eigen::VectorXd frictionForce(const ForceTerm& term, const StepContext& ctx,
                              const Eigen::VectorXd& v);
double frictionPower(const ForceTerm& term, const StepContext& ctx, const Eigen::VectorXd& v);

// observe.dissipation at the cells' scale. Each cell's affine part of v: the least-squares fit
// v_i ≈ a + B (x_i − x̄) over its vertices, weighted by their areas (translation, rotation and
// uniform strain: the motion of whole cells); what the terms dissipate on it against on all of
// v says whether the power moves and reshapes cells or ripples their shells.
Eigen::VectorXd affinePart(const CellSet& cells, const Geometry& geo, const Eigen::VectorXd& v);
// v less its one-ring mean (the mean over the vertex's edge neighbours): a field smooth over a
// few edges leaves little here, jitter from vertex to vertex most of itself.
Eigen::VectorXd ringJitter(const Topology& topo, const Eigen::VectorXd& v);
// The RMS over cells of their centroids' velocity (each cell's area-weighted mean of v), and of
// each one's relative to the mean of its contacting neighbours' (over the cells that have one;
// NaN where none has), µm/min.
struct CellSpeeds {
  double rms_um_min = 0, relative_rms_um_min = 0;
};
CellSpeeds cellSpeeds(const CellSet& cells, const Geometry& geo, const ContactList* contacts,
                      const Eigen::VectorXd& v);
// vᵀΓ_term v of the affine part of v (the contact friction's parts ∥ and ⊥), the cortex's of
// ringJitter(v), nW, and the cells' speeds, of one solve.
struct CellScaleDissipation {
  double medium_affine = 0, cortex_affine = 0, friction_t_affine = 0, friction_n_affine = 0;
  double cortex_jitter = 0;
  CellSpeeds speeds;
};
CellScaleDissipation cellScaleDissipation(const StartSolve& s);

// observe.torque: the aggregate as a body in one solve. Its rigid part of v, the least-squares
// V + ω × (x − x̄) weighted by the vertices' areas (x̄ their area-weighted mean).
struct RigidPart {
  Vec3 centroid = Vec3::Zero(), velocity = Vec3::Zero(), spin = Vec3::Zero();  // µm, µm/s, rad/s
};
RigidPart rigidPart(const CellSet& cells, const Geometry& geo, const Eigen::VectorXd& v);
// The forces F's net force and torque about x̄ (the terms are balanced: both vanish but for the
// active forces), the rigid part's speed and spin, the torque τ_m = Σ (x_i − x̄) × (Γ_m v)_i of
// medium drag on v, and the cortex's, contact friction's (∥ + ⊥) and the implicit stiffnesses'
// (contact springs', and the tension's with numerics.tension_implicit) as shares along it, −τ_term
// · τ̂_m / |τ_m| (> 0: the term drives the turn the medium resists). Γ v = F, so the shares sum to 1
// less F's torque along τ̂_m / |τ_m|, up to the solve's residual; NaN where τ_m = 0.
struct BodyTorques {
  double net_force_nn = 0, net_torque_nnum = 0, rigid_speed_um_h = 0, rigid_spin_deg_h = 0;
  double torque_medium_nnum = 0, share_cortex = 0, share_friction = 0, share_springs = 0;
};
BodyTorques bodyTorques(const StartSolve& s);

// observe.msrd_by_depth: the MSRD of neighbours (MsrdTracker: pairs in contact at the origin,
// pooled over origins) split by where the pair's cells are in the aggregate at the origin.
// A cell's free fraction is the share of its surface in contact with no other cell,
// 1 − S_c,l / S_l (ContactList::cell_contact_area: each triangle's contact area, capped at the
// triangle's own, summed over the cell); below kBuriedBelow the cell is buried.
constexpr double kBuriedBelow = 0.05;
// One per cell; 1 (all free) where the contacts have no areas (none detected).
std::vector<double> freeFractions(const Geometry& geo, const ContactList& contacts);
// Each cell's depth in the contact graph of `pairs` (cells i, j in contact): 0 on the surface
// (not buried), then the distance (in contacts) from the nearest surface cell: 1 buried next to
// a surface cell, 2 buried with buried neighbours only, and so on. Cells with no path to the
// surface take the largest depth found + 1 (all 0 where no cell is on the surface).
std::vector<int> contactDepths(const std::vector<double>& free_fraction,
                               const std::vector<std::pair<int, int>>& pairs,
                               double buried_below = kBuriedBelow);

class MsrdByDepth {
 public:
  explicit MsrdByDepth(double buried_below = kBuriedBelow) : buried_below_(buried_below) {}
  // A sample as MsrdTracker::addSample's (and throwing as it does), with the cells' free
  // fractions (one per cell) from which each cell's burial and depth at this sample are kept.
  void addSample(double t_s, std::vector<Vec3> centroids, std::vector<std::pair<int, int>> pairs,
                 const std::vector<double>& free_fraction);

  // The pair classes: by the two cells' burial (both on the surface, one of each, both
  // buried), and by the depth of the pair's shallower cell (contactDepths; 0: a surface cell in
  // the pair, 1, 2 or more: neither cell touches a surface cell).
  enum Burial { kSurface, kMixed, kBuried };
  enum Layer { kLayer0, kLayer1, kLayer2Plus };
  // The pooled sums at a lag (in samples) of each class. Each split's classes hold every
  // origin–pair of tracker().msrd(lag) once.
  struct Split {
    std::array<MsrdTracker::Pooled, 3> burial, layer;
  };
  Split pooled(int lag) const;
  const MsrdTracker& tracker() const { return tracker_; }

  std::string save() const { return tracker_.save(); }
  void restore(const std::string& bytes);  // throws std::invalid_argument on malformed bytes

 private:
  double buried_below_;
  MsrdTracker tracker_;
};

// observe.shape: the cells' shape at their own scale. Taubin smoothing (λ then μ, `passes`
// times) on each cell's edges removes ripples of a few edges without the shrinkage of plain
// Laplacian smoothing; the shape index is scale-free, so what shrinkage is left does not bias
// it, and the raw index less the smoothed one is the vertex-scale roughness's share.
constexpr double kTaubinLambda = 0.5, kTaubinMu = -0.53;
CellSet taubinSmoothed(const CellSet& cells, const Topology& topo, int passes = 4);
// √(largest / smallest eigenvalue) of cell c's second moment of its surface about its centroid,
// Σ_i S_i (x_i − x_c)(x_i − x_c)ᵀ over its vertices: 1 for a sphere.
double surfaceElongation(const CellSet& cells, const Geometry& geo, int c);
// The least-squares line y ≈ intercept + slope x and Pearson's r; NaN where it has no meaning
// (fewer than two distinct x; r where all y are equal).
struct LineFit {
  double slope, intercept, r;
};
LineFit lineFit(const std::vector<double>& x, const std::vector<double>& y);
// Each cell's shape index S/V^{2/3} (raw and smoothed), elongation and contact fraction
// 1 − freeFractions (its surface in contact with another cell).
struct CellShapes {
  std::vector<double> shape_index, shape_index_smoothed, elongation, contact_fraction;
};
CellShapes cellShapes(const CellSet& cells, const Geometry& geo, const ContactList& contacts,
                      const Topology& topo);

}  // namespace activefoam
