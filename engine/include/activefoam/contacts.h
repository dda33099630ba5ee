// The per-step contact set between cells (docs/model.md §3) and the terms that use it.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <unordered_map>
#include <utility>
#include <vector>

#include "activefoam/contact_geometry.h"
#include "activefoam/force_term.h"
#include "activefoam/spec.h"

namespace activefoam {

// What a step reads of a TriangleContact, kept per pair: 144 of its 224 bytes (the force, centroid
// and centre of pressure are for tests of the contact geometry). The pair list of the 2 × 100
// fusion is written once per detection and read by every contact term and guard: its size is
// bandwidth (docs/benchmarks.md, "6. Where a step goes").
struct PairContact {
  Vec3 normal = Vec3::Zero();
  double area = 0;
  std::array<double, 3> force_weight_a{0, 0, 0};
  std::array<double, 3> force_weight_b{0, 0, 0};
  std::array<double, 3> bary_a{0, 0, 0};
  std::array<double, 3> bary_b{0, 0, 0};
  double energy = 0;
  double mean_gap = 0;
  PairContact() = default;
  // Implicit: a pair is made from the narrow phase's result as it is.
  PairContact(const TriangleContact& t)  // NOLINT(google-explicit-constructor)
      : normal(t.normal),
        area(t.area),
        force_weight_a(t.force_weight_a),
        force_weight_b(t.force_weight_b),
        bary_a(t.bary_a),
        bary_b(t.bary_b),
        energy(t.energy),
        mean_gap(t.mean_gap) {}
};

struct ContactPair {
  int ta, tb;  // triangles of different cells; ta < tb
  PairContact c;
};

// The contact pairs split among threads that each own a range of whole cells: a thread walks,
// in pair order, the pairs with a triangle in its cells and writes only its own cells' vertices.
// Each vertex thus receives its pairs' shares in pair order — the sums one thread walking all
// pairs takes — for any number of parts (a pair across two parts is evaluated by both). The
// forces, the friction diagonal and the coupling product go through it.
// (It replaced a per-vertex gather through an incidence list, which read each pair's data six
// times in vertex order: on the 2 × 100-cell fusion, ~130 000 pairs whose data outgrow the
// cache, that doubled the time per CG iteration against a plain loop over the pairs.)
struct ContactPartition {
  std::size_t num_pairs = 0;        // the pair count it was built for
  int parts = 0;                    // 1: every pair, both sides, in order (no items stored)
  std::vector<std::int64_t> begin;  // items of part p: item[begin[p] .. begin[p + 1])
  std::vector<std::uint64_t> item;  // pair << 2 | owns tb's side << 1 | owns ta's side
  // Parts for `pairs`: `parts` ranges of cells with about equal numbers of pair sides each.
  void build(const std::vector<ContactPair>& pairs, const std::vector<int>& tri_cell, int num_cells,
             int parts);
};
// The parts a kernel over `num_pairs` pairs uses now: the engine's thread count, or 1 below
// Grain::min_items.
int contactParts(std::size_t num_pairs);

struct ContactList {
  std::vector<ContactPair> pairs;        // active pairs this step
  std::vector<ContactMoments> moments;   // theirs, when the law asks for them (ros2), else empty
  std::vector<double> tri_contact_area;  // Σ S_AB over the pairs a triangle takes part in
  std::vector<double> tri_contact_fraction;  // f_A = min(1, contact area / S_A)
  std::vector<double> vertex_contact_area;   // S_i^c = Σ_{A∋i} f_A S_A / 3
  std::vector<double> cell_contact_area;     // S_c,l = Σ_{A∈l} f_A S_A
  // Built by detectContacts for the thread count of the time; a list whose pairs were set by
  // hand has none (num_pairs differs), or one for another thread count, and the terms build one
  // for themselves.
  ContactPartition partition;
  // detectContacts' buffers for the narrow phase's per-thread ranges after the first (which
  // writes into `pairs`), kept so that the next detection reuses their memory: allocated afresh,
  // the pairs of the 2 × 100-cell fusion cost page faults at every detection. Not part of the
  // contact set.
  struct NarrowBuffer {
    std::vector<ContactPair> pairs;
    std::vector<ContactMoments> moments;
  };
  std::vector<NarrowBuffer> narrow_buffers;
  std::vector<TriangleFrame> tri_frames;  // per triangle, for the narrow phase
};

// The broad phase of a simulation, keeping its work between steps (a Verlet list per pair of
// cells). For each pair of cells whose boxes overlap it stores the triangle pairs whose boxes,
// inflated by margin + skin, overlapped when the list was built; a step only filters that list
// with the current boxes and normals. A cell's lists are rebuilt when its triangles changed
// (remeshing) or one of its vertices has moved more than skin/2 along some axis since the cell's
// last rebuild. So no vertex has moved more than `skin` since a stored list was built (≤ skin/2
// from its cell's reference then and now), less than the boxes were inflated by: the filtered
// list is exactly findContactCandidates' — no pair is missed and the trajectory does not
// depend on the skin.
// Work per step: O(cells + triangles + stored pairs) plus the sweeps of the cells that moved.
class CandidateCache {
 public:
  explicit CandidateCache(double skin_um) : skin_(skin_um) {}
  // Exactly findContactCandidates(cells.x, cells.tri, cells.tri_cell, margin).
  std::vector<std::pair<int, int>> find(const CellSet& cells, double margin);
  struct Stats {
    std::int64_t cells_rebuilt = 0;      // cells whose lists were dropped (moved, remeshed, new)
    std::int64_t cell_pairs_built = 0;   // triangle sweeps of a pair of cells
    std::int64_t cell_pairs_reused = 0;  // stored lists filtered instead
  };
  const Stats& stats() const { return stats_; }

 private:
  struct CellRef {
    bool valid = false;
    Eigen::Matrix3Xd x;    // the cell's vertices at its last rebuild
    std::vector<Tri> tri;  // its triangles then, in local vertex indices
  };
  double skin_;
  double margin_ = -1;
  std::uint64_t topology_version_ = 0;
  std::vector<CellRef> ref_;
  // (cell a << 32 | cell b), a < b → (local triangle of a, local triangle of b)
  std::unordered_map<std::uint64_t, std::vector<std::pair<int, int>>> lists_;
  Stats stats_;
  void clear();  // forgets everything: the next find() rebuilds every cell
};

// Finds the active contact pairs of the current geometry: broad phase with margin h0 (through
// `cache` if given, else from scratch), then the narrow phase on every candidate; fills the
// per-triangle, per-vertex and per-cell areas.
void detectContacts(const CellSet& cells, const Geometry& geo, const ContactLaw& law,
                    ContactQuadrature quadrature, ContactList& out,
                    CandidateCache* cache = nullptr);

// Adhesion/repulsion (S17–S18): nodal forces from each pair's linear pressure.
class ContactAdhesion : public ForceTerm {
 public:
  std::string_view name() const override { return "contact_adhesion"; }
  double addForces(const StepContext& ctx, Eigen::Matrix3Xd& f) const override;
};

// Friction (S14–S16) with barycentric weights w_ik = λ_i^A(c) λ_k^B(c), plus — for the
// contact-implicit integrator (StepContext::contact_stiffness_dt = Δt) — the linearised normal
// stiffness Δt k_AB S w_ik n̂n̂ᵀ of the contact springs, so that Γ v = F becomes (Γ + Δt K_c) v = F.
// Both are PSD couplings. With StepContext::consistent_stiffness (ros2) K_c is instead the
// stiffness of the spring field, k ∫ δg² dS / 2 (TriangleContact::m_*): PSD, and it also couples
// the vertices of each triangle among themselves (mesh edges, applied in the product).
class ContactFriction : public ForceTerm {
 public:
  explicit ContactFriction(const CellParams& p)
      : xi_n_(p.xi_normal.value_or(p.xi)), xi_t_(p.xi_tangential.value_or(p.xi)), k_(p.k_contact) {}
  std::string_view name() const override { return "contact_friction"; }
  // The couplings are a product, pair by pair (~100 bytes a pair, no pattern): assembled, those
  // of a 2 × 100-cell aggregate were ~10⁶ blocks, assembly took longer than the CG solve and each
  // product streamed ~100 MB.
  void addFriction(const StepContext& ctx, FrictionOperator& op) const override;

  // One part of this term's Γ as a term of its own (the dissipation probe's split): the friction
  // across the contact plane (ξ∥), along its normal (ξ⊥), or the contact springs' stiffness that
  // the step context puts in Γ (StepContext::contact_stiffness_dt; none when it is 0). Γ is
  // linear in ξ∥, ξ⊥ and k_AB: the three parts sum to the term's Γ.
  enum class Part { Tangential, Normal, Springs };
  ContactFriction part(Part which) const;

 private:
  ContactFriction(double xi_n, double xi_t, double k) : xi_n_(xi_n), xi_t_(xi_t), k_(k) {}
  // Its friction block, with the stiffness factor of the step (StepContext).
  Eigen::Matrix3d pairMatrix(const ContactPair& p, double stiffness_dt) const;
  double xi_n_, xi_t_, k_;
};

}  // namespace activefoam
