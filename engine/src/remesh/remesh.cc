// Brakke-style remeshing: longest-edge splits, shortest-edge collapses with volume-preserving
// placement, Delaunay edge flips (docs/model.md §6.3).
#include "activefoam/remesh.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <utility>

#include "remesher.h"

namespace activefoam {
namespace {

constexpr int kDead = -1;

inline int thirdVertex(const Tri& f, int i, int j) {
  for (int k = 0; k < 3; ++k)
    if (f[k] != i && f[k] != j) return f[k];
  return -1;
}

constexpr double kDelaunayTol = 1e-6;  // on sin(α+β): ≈ 1e-6 rad beyond 180°

// sin(α + β) for the angles α at k in (i,j,k) and β at l in (j,i,l) opposite edge i–j;
// negative ⇔ α + β > 180° (non-Delaunay edge).
double sinAngleSum(const Vec3& xi, const Vec3& xj, const Vec3& xk, const Vec3& xl) {
  const Vec3 u1 = xi - xk, v1 = xj - xk, u2 = xi - xl, v2 = xj - xl;
  const double d1 = u1.dot(v1), c1 = u1.cross(v1).norm();
  const double d2 = u2.dot(v2), c2 = u2.cross(v2).norm();
  const double den =
      std::sqrt(u1.squaredNorm() * v1.squaredNorm() * u2.squaredNorm() * v2.squaredNorm());
  return den > 0 ? (c1 * d2 + d1 * c2) / den : 0.0;
}

}  // namespace

namespace remesh_internal {

Remesher::Remesher(TriMesh& mesh, const RemeshParams& p, RemeshStats& st)
    : mesh_(mesh), p_(p), st_(st), tri_(mesh.tri) {
  const int nv = mesh.numVertices();
  x_.resize(nv);
  v_.resize(nv);
  const bool hasV = mesh.v.cols() == nv;  // else velocities start (and are written) as zero
  for (int i = 0; i < nv; ++i) {
    x_[i] = mesh.x.col(i);
    v_[i] = hasV ? Vec3(mesh.v.col(i)) : Vec3::Zero();
  }
  rep_.resize(nv);
  for (int i = 0; i < nv; ++i) rep_[i] = i;
  dead_.assign(nv, 0);
  alive_ = nv;
  vol_ = st.volume_before;
  if (p.on_surface) v0_ = volume();
}

void Remesher::passes() {
  const bool split_on = p_.max_area > 0, collapse_on = p_.min_area > 0;
  for (int pass = 0; pass < std::max(1, p_.max_passes); ++pass) {
    int changed = 0;
    if (split_on || collapse_on) computeAreas();
    if (split_on && anyArea([&](double a) { return a > p_.max_area; })) {
      for (int s = 0; s < p_.max_passes; ++s) {
        const int n = splitSweep();
        changed += n;
        if (n == 0) break;
        computeAreas();
      }
    }
    if (collapse_on && anyArea([&](double a) { return a < p_.min_area; })) {
      for (int s = 0; s < p_.max_passes; ++s) {
        const int n = collapseSweep();
        changed += n;
        if (n == 0) break;
        computeAreas();
      }
    }
    if (p_.flips) {
      for (int s = 0; s < p_.max_passes; ++s) {
        const int n = flipSweep();
        changed += n;
        if (n == 0) break;
      }
    }
    if (p_.smooth_min_angle_deg > 0) {
      for (int s = 0; s < p_.max_passes; ++s) {
        const int n = smoothSweep();
        changed += n;
        if (n == 0) break;
      }
    }
    if (changed == 0) break;
  }
}

// Writes back positions/velocities/triangles with unused vertices compacted out.
void Remesher::finish(std::vector<int>* old_to_new) {
  const int nin = mesh_.numVertices();
  if (st_.operations() == 0) {
    if (old_to_new) {
      old_to_new->resize(nin);
      for (int i = 0; i < nin; ++i) (*old_to_new)[i] = i;
    }
    return;
  }
  const int nv = static_cast<int>(x_.size());
  std::vector<int> newIndex(nv, -1);
  int n = 0;
  for (int i = 0; i < nv; ++i)
    if (!dead_[i]) newIndex[i] = n++;
  mesh_.x.resize(3, n);
  mesh_.v.resize(3, n);
  for (int i = 0; i < nv; ++i) {
    if (dead_[i]) continue;
    mesh_.x.col(newIndex[i]) = x_[i];
    mesh_.v.col(newIndex[i]) = v_[i];
  }
  for (Tri& f : tri_)
    for (int& k : f) k = newIndex[k];
  mesh_.tri = std::move(tri_);
  if (old_to_new) {
    old_to_new->resize(nin);
    for (int i = 0; i < nin; ++i) {
      int r = i;
      while (rep_[r] != r) r = rep_[r];
      (*old_to_new)[i] = newIndex[r];
    }
  }
}

// ---- snapshot structures ----
void Remesher::computeAreas() {
  area_.resize(tri_.size());
  for (size_t t = 0; t < tri_.size(); ++t) {
    const Tri& f = tri_[t];
    area_[t] = 0.5 * (x_[f[1]] - x_[f[0]]).cross(x_[f[2]] - x_[f[0]]).norm();
  }
}

void Remesher::buildIncidence() {
  const int nv = static_cast<int>(x_.size());
  incStart_.assign(nv + 1, 0);
  for (const Tri& f : tri_)
    for (int k : f) ++incStart_[k + 1];
  for (int i = 0; i < nv; ++i) incStart_[i + 1] += incStart_[i];
  inc_.resize(incStart_[nv]);
  fill_.assign(incStart_.begin(), incStart_.end() - 1);
  for (int t = 0; t < static_cast<int>(tri_.size()); ++t)
    for (int k : tri_[t]) inc_[fill_[k]++] = t;
  triTouched_.assign(tri_.size(), 0);
  vertTouched_.assign(nv, 0);
  if (static_cast<int>(stamp_.size()) < nv) stamp_.resize(nv, 0);
}

// The triangle of j's snapshot incidence list that currently holds the directed edge j→i,
// i.e. the neighbour across edge i→j; -1 if none does (it was replaced in this sweep).
int Remesher::opposite(int i, int j) const {
  for (int q = incStart_[j]; q < incStart_[j + 1]; ++q) {
    const Tri& f = tri_[inc_[q]];
    for (int k = 0; k < 3; ++k)
      if (f[k] == j && f[(k + 1) % 3] == i) return inc_[q];
  }
  return -1;
}

void Remesher::removeDeadTriangles() {
  tri_.erase(std::remove_if(tri_.begin(), tri_.end(), [](const Tri& f) { return f[0] == kDead; }),
             tri_.end());
}

// ---- split ----
int Remesher::splitSweep() {
  buildIncidence();
  const int nsnap = static_cast<int>(tri_.size());
  int n = 0;
  for (int t = 0; t < nsnap; ++t) {
    if (triTouched_[t] || area_[t] <= p_.max_area) continue;
    if (alive_ >= p_.max_vertices) break;
    const Tri f = tri_[t];
    int e = 0;
    double best = -1;
    for (int k = 0; k < 3; ++k) {
      const double l = (x_[f[(k + 1) % 3]] - x_[f[k]]).squaredNorm();
      if (l > best) best = l, e = k;
    }
    const int a = f[e], b = f[(e + 1) % 3], c = f[(e + 2) % 3];
    const int u = opposite(a, b);
    if (touchedTri(u, nsnap)) continue;
    const int d = thirdVertex(tri_[u], a, b);
    const int m = static_cast<int>(x_.size());
    x_.push_back(0.5 * (x_[a] + x_[b]));
    v_.push_back(0.5 * (v_[a] + v_[b]));
    dead_.push_back(0);
    rep_.push_back(m);
    ++alive_;
    tri_[t] = {a, m, c};
    tri_.push_back({m, b, c});
    tri_[u] = {b, m, d};
    tri_.push_back({m, a, d});
    triTouched_[t] = triTouched_[u] = 1;
    ++n;
  }
  st_.splits += n;
  return n;
}

// ---- collapse ----
int Remesher::collapseSweep() {
  buildIncidence();
  const int nsnap = static_cast<int>(tri_.size());
  int n = 0;
  for (int t = 0; t < nsnap; ++t) {
    if (triTouched_[t] || area_[t] >= p_.min_area) continue;
    const Tri f = tri_[t];
    int e = 0;
    double best = 1e300;
    for (int k = 0; k < 3; ++k) {
      const double l = (x_[f[(k + 1) % 3]] - x_[f[k]]).squaredNorm();
      if (l < best) best = l, e = k;
    }
    const int a = f[e], b = f[(e + 1) % 3], c = f[(e + 2) % 3];
    const int u = opposite(a, b);
    if (touchedTri(u, nsnap)) continue;
    const int d = thirdVertex(tri_[u], a, b);
    if (vertTouched_[a] || vertTouched_[b] || vertTouched_[c] || vertTouched_[d]) continue;
    if (!ringsUntouched(a, b)) continue;
    if (tryCollapse(t, u, a, b, c, d)) {
      ++n;
    } else {
      ++st_.refused_collapses;
    }
  }
  if (n) removeDeadTriangles();
  st_.collapses += n;
  return n;
}

bool Remesher::ringsUntouched(int a, int b) const {
  for (int i : {a, b})
    for (int q = incStart_[i]; q < incStart_[i + 1]; ++q)
      if (triTouched_[inc_[q]]) return false;
  return true;
}

// Collapse edge a→b of triangle t (= (a,b,c)), with u = (b,a,d), into a. False if refused.
bool Remesher::tryCollapse(int t, int u, int a, int b, int c, int d) {
  if (alive_ - 1 < p_.min_vertices) return false;
  // In the rescue c or d may drop to 3 (never lower: a collapse next to a vertex of valence 3
  // is refused either way).
  const int least = relaxed_ ? 3 : 4;
  if (valence(a) + valence(b) - 4 < 4 || valence(c) - 1 < least || valence(d) - 1 < least)
    return false;
  // Link condition: the common neighbours of a and b are exactly c and d.
  const int sa = ++stampId_, sb = ++stampId_;
  for (int q = incStart_[a]; q < incStart_[a + 1]; ++q)
    for (int w : tri_[inc_[q]])
      if (w != a) stamp_[w] = sa;
  int common = 0;
  for (int q = incStart_[b]; q < incStart_[b + 1]; ++q)
    for (int w : tri_[inc_[q]])
      if (w != b && w != a && stamp_[w] == sa) {
        stamp_[w] = sb;  // count each common neighbour once
        ++common;
      }
  if (common != 2) return false;

  // Volume-preserving placement. Coordinates relative to the edge midpoint o. The patch
  // volume after the collapse is p·g (p relative to o), g = Σ (1/6) x_j × x_k over the new
  // one-ring triangles (p, j, k); before, it is L_old = Σ (1/6) det over the old triangles.
  const Vec3 o = 0.5 * (x_[a] + x_[b]);
  double lold = 0, ringArea = 0;
  Vec3 g = Vec3::Zero();
  for (int i : {a, b})
    for (int q = incStart_[i]; q < incStart_[i + 1]; ++q) {
      const int s = inc_[q];
      const Tri& f = tri_[s];
      const Vec3 p0 = x_[f[0]] - o, p1 = x_[f[1]] - o, p2 = x_[f[2]] - o;
      if (s == t || s == u) {
        if (i == a) lold += p0.dot(p1.cross(p2)) / 6.0;  // t, u are in both rings: once
        continue;
      }
      lold += p0.dot(p1.cross(p2)) / 6.0;
      int k = 0;
      while (f[k] != i) ++k;
      const Vec3 xj = x_[f[(k + 1) % 3]] - o, xk = x_[f[(k + 2) % 3]] - o;
      const Vec3 c2 = xj.cross(xk);
      g += c2 / 6.0;
      ringArea += 0.5 * (p1 - p0).cross(p2 - p0).norm();
    }
  Vec3 pr = Vec3::Zero();
  const double gn = g.norm(), ab = (x_[b] - x_[a]).norm();
  // |g| is a third of the link polygon's vector area: ill-conditioned when it is tiny compared
  // with the ring area (strongly folded ring).
  if (gn > 1e-3 * ringArea / 3.0) {
    const double s = lold / gn;
    if (std::abs(s) <= 0.5 * ab) pr = (s / gn) * g;
  }
  // The placement stays local with on_surface too, although it moves the vertex along the
  // ring's normal (0.35–0.72 µm measured on 80-triangle cells): merged at the midpoint, with
  // the volume given back to the whole cell or to the two-ring, the junctions' rims flattened
  // and the passive spheroid's contact angle fell 1.5–2.5° below arccos α (0.6° with this), the
  // motile spheroid's 1.5–3° further (docs/numerics.md).
  if (std::abs(pr.dot(g) - lold) > p_.collapse_max_volume * std::abs(vol_)) return false;
  if (keptOut(o + pr, a, b)) return false;

  // Orientation/degeneracy guard on every surviving triangle of the two rings.
  const Vec3 pnew = o + pr;
  for (int i : {a, b})
    for (int q = incStart_[i]; q < incStart_[i + 1]; ++q) {
      const int s = inc_[q];
      if (s == t || s == u) continue;
      const Tri& f = tri_[s];
      int k = 0;
      while (f[k] != i) ++k;
      const Vec3& xj = x_[f[(k + 1) % 3]];
      const Vec3& xk = x_[f[(k + 2) % 3]];
      const Vec3 nold = (xj - x_[i]).cross(xk - x_[i]);
      const Vec3 nnew = (xj - pnew).cross(xk - pnew);
      const double nn = nnew.norm(), on = nold.norm();
      // Near-degenerate: below a small fraction of min_area (or of its old area).
      if (0.5 * nn <= 1e-3 * std::min(p_.min_area, 0.5 * on)) return false;
      if (nnew.dot(nold) <= 0.2 * nn * on) return false;
    }

  // Apply.
  x_[a] = pnew;
  v_[a] = 0.5 * (v_[a] + v_[b]);
  for (int q = incStart_[b]; q < incStart_[b + 1]; ++q) {
    Tri& f = tri_[inc_[q]];
    for (int& k : f)
      if (k == b) k = a;
  }
  for (int i : {a, b})
    for (int q = incStart_[i]; q < incStart_[i + 1]; ++q) triTouched_[inc_[q]] = 1;
  tri_[t] = {kDead, kDead, kDead};
  tri_[u] = {kDead, kDead, kDead};
  dead_[b] = 1;
  rep_[b] = a;
  --alive_;
  vertTouched_[a] = vertTouched_[b] = vertTouched_[c] = vertTouched_[d] = 1;
  return true;
}

// ---- flip ----
// Candidates first: an edge can violate Delaunay (α + β > 180°) only if one of its two
// opposite angles is obtuse, so only half-edges opposite an obtuse corner are examined (none
// on a good mesh: no incidence build, no opposite lookups).
int Remesher::flipSweep() {
  const int nt = static_cast<int>(tri_.size());
  cand_.clear();
  for (int t = 0; t < nt; ++t) {
    const Tri& f = tri_[t];
    for (int c = 0; c < 3; ++c) {
      const Vec3& xc = x_[f[c]];
      if ((x_[f[(c + 1) % 3]] - xc).dot(x_[f[(c + 2) % 3]] - xc) < 0) {
        cand_.push_back(3 * t + (c + 1) % 3);  // half-edge f[c+1] → f[c+2], opposite c
        break;                                 // at most one obtuse corner
      }
    }
  }
  if (cand_.empty()) return 0;
  buildIncidence();
  int n = 0;
  for (int he : cand_) {
    const int t = he / 3, e = he % 3;
    const Tri f = tri_[t];
    const int i = f[e], j = f[(e + 1) % 3], k = f[(e + 2) % 3];
    if (vertTouched_[i] || vertTouched_[j] || vertTouched_[k]) continue;
    const int u = opposite(i, j);
    if (u < 0) continue;  // cannot happen on a closed mesh
    const Tri fu = tri_[u];
    const int l = thirdVertex(fu, i, j);
    if (vertTouched_[l]) continue;
    // Both opposite corners obtuse: the edge is a candidate twice; handle it from the
    // lower-numbered triangle only.
    if (u < t && (x_[i] - x_[l]).dot(x_[j] - x_[l]) < 0) continue;
    if (!(sinOppositeAngleSum(i, j, k, l) < -kDelaunayTol)) continue;
    double dv = 0;
    if (!flipAllowed(i, j, k, l, dv)) {
      ++st_.refused_flips;
      continue;
    }
    tri_[t] = {l, k, i};
    tri_[u] = {k, l, j};
    // Kept with on_surface too: its moves are bounded by 5 % of the quad's shortest edge (3–15
    // nm measured in a spheroid), and without them a doublet that runs 1000 steps at Δt 1 s
    // met period-2 contact oscillation after 80–95 (docs/numerics.md).
    if (p_.flip_volume_correction && !compensateFlipVolume(t, u, {i, j, k, l}, dv)) {
      tri_[t] = f;
      tri_[u] = fu;
      ++st_.refused_flips;
      continue;
    }
    vertTouched_[i] = vertTouched_[j] = vertTouched_[k] = vertTouched_[l] = 1;
    ++n;
  }
  st_.flips += n;
  return n;
}

double Remesher::sinOppositeAngleSum(int i, int j, int k, int l) const {
  return sinAngleSum(x_[i], x_[j], x_[k], x_[l]);
}

bool Remesher::flipAllowed(int i, int j, int k, int l, double& dv) {
  if (k == l) return false;
  if (valence(i) - 1 < 4 || valence(j) - 1 < 4) return false;
  for (int q = incStart_[k]; q < incStart_[k + 1]; ++q)
    for (int w : tri_[inc_[q]])
      if (w == l) return false;  // k–l already an edge: flip would make it non-manifold
  // The new edge k–l must itself be Delaunay (no ping-pong on folded quads).
  if (!(sinOppositeAngleSum(k, l, j, i) > kDelaunayTol)) return false;
  const Vec3 &xi = x_[i], &xj = x_[j], &xk = x_[k], &xl = x_[l];
  const Vec3 nt = (xj - xi).cross(xk - xi), nu = (xi - xj).cross(xl - xj);
  const double ntn = nt.norm(), nun = nu.norm();
  if (ntn <= 0 || nun <= 0) return false;
  const Vec3 avg = (nt / ntn + nu / nun).normalized();
  const Vec3 n1 = (xk - xl).cross(xi - xl), n2 = (xl - xk).cross(xj - xk);
  const double n1n = n1.norm(), n2n = n2.norm();
  const double tiny = 1e-12 * (ntn + nun);
  if (n1n <= tiny || n2n <= tiny) return false;
  if (n1.dot(avg) <= 0.5 * n1n || n2.dot(avg) <= 0.5 * n2n) return false;
  // Volume change = the tetrahedron (i, j, k, l).
  dv = (xk - xi).dot((xl - xi).cross(xj - xi)) / 6.0;
  if (std::abs(dv) > p_.flip_max_volume * std::abs(vol_)) return false;
  return true;
}

// ∂V/∂x_q for the current triangles around q: Σ (1/6) (x_j − x_q) × (x_k − x_q) over the
// triangles (q, j, k). The ring is the snapshot incidence of q plus the flipped pair t, u.
Vec3 Remesher::volumeGradient(int q, int t, int u) const {
  Vec3 g = Vec3::Zero();
  auto add = [&](int s) {
    const Tri& f = tri_[s];
    int k = 0;
    while (k < 3 && f[k] != q) ++k;
    if (k == 3) return;
    g += (x_[f[(k + 1) % 3]] - x_[q]).cross(x_[f[(k + 2) % 3]] - x_[q]) / 6.0;
  };
  for (int r = incStart_[q]; r < incStart_[q + 1]; ++r)
    if (inc_[r] != t && inc_[r] != u) add(inc_[r]);
  add(t);
  add(u);
  return g;
}

// After flipping t, u (now (l,k,i), (k,l,j)), remove the volume change dv by moving each of
// the four vertices along its volume gradient by a quarter of it. The volume is affine in one
// vertex, so solving vertex by vertex with the current gradients makes the correction exact.
// False (nothing moved) if a move would exceed 5% of the shortest quad edge.
bool Remesher::compensateFlipVolume(int t, int u, std::array<int, 4> q, double dv) {
  if (dv == 0) return true;
  const Vec3 &xi = x_[q[0]], &xj = x_[q[1]], &xk = x_[q[2]], &xl = x_[q[3]];
  const double emin =
      std::sqrt(std::min({(xi - xk).squaredNorm(), (xi - xl).squaredNorm(), (xj - xk).squaredNorm(),
                          (xj - xl).squaredNorm(), (xk - xl).squaredNorm()}));
  const double maxMove = 0.05 * emin;
  for (int w : q) {
    const double gn = volumeGradient(w, t, u).norm();
    if (!(0.25 * std::abs(dv) < maxMove * gn)) return false;
  }
  for (int w : q) {
    const Vec3 g = volumeGradient(w, t, u);
    x_[w] -= (0.25 * dv / g.squaredNorm()) * g;
  }
  return true;
}

}  // namespace remesh_internal

namespace {

using remesh_internal::Remesher;

RemeshStats remeshImpl(TriMesh& mesh, const RemeshParams& params, std::vector<int>* old_to_new) {
  RemeshStats st;
  st.volume_before = meshVolume(mesh);
  Remesher r(mesh, params, st);
  r.run();
  r.restoreVolume();
  r.finish(old_to_new);
  remesh_internal::rebuildIfLeftSmall(mesh, params, old_to_new, st);
  st.volume_after = st.operations() ? meshVolume(mesh) : st.volume_before;
  return st;
}

}  // namespace

RemeshStats remesh(TriMesh& mesh, const RemeshParams& params) {
  return remeshImpl(mesh, params, nullptr);
}

RemeshStats remesh(TriMesh& mesh, const RemeshParams& params, std::vector<int>& old_to_new) {
  return remeshImpl(mesh, params, &old_to_new);
}

}  // namespace activefoam
