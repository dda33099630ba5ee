// Triangle–triangle contact geometry (docs/model.md §3): the narrow phase for one facing pair
// and the broad phase over a packed mesh. Pure functions of positions; no cell state.
#pragma once

#include <array>
#include <utility>
#include <vector>

#include <Eigen/Core>

#include "activefoam/mesh.h"
#include "activefoam/spec_enums.h"

namespace activefoam {

// Linear contact pressure P(g) = k g for gap g < h0, 0 beyond (attractive for 0 < g < h0,
// repulsive for g < 0).
struct ContactLaw {
  double k = 71.1;   // nN/µm³
  double h0 = 0.06;  // µm
  // detectContacts also integrates each pair's ContactMoments (the consistent stiffness, which
  // only ros2 uses; ~27 more products per quadrature point in the narrow phase).
  bool stiffness_moments = false;
  // Which part of the overlap polygon carries the pressure (numerics.contact_law). Prisms keeps
  // only the points y whose point on B lies over A (inside A's prism along n̂_A) and whose point
  // on A lies over B: a nearly perpendicular pair whose planes cross beside its triangles reads
  // micrometres of "overlap" along the bisector where neither triangle is over the other.
  // PrismsOverlap restricts only the overlapping part (g < 0) so; the adhesive part (0 ≤ g < h0),
  // where the junctions' rims are, stays whole.
  ContactLawKind kind = ContactLawKind::Supplement;
};

// ∫ λ^A_i λ^B_k dS, ∫ λ^A_i λ^A_j dS, ∫ λ^B_k λ^B_l dS (row-major 3 × 3) over a pair's contact
// polygon: the consistent stiffness of the spring field, ½ k ∫ δg² dS with δg = Σ λ^B u^B −
// Σ λ^A u^A (normal parts). Exact for Exact and Dunavant7. Kept apart from TriangleContact: only
// ros2 uses them, and in every pair they doubled the pair data that each detection copies and
// the force terms read (448 instead of 232 bytes a pair then; 152 since the pair keeps only what
// the step reads, PairContact).
struct ContactMoments {
  std::array<double, 9> ab{}, aa{}, bb{};
};

struct TriangleContact {
  bool active = false;         // facing, projections overlap, and some part has g < h0
  Vec3 normal = Vec3::Zero();  // n̂_AB = normalize(n̂_A − n̂_B), from A towards B
  double area = 0;             // S_AB: area of the projected overlap polygon where g < h0
  Vec3 force = Vec3::Zero();   // ∫ P n̂_AB dS, acting on A; B receives −force
  // Nodal split of `force` (S18): nodal force on A's vertex i is  force_weight_a[i] · n̂_AB,
  // on B's vertex k it is  −force_weight_b[k] · n̂_AB; weights are ∫ P λ_i dS (the unique
  // collinear solution reproducing force and moment; sum of each triple = ∫ P dS).
  std::array<double, 3> force_weight_a{0, 0, 0};
  std::array<double, 3> force_weight_b{0, 0, 0};
  Vec3 center_of_pressure = Vec3::Zero();  // ∫ x P dS / ∫ P dS on the mid plane (centroid if ∫P≈0)
  Vec3 centroid = Vec3::Zero();            // centroid of the contact polygon (mid plane)
  // Barycentric coordinates of `centroid` in projected A and B (friction/stiffness weights
  // w_ik = bary_a[i]·bary_b[k]); non-negative, each sums to 1.
  std::array<double, 3> bary_a{0, 0, 0};
  std::array<double, 3> bary_b{0, 0, 0};
  double energy = 0;    // ∫ ½ k g² dS over the contact polygon (for consistency tests)
  double mean_gap = 0;  // ∫ g dS / S_AB
};

// a, b: the three vertices of triangles A and B (counter-clockwise seen from outside their
// cells). Returns an inactive contact when the triangles do not face each other
// (n̂_A·n̂_B ≥ 0), are degenerate (area ≤ 1e-14 · longest edge²) or non-finite, or their
// projections do not overlap within g < h0 (polygon area ≤ 1e-14 · the larger projected
// triangle area). An inactive contact is all zeros. There is no lower cut-off on g: a pair
// that interpenetrates deeply is pushed apart with P = k g, however negative g is.
// `area`, `force`, `centroid` are exact for every quadrature; `force_weight_*`,
// `center_of_pressure` and `energy` are exact for Exact and Dunavant7 only.
// With `moments`, also the pair's ContactMoments (all zeros for an inactive contact).
TriangleContact computeTriangleContact(const std::array<Vec3, 3>& a, const std::array<Vec3, 3>& b,
                                       const ContactLaw& law, ContactQuadrature quadrature,
                                       ContactMoments* moments = nullptr);

// A triangle's unit outward normal; `ok` is false for a degenerate or non-finite triangle (area ≤
// 1e-14 · longest edge²), which never makes contact. detectContacts computes it once per triangle
// (each is in ~8 candidate pairs of a packed aggregate) and passes it to the overload below,
// which gives the same result as the one above.
struct TriangleFrame {
  Vec3 normal = Vec3::Zero();
  bool ok = false;
};
TriangleFrame triangleFrame(const std::array<Vec3, 3>& p);
// What the overload below fills: everything, or what a ContactPair keeps (detectContacts): all
// fields but `centroid` and `center_of_pressure`, which stay zero (their mapping back to 3D was
// ~6 % of an active pair's cost). The fields filled are the same bits either way.
enum class ContactOutputs { All, PairOnly };
TriangleContact computeTriangleContact(const std::array<Vec3, 3>& a, const std::array<Vec3, 3>& b,
                                       const TriangleFrame& fa, const TriangleFrame& fb,
                                       const ContactLaw& law, ContactQuadrature quadrature,
                                       ContactMoments* moments = nullptr,
                                       ContactOutputs outputs = ContactOutputs::All);

// Broad phase: all pairs (tA, tB), tA < tB, of triangles of different cells whose axis-aligned
// bounding boxes, inflated by `margin`, overlap and whose normals face (n̂_A·n̂_B < 0).
// Ordered by the pair of cells (lower id, higher id), then by (tA, tB): each pair of cells' list
// is sorted on its own (CandidateCache sorts its stored lists once, when it builds them), and no
// sort of the whole list is needed. `tri_cell[t]` is the cell of triangle t (any int ids; same
// size as `tri`, else std::invalid_argument).
// Each box is inflated by `margin` on every side, so boxes up to 2·margin apart qualify:
// two points at gap g (along n̂_AB) are |g| apart, so margin = h0/2 catches every pair with a
// contact point at |g| ≤ h0 (a pair interpenetrating by more than 2·margin everywhere is not
// caught).
// Degenerate triangles (zero normal) never face anything. Runs in parallel (OpenMP) over
// overlapping cell pairs; the result does not depend on the thread count.
std::vector<std::pair<int, int>> findContactCandidates(const Eigen::Matrix3Xd& x,
                                                       const std::vector<Tri>& tri,
                                                       const std::vector<int>& tri_cell,
                                                       double margin);

// The O(T²) oracle with the same contract.
std::vector<std::pair<int, int>> findContactCandidatesBruteForce(const Eigen::Matrix3Xd& x,
                                                                 const std::vector<Tri>& tri,
                                                                 const std::vector<int>& tri_cell,
                                                                 double margin);

}  // namespace activefoam
