#include "activefoam/step_guards.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <iomanip>
#include <limits>
#include <sstream>
#include <utility>

#include <Eigen/Geometry>

#include "activefoam/contacts.h"

namespace activefoam {

namespace {

std::string at(double t) {
  std::ostringstream os;
  os << " at t=" << t << " s";
  return os.str();
}

class NonFiniteGuard : public StepGuard {
 public:
  std::string_view name() const override { return "non-finite"; }
  Phase phase() const override { return Phase::Solved; }
  std::optional<StepFailure> check(const GuardView& g) override {
    const bool f_ok = g.force->allFinite();
    if (f_ok && g.v->allFinite()) return std::nullopt;
    return StepFailure{FailureKind::NonFinite,
                       std::string("non-finite ") + (f_ok ? "velocity" : "force") + at(g.t)};
  }
};

class CgGuard : public StepGuard {
 public:
  std::string_view name() const override { return "cg-not-converged"; }
  Phase phase() const override { return Phase::Solved; }
  std::optional<StepFailure> check(const GuardView& g) override {
    if (g.cg->converged) return std::nullopt;
    std::ostringstream why;
    why << "CG did not reach the tolerance " << g.spec.numerics.cg_tol << " in " << g.cg->iterations
        << " iterations (relative residual " << g.cg->residual << ")" << at(g.t);
    return StepFailure{FailureKind::CgNotConverged, why.str()};
  }
};

// The period-2 signature of an explicit contact scheme past its stability limit: contacting
// vertices that move by a noticeable fraction of h0 per step mostly reverse their velocity from
// one step to the next, for numerics.max_oscillating_steps steps in a row.
class OscillationGuard : public StepGuard {
 public:
  std::string_view name() const override { return "contact-oscillation"; }
  Phase phase() const override { return Phase::Solved; }
  std::int64_t count() const override { return steps_; }
  void setCount(std::int64_t n) override { steps_ = n; }
  std::optional<StepFailure> check(const GuardView& g) override {
    const ContactList& contacts = *g.contacts;
    const Eigen::VectorXd& v = *g.v;
    const double floor = 0.1 * g.law->h0 / g.dt;  // µm/s
    double dot = 0, norms = 0;
    int moving = 0;
    for (int i = 0; i < g.cells.numVertices(); ++i) {
      if (contacts.vertex_contact_area[i] <= 0) continue;
      const Vec3 now = v.segment<3>(3 * i), before = g.cells.v.col(i);
      if (now.norm() < floor || before.norm() < floor) continue;
      ++moving;
      dot += now.dot(before);
      norms += now.norm() * before.norm();
    }
    steps_ = moving > 0 && dot < -0.5 * norms ? steps_ + 1 : 0;
    if (steps_ < g.spec.numerics.max_oscillating_steps) return std::nullopt;
    std::ostringstream why;
    why << "contact velocities reversed in " << steps_ << " consecutive steps" << at(g.t)
        << ": the contact springs are too stiff for dt = " << g.dt << " s with the "
        << toString(g.spec.numerics.integrator)
        << " integrator (use contact-implicit or a smaller dt)";
    return StepFailure{FailureKind::ContactOscillation, why.str()};
  }

 private:
  std::int64_t steps_ = 0;
};

// A triangle whose normal turned by more than 90° in one step has inverted.
class InvertedTriangleGuard : public StepGuard {
 public:
  std::string_view name() const override { return "inverted-triangle"; }
  Phase phase() const override { return Phase::Moved; }
  std::optional<StepFailure> check(const GuardView& g) override {
    for (int t = 0; t < g.cells.numTriangles(); ++t) {
      if (g.geo.tri_area[t] > 0 && g.geo.tri_normal[t].dot(g.geo_before->tri_normal[t]) >= 0)
        continue;
      std::ostringstream why;
      why << "triangle " << t << " of cell " << g.cells.tri_cell[t] << " inverted" << at(g.t + g.dt)
          << " (time step too large for the forces?)";
      describe(why, g, t);
      return StepFailure{FailureKind::InvertedTriangle, why.str()};
    }
    return std::nullopt;
  }

 private:
  // Its shape and contact at the step's start (the positions adaptive stepping keeps; else at
  // its end), which tell the two known causes apart: a sliver the remesher left (a long edge,
  // a small height, an angle near 180°) and a contact pair pressing it (its contact fraction).
  static void describe(std::ostream& why, const GuardView& g, int t) {
    const bool start =
        g.cells_before != nullptr && g.cells_before->topology_version == g.cells.topology_version;
    const Eigen::Matrix3Xd& x = start ? g.cells_before->x : g.cells.x;
    const Tri& f = g.cells.tri[t];
    std::array<double, 3> edge{}, angle{};
    for (int k = 0; k < 3; ++k) {
      const Vec3 p = x.col(f[k]), q = x.col(f[(k + 1) % 3]), r = x.col(f[(k + 2) % 3]);
      edge[k] = (q - p).norm();
      angle[k] = std::atan2((q - p).cross(r - p).norm(), (q - p).dot(r - p)) * 180 / M_PI;
    }
    const double area = 0.5 * (x.col(f[1]) - x.col(f[0])).cross(x.col(f[2]) - x.col(f[0])).norm();
    const double longest = *std::max_element(edge.begin(), edge.end());
    const double r = g.cells.radius[g.cells.tri_cell[t]];
    const double a_ref = 4 * M_PI * r * r / g.spec.numerics.triangles_per_cell;
    std::ostringstream d;
    d.precision(3);
    d << "; " << (start ? "at the step's start" : "at its end") << " its edges were " << edge[0]
      << ", " << edge[1] << ", " << edge[2] << " µm, its height on the longest "
      << (longest > 0 ? 2 * area / longest : 0) << " µm, its largest angle "
      << *std::max_element(angle.begin(), angle.end()) << "°, its area " << area / a_ref
      << " × 4πr²/N (the remesher's reference)";
    if (g.contacts != nullptr && t < static_cast<int>(g.contacts->tri_contact_fraction.size()))
      d << ", in contact over " << 100 * g.contacts->tri_contact_fraction[t] << " % of it";
    why << d.str();
  }
};

class VolumeGuard : public StepGuard {
 public:
  std::string_view name() const override { return "volume-drift"; }
  Phase phase() const override { return Phase::Moved; }
  std::optional<StepFailure> check(const GuardView& g) override {
    const double limit = g.spec.numerics.max_volume_error;
    for (int c = 0; c < g.cells.numCells(); ++c) {
      const double v0 = g.cells.target_volume[c];
      const double eps = (g.geo.cell_volume[c] - v0) / v0;
      if (std::abs(eps) <= limit) continue;
      std::ostringstream why;
      why << "cell " << c << " volume error " << eps << " exceeds numerics.max_volume_error "
          << limit << at(g.t + g.dt);
      return StepFailure{FailureKind::VolumeDrift, why.str()};
    }
    return std::nullopt;
  }
};

// Single triangle pairs are no measure: where two surfaces meet at a rim at ~70° a pair
// overlaps by a sliver of 1e-4 µm² whose mean gap along the pair normal reads −0.5 … −1.6 µm
// while the cells do not overlap (measured on a 2 × 8-cell fusion; it stopped runs at
// t = 990 s); nor is a pair of cells' mean gap (see interpenetration()).
class InterpenetrationGuard : public StepGuard {
 public:
  std::string_view name() const override { return "interpenetration"; }
  Phase phase() const override { return Phase::Detected; }
  std::optional<StepFailure> check(const GuardView& g) override {
    std::string why = interpenetration(g.cells, *g.contacts, g.spec.numerics.max_penetration_um,
                                       g.t + g.dt, scratch_, g.cells_before, g.remeshed);
    if (why.empty()) return std::nullopt;
    return StepFailure{FailureKind::Interpenetration, std::move(why)};
  }

 private:
  PenetrationScratch scratch_;
};

// The deepest of `verts` inside cell c: (depth, vertex), depth 0 when none is inside.
std::pair<double, int> deepestInside(const CellSet& cells, const std::vector<int>& verts, int c) {
  std::pair<double, int> deepest{0.0, -1};
  for (const int v : verts) {
    const Vec3 p = cells.x.col(v);
    if (!(windingNumber(cells, c, p) > 0.5)) continue;
    const double d = distanceToSurface(cells, c, p);
    if (d > deepest.first) deepest = {d, v};
  }
  return deepest;
}

struct PairDepth {
  double depth = 0;
  int vertex = -1, inside = -1;  // the deepest vertex and its cell
};

// The deepest vertex of cell a inside cell b or of b inside a, among the vertices within both
// cells' bounding boxes (the vertices of the contact triangles missed the deepest one of two
// spheres 2.4 µm into each other).
PairDepth deepestBetween(const CellSet& cells, int a, int b, PenetrationScratch& scratch) {
  Eigen::AlignedBox3d box_a, box_b;
  for (int v = cells.cell_vertex_begin[a]; v < cells.cell_vertex_begin[a + 1]; ++v)
    box_a.extend(cells.x.col(v));
  for (int v = cells.cell_vertex_begin[b]; v < cells.cell_vertex_begin[b + 1]; ++v)
    box_b.extend(cells.x.col(v));
  const Eigen::AlignedBox3d both = box_a.intersection(box_b);
  scratch.va.clear();
  scratch.vb.clear();
  for (int v = cells.cell_vertex_begin[a]; v < cells.cell_vertex_begin[a + 1]; ++v)
    if (both.contains(cells.x.col(v))) scratch.va.push_back(v);
  for (int v = cells.cell_vertex_begin[b]; v < cells.cell_vertex_begin[b + 1]; ++v)
    if (both.contains(cells.x.col(v))) scratch.vb.push_back(v);
  const auto [da, va] = deepestInside(cells, scratch.va, b);
  const auto [db, vb] = deepestInside(cells, scratch.vb, a);
  return da >= db ? PairDepth{da, va, a} : PairDepth{db, vb, b};
}

// The squared distance from p to cell c's surface and the triangle that attains it (the first
// of equals, in the cell's triangle order).
std::pair<double, int> nearestTriangle(const CellSet& cells, int c, const Vec3& p) {
  std::pair<double, int> best{std::numeric_limits<double>::infinity(), -1};
  for (int t = cells.cell_tri_begin[c]; t < cells.cell_tri_begin[c + 1]; ++t) {
    const Tri& tr = cells.tri[t];
    const Vec3 q = closestOnTriangle(p, cells.x.col(tr[0]), cells.x.col(tr[1]), cells.x.col(tr[2]));
    const double d2 = (q - p).squaredNorm();
    if (d2 < best.first) best = {d2, t};
  }
  return best;
}

// How the deepest vertex's surface lies against the cell it is inside: the cosine between its
// one-ring's area vector and the outward normal of that cell's nearest triangle. Two membranes
// pressed into each other read near −1; a sheet that has slid through the other's membrane (at
// p_a r/2γ = 1, α 0.3 every interpenetration read so, +0.06 … +0.95:
// docs/science/fig8-pa1-probe/) faces the same way, > 0, and the contact, which pushes facing
// triangles apart, has nothing to push it back with.
double facingCosine(const CellSet& cells, int vertex, int inside_of) {
  const int c = cells.vertex_cell[vertex];
  Vec3 ring = Vec3::Zero();
  for (int t = cells.cell_tri_begin[c]; t < cells.cell_tri_begin[c + 1]; ++t) {
    const Tri& tr = cells.tri[t];
    if (tr[0] != vertex && tr[1] != vertex && tr[2] != vertex) continue;
    ring +=
        (cells.x.col(tr[1]) - cells.x.col(tr[0])).cross(cells.x.col(tr[2]) - cells.x.col(tr[0]));
  }
  const Tri& near = cells.tri[nearestTriangle(cells, inside_of, cells.x.col(vertex)).second];
  const Vec3 a = cells.x.col(near[0]);
  const Vec3 normal = (cells.x.col(near[1]) - a).cross(cells.x.col(near[2]) - a);
  const double n = ring.norm() * normal.norm();
  return n > 0 ? ring.dot(normal) / n : 0.0;
}

}  // namespace

double windingNumber(const CellSet& cells, int c, const Vec3& p) {
  double omega = 0;
  for (int t = cells.cell_tri_begin[c]; t < cells.cell_tri_begin[c + 1]; ++t) {
    const Tri& tr = cells.tri[t];
    omega += solidAngle(p, cells.x.col(tr[0]), cells.x.col(tr[1]), cells.x.col(tr[2]));
  }
  return omega / (4 * M_PI);
}

double distanceToSurface(const CellSet& cells, int c, const Vec3& p) {
  return std::sqrt(nearestTriangle(cells, c, p).first);
}

std::string interpenetration(const CellSet& cells, const ContactList& contacts, double limit,
                             double t, PenetrationScratch& scratch, const CellSet* before,
                             const std::vector<char>* remeshed) {
  std::vector<PairGap>& pairs = scratch.pairs;
  pairs.clear();
  for (const ContactPair& p : contacts.pairs) {
    int a = cells.tri_cell[p.ta], b = cells.tri_cell[p.tb];
    if (a > b) std::swap(a, b);
    pairs.push_back({(static_cast<std::uint64_t>(a) << 32) | static_cast<std::uint32_t>(b),
                     p.c.mean_gap * p.c.area, p.c.area});
  }
  // detectContacts lists the pairs grouped by pair of cells already (the broad phase's order):
  // the sort is then skipped.
  const auto by_key = [](const auto& x, const auto& y) { return x.key < y.key; };
  if (!std::is_sorted(pairs.begin(), pairs.end(), by_key))
    std::stable_sort(pairs.begin(), pairs.end(), by_key);
  for (std::size_t i = 0; i < pairs.size();) {
    double gs = 0, area = 0;
    std::size_t j = i;
    for (; j < pairs.size() && pairs[j].key == pairs[i].key; ++j) {
      gs += pairs[j].gap_area;
      area += pairs[j].area;
    }
    const std::size_t begin = i;
    i = j;
    if (!(area > 0 && -gs / area > 0.25 * limit)) continue;
    const int a = static_cast<int>(pairs[begin].key >> 32);
    const int b = static_cast<int>(pairs[begin].key & 0xffffffffULL);
    const PairDepth d = deepestBetween(cells, a, b, scratch);
    if (!(d.depth > limit)) continue;
    // A step that did not deepen it is no failure of the step: halving it could not undo an
    // overlap it started with (the first 24 h rerun stopped so at 2.4 h, a vertex 1.218 µm in at
    // every step down to the floor), and the contact forces are pushing it out.
    double at_start = -1;
    if (before != nullptr) {
      at_start = deepestBetween(*before, a, b, scratch).depth;
      if (d.depth <= at_start) continue;
    }
    std::ostringstream why;
    why << "cells " << a << " and " << b << " interpenetrate: vertex " << d.vertex << " of cell "
        << d.inside << " lies " << d.depth << " µm inside cell " << (d.inside == a ? b : a)
        << " > numerics.max_penetration_um = " << limit << " µm";
    if (at_start >= 0) why << " (" << at_start << " µm at the step's start)";
    why << " (their contact's mean gap: " << gs / area << " µm)" << at(t);
    const int other = d.inside == a ? b : a;
    const double cosine = facingCosine(cells, d.vertex, other);
    why << "; its surface " << (cosine > 0 ? "faces the way of" : "faces") << " cell " << other
        << "'s there (cosine " << std::showpos << std::setprecision(2) << cosine << std::noshowpos
        << std::setprecision(6) << ")"
        << (cosine > 0 ? ": the membranes have crossed" : ": pressed in");
    // Whether the remesher moved them: a collapse places its merged vertex to keep the cell's
    // volume, which the remesher does without looking at the neighbours.
    if (remeshed != nullptr)
      for (const int c : {a, b}) {
        const bool r = !remeshed->empty() && (*remeshed)[c];  // empty: no cell was due
        why << "; the step " << (r ? "remeshed" : "did not remesh") << " cell " << c;
      }
    return why.str();
  }
  return {};
}

class StepErrorGuard : public StepGuard {
 public:
  std::string_view name() const override { return "step-error"; }
  Phase phase() const override { return Phase::Solved; }
  std::optional<StepFailure> check(const GuardView& g) override {
    const NumericsParams& n = g.spec.numerics;
    if (!(n.max_step_error_um > 0) || !(g.step_error_um > n.max_step_error_um)) return std::nullopt;
    if (0.5 * g.dt < dtMinS(n)) return std::nullopt;  // at the floor
    std::ostringstream why;
    why << "error estimate " << g.step_error_um << " µm of a " << g.dt
        << " s step exceeds numerics.max_step_error_um = " << n.max_step_error_um << at(g.t);
    return StepFailure{FailureKind::StepError, why.str()};
  }
};

std::unique_ptr<StepGuard> stepErrorGuard() {
  return std::make_unique<StepErrorGuard>();
}

std::vector<std::unique_ptr<StepGuard>> standardGuards(bool with_contacts) {
  std::vector<std::unique_ptr<StepGuard>> g;
  g.push_back(std::make_unique<NonFiniteGuard>());
  g.push_back(std::make_unique<CgGuard>());
  if (with_contacts) g.push_back(std::make_unique<OscillationGuard>());
  g.push_back(std::make_unique<InvertedTriangleGuard>());
  g.push_back(std::make_unique<VolumeGuard>());
  if (with_contacts) g.push_back(std::make_unique<InterpenetrationGuard>());
  return g;
}

}  // namespace activefoam
