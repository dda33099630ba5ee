// Narrow phase of the triangle–triangle contact (docs/model.md §3, supplement S14–S18).
//
// Both triangles are projected onto the plane ⟂ n̂_AB (2D coordinates y in an orthonormal basis
// e1, e2 with e1 × e2 = n̂_AB, origin o = mean of the six vertices), clipped against each other
// and against the half-plane g(y) < h0, and the affine pressure P = k g is integrated over the
// resulting convex polygon with the requested quadrature, fan-triangulated from its first vertex.
#include <algorithm>
#include <cmath>

#include <Eigen/Geometry>

#include "activefoam/contact_geometry.h"

namespace activefoam {
namespace {

using Vec2 = Eigen::Vector2d;

// A triangle is degenerate when its area is below this fraction of its longest edge squared.
constexpr double kDegenerateRel = 1e-14;
// A contact polygon whose area is below this fraction of the larger projected triangle area is
// treated as empty (roundoff slivers from touching edges).
constexpr double kEmptyPolygonRel = 1e-14;
// |∫P dS| below this fraction of S · k · max|g| counts as "∫P ≈ 0": the centre of pressure is
// then reported as the polygon centroid (the nodal weights need no such special case).
constexpr double kZeroLoadRel = 1e-9;

inline double cross2(const Vec2& u, const Vec2& v) {
  return u.x() * v.y() - u.y() * v.x();
}

// Convex polygon with at most 3 + 11 vertices (a triangle clipped by the other's 3 edges, the
// law's range and, under the prisms laws, the split at g = 0 and both triangles' 3 prism
// sides; each clip of a convex polygon adds at most one vertex), and slots to spare. One more
// slot than the cap: a clip may write a vertex and a crossing before it checks the cap.
constexpr int kMaxPolygon = 17;
struct Polygon {
  std::array<Vec2, kMaxPolygon + 1> v;
  int n = 0;
};

// Sutherland–Hodgman step: keep the part of `in` where the affine function d(y) ≥ 0, into `out`
// (the clips ping-pong between two polygons: returning one by value per clipping line cost ~5 %
// of an active pair). Intersections use the linear interpolation of d. At most kMaxPolygon
// vertices are kept, which a convex input never reaches. (A variant without data-dependent
// branches, writing every candidate vertex and advancing the count over those kept, was slower:
// 196 → 232 ns an active pair.)
template <class F>
void clipHalfPlane(const Polygon& in, Polygon& out, F&& dist) {
  const int n = in.n;
  std::array<double, kMaxPolygon + 1> d;  // in.n ≤ kMaxPolygon + 1 (the slot above)
  for (int i = 0; i < n; ++i) d[i] = dist(in.v[i]);
  int m = 0;
  for (int i = 0; i < n; ++i) {
    const int j = i + 1 == n ? 0 : i + 1;  // not %: an integer division per vertex
    const double dc = d[i], dn = d[j];
    if (dc >= 0) out.v[m++] = in.v[i];
    if ((dc > 0 && dn < 0) || (dc < 0 && dn > 0)) {
      const double t = dc / (dc - dn);
      out.v[m++] = in.v[i] + t * (in.v[j] - in.v[i]);
    }
    if (m >= kMaxPolygon) break;
  }
  out.n = std::min(m, kMaxPolygon);
}

// Barycentric coordinates of y in the 2D triangle p (any orientation), as ratios of signed
// areas, so that Σ λ_i = 1 and Σ λ_i p_i = y hold for every y (affine reproduction).
struct Barycentric {
  std::array<Vec2, 3> p;
  double inv_twice_area;
  explicit Barycentric(const std::array<Vec2, 3>& pts) : p(pts) {
    inv_twice_area = 1.0 / cross2(p[1] - p[0], p[2] - p[0]);
  }
  std::array<double, 3> operator()(const Vec2& y) const {
    const double l0 = cross2(p[1] - y, p[2] - y) * inv_twice_area;
    const double l1 = cross2(p[2] - y, p[0] - y) * inv_twice_area;
    return {l0, l1, 1.0 - l0 - l1};
  }
};

// Quadrature rules on a triangle in barycentric coordinates, weights summing to 1.
struct QuadPoint {
  double b0, b1, b2, w;
};

// Dunavant's degree-5, 7-point rule (closed form of the weights and points).
const std::array<QuadPoint, 7>& dunavant7Rule() {
  static const std::array<QuadPoint, 7> r = [] {
    const double s15 = std::sqrt(15.0);
    const double b1 = (6.0 + s15) / 21.0, a1 = 1.0 - 2.0 * b1;
    const double b2 = (6.0 - s15) / 21.0, a2 = 1.0 - 2.0 * b2;
    const double w1 = (155.0 + s15) / 1200.0, w2 = (155.0 - s15) / 1200.0;
    return std::array<QuadPoint, 7>{{{1.0 / 3.0, 1.0 / 3.0, 1.0 / 3.0, 9.0 / 40.0},
                                     {a1, b1, b1, w1},
                                     {b1, a1, b1, w1},
                                     {b1, b1, a1, w1},
                                     {a2, b2, b2, w2},
                                     {b2, a2, b2, w2},
                                     {b2, b2, a2, w2}}};
  }();
  return r;
}

const std::array<QuadPoint, 1>& centroidRule() {
  static const std::array<QuadPoint, 1> r{{{1.0 / 3.0, 1.0 / 3.0, 1.0 / 3.0, 1.0}}};
  return r;
}

// Accumulated integrals over the contact polygon (2D coordinates).
struct Integrals {
  double area = 0;                         // ∫ dS
  Vec2 y = Vec2::Zero();                   // ∫ y dS
  double g = 0;                            // ∫ g dS
  double g2 = 0;                           // ∫ g² dS
  Vec2 gy = Vec2::Zero();                  // ∫ g y dS
  std::array<double, 3> ga{0, 0, 0};       // ∫ g λ^A_i dS
  std::array<double, 3> gb{0, 0, 0};       // ∫ g λ^B_i dS
  std::array<double, 9> ab{}, aa{}, bb{};  // ∫ λ^A_i λ^B_k, λ^A_i λ^A_j, λ^B_k λ^B_l dS
};

template <class Rule>
void integrate(const Polygon& poly, const Rule& rule, double g0, const Vec2& grad_g,
               const Barycentric& lam_a, const Barycentric& lam_b, bool moments, Integrals& I) {
  const Vec2& v0 = poly.v[0];
  for (int t = 1; t + 1 < poly.n; ++t) {
    const Vec2& v1 = poly.v[t];
    const Vec2& v2 = poly.v[t + 1];
    const double tri_area = 0.5 * cross2(v1 - v0, v2 - v0);
    for (const QuadPoint& q : rule) {
      const Vec2 y = q.b0 * v0 + q.b1 * v1 + q.b2 * v2;
      const double w = q.w * tri_area;
      const double g = g0 + grad_g.dot(y);
      const std::array<double, 3> la = lam_a(y);
      const std::array<double, 3> lb = lam_b(y);
      I.area += w;
      I.y += w * y;
      I.g += w * g;
      I.g2 += w * g * g;
      I.gy += (w * g) * y;
      for (int i = 0; i < 3; ++i) {
        I.ga[i] += w * g * la[i];
        I.gb[i] += w * g * lb[i];
        for (int k = 0; k < 3 && moments; ++k) {
          I.ab[3 * i + k] += w * la[i] * lb[k];
          I.aa[3 * i + k] += w * la[i] * la[k];
          I.bb[3 * i + k] += w * lb[i] * lb[k];
        }
      }
    }
  }
}

// The Exact rule in closed form: every integrand of Integrals is a product of at most two affine
// functions of y, so the polygon's area, first moments and second moments (fan triangles from
// v0, in z = y − v0) give them all. This is the edge-midpoint rule's value up to roundoff at
// about a third of its cost (it evaluated both barycentric maps at 3 points per fan triangle).
void integrateExact(const Polygon& poly, double g0, const Vec2& grad_g, const Barycentric& lam_a,
                    const Barycentric& lam_b, bool moments, Integrals& I) {
  const Vec2& v0 = poly.v[0];
  // ∫ 1, ∫ z, ∫ z zᵀ over the polygon: a triangle (0, p, q) of area a has ∫ z = a (p + q) / 3
  // and ∫ z zᵀ = a / 12 (p pᵀ + q qᵀ + (p + q)(p + q)ᵀ).
  double area = 0, mx = 0, my = 0, sxx = 0, sxy = 0, syy = 0;
  for (int t = 1; t + 1 < poly.n; ++t) {
    const Vec2 p = poly.v[t] - v0, q = poly.v[t + 1] - v0;
    const double a = 0.5 * cross2(p, q);
    const double sx = p.x() + q.x(), sy = p.y() + q.y();
    area += a;
    mx += a * sx;
    my += a * sy;
    sxx += a * (p.x() * p.x() + q.x() * q.x() + sx * sx);
    sxy += a * (p.x() * p.y() + q.x() * q.y() + sx * sy);
    syy += a * (p.y() * p.y() + q.y() * q.y() + sy * sy);
  }
  mx /= 3, my /= 3, sxx /= 12, sxy /= 12, syy /= 12;
  // An affine function as its value at v0 and its gradient.
  struct Affine {
    double c, gx, gy;
  };
  // ∫ f and ∫ f h.
  auto int1 = [&](const Affine& f) { return f.c * area + f.gx * mx + f.gy * my; };
  auto int2 = [&](const Affine& f, const Affine& h) {
    return f.c * h.c * area + (f.c * h.gx + h.c * f.gx) * mx + (f.c * h.gy + h.c * f.gy) * my +
           f.gx * h.gx * sxx + (f.gx * h.gy + f.gy * h.gx) * sxy + f.gy * h.gy * syy;
  };
  const Affine g{g0 + grad_g.dot(v0), grad_g.x(), grad_g.y()};
  // λ_0 = cross2(p1 − y, p2 − y) / 2S has gradient (p1.y − p2.y, p2.x − p1.x) / 2S; λ_1 likewise;
  // λ_2 = 1 − λ_0 − λ_1.
  auto lambdas = [&](const Barycentric& lam) {
    const std::array<double, 3> at = lam(v0);
    const std::array<Vec2, 3>& p = lam.p;
    const double s = lam.inv_twice_area;
    const double g0x = (p[1].y() - p[2].y()) * s, g0y = (p[2].x() - p[1].x()) * s;
    const double g1x = (p[2].y() - p[0].y()) * s, g1y = (p[0].x() - p[2].x()) * s;
    return std::array<Affine, 3>{Affine{at[0], g0x, g0y}, Affine{at[1], g1x, g1y},
                                 Affine{at[2], -g0x - g1x, -g0y - g1y}};
  };
  const std::array<Affine, 3> la = lambdas(lam_a), lb = lambdas(lam_b);
  // Accumulated (+=), so that the pieces of a pair's contact add into one Integrals.
  I.area += area;
  const double ig = int1(g);
  I.y += Vec2(v0.x() * area + mx, v0.y() * area + my);
  I.g += ig;
  I.g2 += int2(g, g);
  // ∫ g y = v0 ∫ g + ∫ g z.
  I.gy += Vec2(v0.x() * ig + int2(g, Affine{0, 1, 0}), v0.y() * ig + int2(g, Affine{0, 0, 1}));
  for (int i = 0; i < 3; ++i) {
    I.ga[i] += int2(g, la[i]);
    I.gb[i] += int2(g, lb[i]);
  }
  if (!moments) return;
  for (int i = 0; i < 3; ++i)
    for (int k = 0; k < 3; ++k) {
      I.ab[3 * i + k] += int2(la[i], lb[k]);
      I.aa[3 * i + k] += int2(la[i], la[k]);
      I.bb[3 * i + k] += int2(lb[i], lb[k]);
    }
}

// Clamp roundoff negatives of barycentric coordinates of an interior point and renormalise.
std::array<double, 3> clampBarycentric(std::array<double, 3> l) {
  double sum = 0;
  for (double& v : l) {
    v = std::max(v, 0.0);
    sum += v;
  }
  if (!(sum > 0)) return {1.0 / 3.0, 1.0 / 3.0, 1.0 / 3.0};
  for (double& v : l) v /= sum;
  return l;
}

double maxEdgeSquared(const std::array<Vec3, 3>& p) {
  return std::max(
      {(p[1] - p[0]).squaredNorm(), (p[2] - p[1]).squaredNorm(), (p[0] - p[2]).squaredNorm()});
}

}  // namespace

TriangleFrame triangleFrame(const std::array<Vec3, 3>& p) {
  TriangleFrame f;
  // Outward normal; degenerate (or non-finite) triangles never make contact.
  const Vec3 raw = (p[1] - p[0]).cross(p[2] - p[0]);
  const double len = raw.norm();
  if (!(len > 2 * kDegenerateRel * maxEdgeSquared(p))) return f;
  f.normal = raw / len;
  f.ok = true;
  return f;
}

TriangleContact computeTriangleContact(const std::array<Vec3, 3>& a, const std::array<Vec3, 3>& b,
                                       const ContactLaw& law, ContactQuadrature quadrature,
                                       ContactMoments* moments) {
  return computeTriangleContact(a, b, triangleFrame(a), triangleFrame(b), law, quadrature, moments);
}

namespace {

// A facing pair seen in the projection plane ⟂ n = n̂_AB: the basis, both triangles' projected
// corners and the gap g(y), affine in y.
struct PairFrame {
  Vec3 n, e1, e2, o;
  std::array<Vec2, 3> pa, pb;
  // The line o + y + s n meets plane A at s_A(y) = sa0 + sa_grad·y, plane B likewise.
  double sa0, sb0;
  Vec2 sa_grad, sb_grad;
  double g0;
  Vec2 g_grad;
  double gap(const Vec2& y) const { return g0 + g_grad.dot(y); }
};

// The frame of a facing pair, or false when the pair cannot touch within h0 (each early out
// rejects only pairs the full clip would leave without a polygon of positive area).
bool framePair(const std::array<Vec3, 3>& a, const std::array<Vec3, 3>& b, const Vec3& na,
               const Vec3& nb, double h0, PairFrame& f) {
  // A corner a_i at distance d_i = n̂_B·(a_i − b_0) in front of B's plane has gap
  // g = d_i / |n̂_B·n̂_AB| ≥ d_i there, so d_i ≥ h0 at all of A's corners implies g ≥ h0 on the
  // polygon; likewise for B's corners and A's plane. The margin of 1e-9 h0 keeps the
  // implication true through roundoff (~1e-14 µm here), so the result is the same bits.
  const double h_safe = h0 * (1 + 1e-9);
  if (nb.dot(a[0] - b[0]) >= h_safe && nb.dot(a[1] - b[0]) >= h_safe &&
      nb.dot(a[2] - b[0]) >= h_safe)
    return false;
  if (na.dot(b[0] - a[0]) >= h_safe && na.dot(b[1] - a[0]) >= h_safe &&
      na.dot(b[2] - a[0]) >= h_safe)
    return false;
  const Vec3 n = (na - nb).normalized();  // |n̂_A − n̂_B| ≥ √2 for facing pairs
  // Disjoint projections (about half of the broad phase's candidates on a packed tissue): an
  // edge of one triangle with the other's three corners strictly outside it separates them.
  // cross2(Pu, Pw) = n·(u × w) for the projection P, so the test runs in 3D without projecting.
  // Projected A runs counter-clockwise (n̂_A·n > 0), projected B clockwise. One branch for all
  // six edges (the outcome is a coin flip for the branch predictor).
  auto separation = [&](const std::array<Vec3, 3>& p, const std::array<Vec3, 3>& q, double sign) {
    double best = -1;
    for (int i = 0; i < 3; ++i) {
      const Vec3 c = sign * n.cross(p[(i + 1) % 3] - p[i]);  // n·(e × w) = (n × e)·w
      best = std::max(best, std::min({c.dot(q[0] - p[i]), c.dot(q[1] - p[i]), c.dot(q[2] - p[i])}));
    }
    return best;
  };
  if (std::max(separation(a, b, -1.0), separation(b, a, 1.0)) > 0) return false;
  int axis = 0;
  if (std::abs(n.y()) < std::abs(n[axis])) axis = 1;
  if (std::abs(n.z()) < std::abs(n[axis])) axis = 2;
  f.n = n;
  f.e1 = Vec3::Unit(axis).cross(n).normalized();
  f.e2 = n.cross(f.e1);
  f.o = (a[0] + a[1] + a[2] + b[0] + b[1] + b[2]) / 6.0;
  auto project = [&](const Vec3& x) {
    const Vec3 r = x - f.o;
    return Vec2(r.dot(f.e1), r.dot(f.e2));
  };
  f.pa = {project(a[0]), project(a[1]), project(a[2])};
  f.pb = {project(b[0]), project(b[1]), project(b[2])};
  // n̂_A·n ≥ 1/√2 and n̂_B·n ≤ −1/√2: the divisions are well conditioned.
  const double dna = na.dot(n), dnb = nb.dot(n);
  const Vec3 ca = (a[0] + a[1] + a[2]) / 3.0 - f.o, cb = (b[0] + b[1] + b[2]) / 3.0 - f.o;
  f.sa0 = na.dot(ca) / dna;
  f.sb0 = nb.dot(cb) / dnb;
  f.sa_grad = Vec2(-na.dot(f.e1) / dna, -na.dot(f.e2) / dna);
  f.sb_grad = Vec2(-nb.dot(f.e1) / dnb, -nb.dot(f.e2) / dnb);
  f.g0 = f.sb0 - f.sa0;
  f.g_grad = f.sb_grad - f.sa_grad;
  // g is affine and the polygon lies inside projected A (and B): g ≥ h0 at its corners means
  // g ≥ h0 on the whole polygon.
  if (f.gap(f.pa[0]) >= h0 && f.gap(f.pa[1]) >= h0 && f.gap(f.pa[2]) >= h0) return false;
  if (f.gap(f.pb[0]) >= h0 && f.gap(f.pb[1]) >= h0 && f.gap(f.pb[2]) >= h0) return false;
  return true;
}

// The supplement's polygon: projected A clipped by projected B and by the law's range g < h0.
// The clips ping-pong between buf[0] and buf[1]; returns the index of the result.
int overlapPolygon(const PairFrame& f, double h0, Polygon (&buf)[2]) {
  buf[0].n = 3;
  for (int i = 0; i < 3; ++i) buf[0].v[i] = f.pa[i];
  const std::array<Vec2, 3> qb{f.pb[0], f.pb[2], f.pb[1]};  // B reversed: counter-clockwise
  int cur = 0;
  for (int k = 0; k < 3 && buf[cur].n > 0; ++k, cur ^= 1) {
    const Vec2 q0 = qb[k], edge = qb[k == 2 ? 0 : k + 1] - qb[k];
    clipHalfPlane(buf[cur], buf[cur ^ 1], [&](const Vec2& y) { return cross2(edge, y - q0); });
  }
  clipHalfPlane(buf[cur], buf[cur ^ 1], [&](const Vec2& y) { return h0 - f.gap(y); });
  return cur ^ 1;
}

// The law "prisms": keep the points y where B's point p_B(y) = o + y + s_B(y) n lies over A —
// inside A's prism along n̂_A: m·(p_B(y) − a_i) ≥ 0 for the inward edge normals
// m = n̂_A × (a_{i+1} − a_i) (the component of p_B along n̂_A drops out) — and A's point over B.
// Each condition is affine in y. Where n̂_B = −n̂_A the lines are the projected edges: a pair of
// parallel triangles keeps its polygon.
int clipToPrisms(const PairFrame& f, const std::array<Vec3, 3>& a, const std::array<Vec3, 3>& b,
                 const Vec3& na, const Vec3& nb, Polygon (&buf)[2], int cur) {
  auto overlie = [&](const std::array<Vec3, 3>& t, const Vec3& nt, double s0, const Vec2& s_grad) {
    for (int i = 0; i < 3 && buf[cur].n > 0; ++i, cur ^= 1) {
      const Vec3 m = nt.cross(t[i == 2 ? 0 : i + 1] - t[i]);
      const double mn = m.dot(f.n);
      const double c0 = m.dot(f.o - t[i]) + s0 * mn;
      const Vec2 c(m.dot(f.e1) + s_grad.x() * mn, m.dot(f.e2) + s_grad.y() * mn);
      clipHalfPlane(buf[cur], buf[cur ^ 1], [&](const Vec2& y) { return c0 + c.dot(y); });
    }
  };
  overlie(a, na, f.sb0, f.sb_grad);
  overlie(b, nb, f.sa0, f.sa_grad);
  return cur;
}

// The law "prisms-overlap": the polygon's overlapping part (g < 0) within the prisms, its
// adhesive part (g ≥ 0, the junctions' rims) whole, into `adhesive`. A polygon on one side of
// g = 0 is not split: both clips keep the points at g = 0, so a pair at g ≡ 0 (touching
// antiparallel faces) would be counted twice. Returns the index of the overlapping piece.
int clipOverlapToPrisms(const PairFrame& f, const std::array<Vec3, 3>& a,
                        const std::array<Vec3, 3>& b, const Vec3& na, const Vec3& nb,
                        Polygon (&buf)[2], int cur, Polygon& adhesive, bool& split) {
  split = false;
  if (buf[cur].n == 0) return clipToPrisms(f, a, b, na, nb, buf, cur);
  double g_lo = f.gap(buf[cur].v[0]), g_hi = g_lo;
  for (int i = 1; i < buf[cur].n; ++i) {
    const double g = f.gap(buf[cur].v[i]);
    g_lo = std::min(g_lo, g);
    g_hi = std::max(g_hi, g);
  }
  if (g_lo >= 0) return cur;  // adhesive only: the supplement's polygon
  if (g_hi > 0) {
    clipHalfPlane(buf[cur], adhesive, [&](const Vec2& y) { return f.gap(y); });
    clipHalfPlane(buf[cur], buf[cur ^ 1], [&](const Vec2& y) { return -f.gap(y); });
    cur ^= 1;
    split = true;
  }
  return clipToPrisms(f, a, b, na, nb, buf, cur);
}

// Adds the polygon's area into `area` (one running sum over the pieces: the same bits as ever).
void addArea(const Polygon& poly, double& area) {
  for (int t = 1; t + 1 < poly.n; ++t)
    area += 0.5 * cross2(poly.v[t] - poly.v[0], poly.v[t + 1] - poly.v[0]);
}

void integrateOver(const Polygon& p, const PairFrame& f, const Barycentric& lam_a,
                   const Barycentric& lam_b, ContactQuadrature quadrature, bool with_moments,
                   Integrals& into) {
  switch (quadrature) {
    case ContactQuadrature::Exact:
      integrateExact(p, f.g0, f.g_grad, lam_a, lam_b, with_moments, into);
      break;
    case ContactQuadrature::Dunavant7:
      integrate(p, dunavant7Rule(), f.g0, f.g_grad, lam_a, lam_b, with_moments, into);
      break;
    case ContactQuadrature::Centroid:
      integrate(p, centroidRule(), f.g0, f.g_grad, lam_a, lam_b, with_moments, into);
      break;
  }
}

// The pair's contact from the integrals over its polygon pieces (P = k g).
TriangleContact assembleContact(const PairFrame& f, const std::array<const Polygon*, 2>& pieces,
                                double poly_area, Integrals& I, double g_true,
                                const Barycentric& lam_a, const Barycentric& lam_b, double k,
                                ContactMoments* moments, ContactOutputs outputs) {
  TriangleContact out;
  auto toMidSurface = [&](const Vec2& y) {
    const double s_mid = 0.5 * (f.sa0 + f.sa_grad.dot(y) + f.sb0 + f.sb_grad.dot(y));
    return Vec3(f.o + y.x() * f.e1 + y.y() * f.e2 + s_mid * f.n);
  };
  out.active = true;
  out.normal = f.n;
  out.area = poly_area;
  out.force = (k * I.g) * f.n;
  for (int i = 0; i < 3; ++i) {
    out.force_weight_a[i] = k * I.ga[i];
    out.force_weight_b[i] = k * I.gb[i];
  }
  const Vec2 centroid2 = I.y / I.area;
  if (outputs == ContactOutputs::All) {
    out.centroid = toMidSurface(centroid2);
    double g_max = 0;
    for (const Polygon* poly : pieces)
      for (int i = 0; poly && i < poly->n; ++i)
        g_max = std::max(g_max, std::abs(f.gap(poly->v[i])));
    const bool loaded = std::abs(I.g) > kZeroLoadRel * I.area * g_max;
    out.center_of_pressure = loaded ? toMidSurface(I.gy / I.g) : out.centroid;
  }
  out.bary_a = clampBarycentric(lam_a(centroid2));
  out.bary_b = clampBarycentric(lam_b(centroid2));
  // (w λ_i) λ_j and (w λ_j) λ_i round differently: mirror, so that K is exactly symmetric.
  for (int i = 0; i < 3; ++i)
    for (int j = i + 1; j < 3; ++j) {
      I.aa[3 * j + i] = I.aa[3 * i + j];
      I.bb[3 * j + i] = I.bb[3 * i + j];
    }
  if (moments) *moments = {I.ab, I.aa, I.bb};
  out.energy = 0.5 * k * I.g2;
  out.mean_gap = g_true / I.area;
  return out;
}

}  // namespace

TriangleContact computeTriangleContact(const std::array<Vec3, 3>& a, const std::array<Vec3, 3>& b,
                                       const TriangleFrame& fa, const TriangleFrame& fb,
                                       const ContactLaw& law, ContactQuadrature quadrature,
                                       ContactMoments* moments, ContactOutputs outputs) {
  if (moments) *moments = ContactMoments{};
  if (!fa.ok || !fb.ok) return {};
  const Vec3& na = fa.normal;
  const Vec3& nb = fb.normal;
  if (!(na.dot(nb) < 0)) return {};  // not facing
  PairFrame f;
  if (!framePair(a, b, na, nb, law.h0, f)) return {};
  // The law's polygon: one piece, or two under prisms-overlap (the adhesive part apart).
  Polygon buf[2], adhesive;
  int cur = overlapPolygon(f, law.h0, buf);
  bool split = false;
  if (law.kind == ContactLawKind::Prisms) cur = clipToPrisms(f, a, b, na, nb, buf, cur);
  if (law.kind == ContactLawKind::PrismsOverlap)
    cur = clipOverlapToPrisms(f, a, b, na, nb, buf, cur, adhesive, split);
  const std::array<const Polygon*, 2> pieces{&buf[cur], split ? &adhesive : nullptr};
  double poly_area = 0;
  addArea(buf[cur], poly_area);
  if (split) addArea(adhesive, poly_area);
  const double ref_area = std::max(std::abs(cross2(f.pa[1] - f.pa[0], f.pa[2] - f.pa[0])),
                                   std::abs(cross2(f.pb[1] - f.pb[0], f.pb[2] - f.pb[0])));
  if (!(poly_area > kEmptyPolygonRel * ref_area)) return {};

  const Barycentric lam_a(f.pa), lam_b(f.pb);
  Integrals I;
  double g_true = 0;  // ∫ g: each piece adds into I (a single piece's sums are its own)
  for (const Polygon* piece : pieces) {
    if (!piece || piece->n < 3) continue;
    const double g_before = I.g;
    integrateOver(*piece, f, lam_a, lam_b, quadrature, moments != nullptr, I);
    g_true += I.g - g_before;
  }
  return assembleContact(f, pieces, poly_area, I, g_true, lam_a, lam_b, law.k, moments, outputs);
}

}  // namespace activefoam
