// Observables computed from a simulation state (docs/model.md §8).
#pragma once

#include <array>
#include <functional>
#include <string>
#include <utility>
#include <vector>

#include <Eigen/Core>

#include "activefoam/contacts.h"
#include "activefoam/geometry.h"

namespace activefoam {

// Ratio of the largest to the smallest principal axis of cell c (1 for a sphere).
double aspectRatio(const CellSet& cells, int c);

struct SphereFit {
  Vec3 centre = Vec3::Zero();
  double radius = 0;
  double rms = 0;  // rms distance of the points from the sphere
  bool ok = false;
};
// Algebraic least-squares sphere through the columns of `points` (at least 4, not coplanar).
SphereFit fitSphere(const Eigen::Matrix3Xd& points);

// Contact angle θ_c of a doublet (cells 0 and 1), degrees: the angle between a cell's free
// surface and the interface plane at the contact rim; 0° for cells touching at a point, 90° for
// complete fusion. Each cell's free surface (vertices with no contact area) is fitted by a sphere
// (centre c, radius R); the interface plane passes through the centroid of the contacting
// vertices, normal to the line of the fitted centres; at distance h from c, cos θ_c = h/R.
// Returns the mean over the two cells, 0 when there is no contact.
double doubletContactAngleDeg(const CellSet& cells, const ContactList& contacts);

// ---------------------------------------------------------------------------------------------
// Fusion observables (docs/model.md §8; implemented in observe/fusion_observables.cc, the
// contacting pairs, MSRD and unique contacts in observe/msrd.cc).

// Fusion angle of two spheroids (cells.label[c] = 0 or 1). Each spheroid's centroid is the
// volume-weighted mean of its cells' volume centroids; the axis runs through the two centroids
// (distance d). L = extent of all vertices along the axis. In each cross-section
// perpendicular to the axis, the section's radius is the largest distance from the axis at
// which the surface crosses it (edges intersected exactly: a slab of zero width, so no
// slab-width bias; 0 where nothing crosses, i.e. a gap). The neck radius a is the smallest
// section radius between the centroids with a section at least as wide on each side (65
// sections, then a golden-section refinement) — for nearly fused spheroids the sections at the
// centroids are narrower than the neck but are not a neck; with no such trapped minimum (a
// single bulge: complete fusion) a is the widest section. θ = 2 atan(2a/L): exact for two
// equal truncated spheres (a = R sin θ, L = 2R(1 + cos θ)); 90° is complete fusion, 0° two
// separate spheroids.
// Surface used: by default every cell surface. The largest crossing of a section is on the
// aggregate's outer envelope anyway (contact surfaces lie inside it), and the "free
// surface" alone leaves a one-edge band without data around every cell–cell junction — at a
// two-cell neck that band sits exactly on the neck and biases a by ~cot θ × the band width.
// free_surface_only = true restricts to edges whose two vertices have no contact area.
struct FusionAngle {
  bool ok = false;
  std::string why;
  double theta_deg = 0;
  double neck_radius_um = 0;    // a
  double length_um = 0;         // L
  double distance_um = 0;       // d, between the spheroid centroids
  double neck_position_um = 0;  // where a is found, along the axis from spheroid 0's centroid
  std::array<Vec3, 2> centroid{Vec3::Zero(), Vec3::Zero()};
};
FusionAngle fusionAngle(const CellSet& cells, const ContactList& contacts,
                        bool free_surface_only = false);

// Shape index S/V^{2/3} of cell c (sphere (36π)^{1/3} ≈ 4.836; 3D vertex-model transition 5.41)
// and its mean over cells (NaN without cells).
double shapeIndex(const Geometry& geo, int c);
double meanShapeIndex(const Geometry& geo);

// The distinct cell pairs (i < j, sorted) with at least one active triangle contact.
std::vector<std::pair<int, int>> contactingCellPairs(const CellSet& cells,
                                                     const ContactList& contacts);

// The rotation R (det +1) that best carries the points p onto q about their centroids (their
// unweighted means), in the least-squares sense (Kabsch): q_i − q̄ ≈ R (p_i − p̄). Points on one
// line (two cells) leave the turn about it undetermined: R is then the smallest rotation that
// carries the line onto its new direction. Throws std::invalid_argument unless p and q are
// equal in number and not empty.
Eigen::Matrix3d bestRotation(const std::vector<Vec3>& p, const std::vector<Vec3>& q);
// The angle of a rotation matrix, radians in [0, π].
double rotationAngle(const Eigen::Matrix3d& r);

// Mean squared relative displacement of neighbours. Feed one sample per observable interval
// (equal intervals): the cell centroids and the contacting cell pairs at that time.
// msrd(lag) = ⟨|(x_i − x_j)(t₀ + lag) − (x_i − x_j)(t₀)|²⟩ over all time origins t₀ and the
// pairs (i, j) in contact at t₀, pooled (every origin–pair counts once). With more than
// `max_origins` samples the origins are every ⌈n / max_origins⌉-th sample (cost
// O(origins × samples × pairs) for the full curve).
class MsrdTracker {
 public:
  explicit MsrdTracker(int max_origins = 256) : max_origins_(max_origins) {}

  // Throws std::invalid_argument if the number of cells changes or time does not increase.
  // `labels` (none, or one per cell) mark the cells at this sample for pooledByClass.
  void addSample(double t_s, std::vector<Vec3> centroids,
                 std::vector<std::pair<int, int>> contact_pairs, std::vector<int> labels = {});
  // Convenience: geo.cell_centroid and contactingCellPairs(cells, contacts).
  void addSample(double t_s, const CellSet& cells, const Geometry& geo,
                 const ContactList& contacts);

  int numSamples() const { return static_cast<int>(t_.size()); }
  const std::vector<int>& labels(int sample) const { return labels_.at(sample); }
  // Lag of k samples in seconds: k × the mean sampling interval.
  double lagTime(int k) const;
  // µm²; NaN where no origin–pair has that lag (lag ≥ numSamples(), or no contacts).
  double msrd(int lag) const;
  std::vector<double> msrdCurve() const;  // lags 0 … numSamples() − 1

  // As msrd(lag), with the aggregate's rigid rotation between origin and lag taken out: each
  // pair's relative vector at the origin is first turned by the rotation that best carries all
  // the cells' centroids at the origin onto those at origin + lag (least squares about the
  // centroids, Kabsch). A doublet turning as a body moves every pair's relative vector with no
  // cell changing its neighbours — S13's non-central cortex coupling turns ours 0.5–2.4° an
  // hour, which alone takes a non-motile doublet past r² within a day (docs/science/jam-day).
  double msrdLessRotation(int lag) const;
  // The angle of that rotation, degrees, averaged over the origins; NaN as msrd.
  double turnDeg(int lag) const;

  struct Mixing {
    double time_s = 0;     // lag where MSRD first reaches r² (linear between samples)
    bool reached = false;  // false: never reached; time_s is then the run length (capped)
  };
  Mixing mixingTime(double r_um) const;
  Mixing mixingTimeLessRotation(double r_um) const;  // the same on msrdLessRotation
  // The same rule on another curve over lags 0 … numSamples() − 1 (pooledByClass's means).
  Mixing mixingTime(double r_um, const std::vector<double>& curve) const;

  // msrd(lag) split by the class of each origin–pair: class_of(l_i, l_j) of its cells' labels
  // at the origin (addSample's), in [0, classes). The classes' pairs are msrd(lag)'s and their
  // sums add up to its sum (up to rounding): msrd(lag) is their pair-weighted mean. Throws
  // std::invalid_argument where an origin has no labels or a class is out of range.
  struct Pooled {
    double sum = 0;  // µm²
    long pairs = 0;
    double mean() const;  // sum / pairs; NaN without pairs
  };
  using ClassOf = std::function<int(int label_i, int label_j)>;
  std::vector<Pooled> pooledByClass(int lag, int classes, const ClassOf& class_of) const;

  // The tracker's samples as bytes (checkpoints) and back; restore throws std::invalid_argument
  // on malformed bytes.
  std::string save() const;
  void restore(const std::string& bytes);

 private:
  std::vector<int> origins() const;
  // Σ over origin–pairs of the squared relative displacement (less the best rotation when
  // `less_rotation`), the origin–pair count, Σ over origins of the angle (rad) and the origins.
  struct LagSums {
    double sum = 0, angle = 0;
    long pairs = 0, origins = 0;
  };
  // With `by_class`: each origin–pair's share also into (*by_class)[class_of(labels)].
  LagSums lagSums(int lag, bool less_rotation, const ClassOf* class_of = nullptr,
                  std::vector<Pooled>* by_class = nullptr) const;
  Mixing mixingOf(double r_um, bool less_rotation) const;
  Mixing mixingOn(double r_um, const std::function<double(int)>& msrd_at) const;
  int max_origins_;
  std::vector<double> t_;
  std::vector<std::vector<Vec3>> x_;
  std::vector<std::vector<std::pair<int, int>>> pairs_;
  std::vector<std::vector<int>> labels_;  // per sample: empty, or one per cell
};

// Normalized unique contacts: distinct cell pairs ever in contact / pairs in contact in the
// first sample (t = 0). Feed every sample (or every step, for completeness of "ever").
class ContactHistory {
 public:
  void add(const std::vector<std::pair<int, int>>& cell_pairs);  // pairs (i, j), any order
  void add(const CellSet& cells, const ContactList& contacts);
  int initialCount() const { return initial_; }  // −1 before the first sample
  int distinctCount() const { return static_cast<int>(seen_.size()); }
  double normalized() const;  // NaN before the first sample or with no contact at t = 0

  std::string save() const;  // as MsrdTracker
  void restore(const std::string& bytes);

 private:
  int initial_ = -1;
  std::vector<std::pair<int, int>> seen_;  // sorted, unique
};

// Contact angle θ_c at cell–cell–medium junctions (the aggregate surface) and GSI = cos θ_c.
// Each cell's free surface (vertices with no contact area) is split into connected patches; a
// patch of at least 10 vertices is fitted by a sphere (Young–Laplace: a free surface under
// uniform tension and pressure has constant mean curvature). A junction is a pair of patches
// of two contacting cells A, B that both border the A–B contact (a contact vertex touching the
// other cell with a free neighbour in the patch) within 3 mean edge lengths of each other.
// At the circle where the two fitted spheres meet, the angle ψ between the outward normals is
// cos ψ = (R_A² + R_B² − D²)/(2 R_A R_B) (D: distance of the centres), and
// θ_c = 90° − ψ/2: 0° for cells touching at a point (ψ = 180°), 90° for complete fusion
// (ψ = 0°) — for a doublet the same angle as doubletContactAngleDeg (cos θ_c = h/R).
// Spheres that do not meet count as θ_c = 0°. Patches fitted with rms > 10 % of R are skipped.
struct SurfaceContactAngle {
  bool ok = false;
  std::string why;
  double theta_deg = 0;     // mean over junctions
  double theta_sd_deg = 0;  // standard deviation over junctions
  double gsi = 0;           // cos(theta_deg)
  int junctions = 0;
};
SurfaceContactAngle surfaceContactAngle(const CellSet& cells, const ContactList& contacts);

}  // namespace activefoam
