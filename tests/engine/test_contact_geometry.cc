// Tests of the triangle–triangle contact geometry (docs/model.md §3): broad phase against its
// brute-force oracle, and the narrow phase against the physics it must satisfy (action–reaction,
// energy consistency, moment balance, hand-computed special cases, an independent grid
// integration).
#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <random>
#include <tuple>

#include <gtest/gtest.h>
#ifdef _OPENMP
#include <omp.h>
#endif
#include <Eigen/Geometry>

#include "activefoam/contact_geometry.h"
#include "activefoam/contacts.h"
#include "activefoam/spec.h"

namespace activefoam {
namespace {

using Tri3 = std::array<Vec3, 3>;
using Vec2 = Eigen::Vector2d;

constexpr ContactQuadrature kAllQuadratures[] = {
    ContactQuadrature::Exact, ContactQuadrature::Dunavant7, ContactQuadrature::Centroid};

// ---- helpers ---------------------------------------------------------------------------------

Vec3 triNormal(const Tri3& t) {
  return (t[1] - t[0]).cross(t[2] - t[0]).normalized();
}
double triArea(const Tri3& t) {
  return 0.5 * (t[1] - t[0]).cross(t[2] - t[0]).norm();
}

Eigen::Matrix3d randomRotation(std::mt19937& rng) {
  std::normal_distribution<double> n01;
  Eigen::Quaterniond q(n01(rng), n01(rng), n01(rng), n01(rng));
  return q.normalized().toRotationMatrix();
}

Eigen::Matrix3d rotationAbout(const Vec3& axis, double angle) {
  return Eigen::AngleAxisd(angle, axis.normalized()).toRotationMatrix();
}

Tri3 transformed(const Tri3& t, const Eigen::Matrix3d& R, const Vec3& shift) {
  return {R * t[0] + shift, R * t[1] + shift, R * t[2] + shift};
}

// Random triangle in the plane z = 0, roughly of size `size`, not too thin; counter-clockwise
// seen from +z when `ccw`, clockwise otherwise.
Tri3 randomFlatTriangle(std::mt19937& rng, double size, bool ccw) {
  std::uniform_real_distribution<double> u(-size, size);
  for (;;) {
    Tri3 t{Vec3(u(rng), u(rng), 0), Vec3(u(rng), u(rng), 0), Vec3(u(rng), u(rng), 0)};
    const double z = (t[1] - t[0]).cross(t[2] - t[0]).z();
    if (std::abs(z) < 0.2 * size * size) continue;
    if ((z > 0) != ccw) std::swap(t[1], t[2]);
    return t;
  }
}

struct Pair {
  Tri3 a, b;
};

// A facing pair: A in z = 0 with outward normal +z, B around z = gap with outward normal −z,
// tilted by up to `tilt` rad about a random in-plane axis through (0, 0, gap), then the whole
// pair moved by a random rigid motion.
Pair randomFacingPair(std::mt19937& rng, double gap_lo, double gap_hi, double tilt) {
  std::uniform_real_distribution<double> ug(gap_lo, gap_hi), ut(-tilt, tilt), uphi(0, 2 * M_PI),
      ushift(-5, 5);
  const double gap = ug(rng);
  Tri3 a = randomFlatTriangle(rng, 1.0, true);
  Tri3 b = randomFlatTriangle(rng, 1.0, false);
  const double phi = uphi(rng);
  const Eigen::Matrix3d Rt = rotationAbout(Vec3(std::cos(phi), std::sin(phi), 0), ut(rng));
  const Vec3 pivot(0, 0, gap);
  for (Vec3& p : b) p = pivot + Rt * p;
  const Eigen::Matrix3d R = randomRotation(rng);
  const Vec3 shift(ushift(rng), ushift(rng), ushift(rng));
  return {transformed(a, R, shift), transformed(b, R, shift)};
}

// Nodal forces of a contact: A's three nodes then B's three nodes.
std::array<Vec3, 6> nodalForces(const TriangleContact& c) {
  std::array<Vec3, 6> f;
  for (int i = 0; i < 3; ++i) {
    f[i] = c.force_weight_a[i] * c.normal;
    f[3 + i] = -c.force_weight_b[i] * c.normal;
  }
  return f;
}

bool allFinite(const TriangleContact& c) {
  bool ok = c.normal.allFinite() && c.force.allFinite() && c.center_of_pressure.allFinite() &&
            c.centroid.allFinite() && std::isfinite(c.area) && std::isfinite(c.energy) &&
            std::isfinite(c.mean_gap);
  for (int i = 0; i < 3; ++i)
    ok = ok && std::isfinite(c.force_weight_a[i]) && std::isfinite(c.force_weight_b[i]) &&
         std::isfinite(c.bary_a[i]) && std::isfinite(c.bary_b[i]);
  return ok;
}

void expectInactiveAndZero(const TriangleContact& c) {
  EXPECT_FALSE(c.active);
  EXPECT_TRUE(allFinite(c));
  EXPECT_EQ(c.area, 0.0);
  EXPECT_EQ(c.force.norm(), 0.0);
  EXPECT_EQ(c.energy, 0.0);
  for (int i = 0; i < 3; ++i) {
    EXPECT_EQ(c.force_weight_a[i], 0.0);
    EXPECT_EQ(c.force_weight_b[i], 0.0);
  }
}

// Independent reference: integrate over a fine grid of the projection plane, testing each
// sample point for membership in both projected triangles and g < h0, with the gap measured
// along n̂_AB between the 3D planes.
struct GridReference {
  double area = 0, int_p = 0, energy = 0;
  std::array<double, 3> wa{0, 0, 0}, wb{0, 0, 0};
  Vec3 centroid = Vec3::Zero();
  double g_min = std::numeric_limits<double>::infinity();   // the smallest gap sampled
  double g_max = -std::numeric_limits<double>::infinity();  // the largest
  std::array<double, 9> ab{};                               // ∫ λ^A_i λ^B_k dS
};

std::array<double, 3> bary2(const std::array<Vec2, 3>& p, const Vec2& y) {
  auto cr = [](const Vec2& u, const Vec2& v) { return u.x() * v.y() - u.y() * v.x(); };
  const double d = cr(p[1] - p[0], p[2] - p[0]);
  const double l0 = cr(p[1] - y, p[2] - y) / d, l1 = cr(p[2] - y, p[0] - y) / d;
  return {l0, l1, 1 - l0 - l1};
}

// Whether p lies over triangle t: its projection along t's normal falls inside t.
bool over(const Tri3& t, const Vec3& p) {
  const Vec3 n = triNormal(t);
  for (int i = 0; i < 3; ++i)
    if (n.dot((t[(i + 1) % 3] - t[i]).cross(p - t[i])) < 0) return false;
  return true;
}

GridReference gridIntegrate(const Tri3& a, const Tri3& b, const ContactLaw& law, int n_grid) {
  const Vec3 na = triNormal(a), nb = triNormal(b);
  const Vec3 n = (na - nb).normalized();
  const Vec3 e1 = n.unitOrthogonal(), e2 = n.cross(e1);
  const Vec3 o = a[0];
  std::array<Vec2, 3> pa, pb;
  for (int i = 0; i < 3; ++i) {
    pa[i] = Vec2((a[i] - o).dot(e1), (a[i] - o).dot(e2));
    pb[i] = Vec2((b[i] - o).dot(e1), (b[i] - o).dot(e2));
  }
  // The grid spans the overlap of both triangles' bounding boxes: a sliver of overlap gets the
  // whole resolution (over A's box alone a 0.001 µm² polygon was 3.5 % off in area).
  const Vec2 lo =
      pa[0].cwiseMin(pa[1]).cwiseMin(pa[2]).cwiseMax(pb[0].cwiseMin(pb[1]).cwiseMin(pb[2]));
  const Vec2 hi =
      pa[0].cwiseMax(pa[1]).cwiseMax(pa[2]).cwiseMin(pb[0].cwiseMax(pb[1]).cwiseMax(pb[2]));
  GridReference r;
  if (!(lo.array() < hi.array()).all()) return r;
  const Vec2 h = (hi - lo) / n_grid;
  const double dA = h.x() * h.y();
  for (int i = 0; i < n_grid; ++i) {
    for (int j = 0; j < n_grid; ++j) {
      const Vec2 y = lo + Vec2((i + 0.5) * h.x(), (j + 0.5) * h.y());
      const auto la = bary2(pa, y), lb = bary2(pb, y);
      if (*std::min_element(la.begin(), la.end()) < 0) continue;
      if (*std::min_element(lb.begin(), lb.end()) < 0) continue;
      const Vec3 X = o + y.x() * e1 + y.y() * e2;
      const double sA = na.dot(a[0] - X) / na.dot(n), sB = nb.dot(b[0] - X) / nb.dot(n);
      const double g = sB - sA;
      if (!(g < law.h0)) continue;
      // The prisms laws: B's point over A and A's point over B (prisms-overlap: only where they
      // overlap, g < 0).
      if ((law.kind == ContactLawKind::Prisms ||
           (law.kind == ContactLawKind::PrismsOverlap && g < 0)) &&
          !(over(a, X + sB * n) && over(b, X + sA * n)))
        continue;
      r.g_min = std::min(r.g_min, g);
      r.g_max = std::max(r.g_max, g);
      const double P = law.k * g;
      r.area += dA;
      r.int_p += P * dA;
      r.energy += 0.5 * law.k * g * g * dA;
      for (int k = 0; k < 3; ++k) {
        r.wa[k] += P * la[k] * dA;
        r.wb[k] += P * lb[k] * dA;
        for (int l = 0; l < 3; ++l) r.ab[3 * k + l] += la[k] * lb[l] * dA;
      }
      r.centroid += (X + 0.5 * (sA + sB) * n) * dA;
    }
  }
  if (r.area > 0) r.centroid /= r.area;
  return r;
}

// A contact against its grid reference: area, ∫P, energy and nodal weights (the tolerances of
// a 500 × 500 grid on pairs of ≥ 0.02 µm²).
void expectMatchesGrid(const TriangleContact& c, const GridReference& r, double k, int trial) {
  const double scale = k * c.area * 0.4;
  EXPECT_NEAR(c.area, r.area, 2e-2 * c.area) << trial;
  EXPECT_NEAR(c.force.dot(c.normal), r.int_p, 1e-2 * scale) << trial;
  EXPECT_NEAR(c.energy, r.energy, 1e-2 * scale * 0.4) << trial;
  for (int i = 0; i < 3; ++i) {
    EXPECT_NEAR(c.force_weight_a[i], r.wa[i], 1e-2 * scale) << trial;
    EXPECT_NEAR(c.force_weight_b[i], r.wb[i], 1e-2 * scale) << trial;
  }
}

// The pair that started the runaway of step fitness's seed 8 at Δt 0.5 s (cells 20 and 27 at
// t = 4 099.5 s; docs/science/motion-convergence.md): two triangles 0.19 µm apart at
// n̂_A·n̂_B = −0.13 whose planes cross beside them.
std::pair<Tri3, Tri3> seed8ObliquePair() {
  return {Tri3{Vec3(-0.71473498413431003, -0.90190029979868758, 1.2308333131784792),
               Vec3(1.117319105989651, -0.22447818566602784, -1.1349120439527667),
               Vec3(-0.3532954872741243, 1.1220257897960906, -0.10711276345514165)},
          Tri3{Vec3(-0.83649036103684438, -0.78063818627418424, 1.0147309210419841),
               Vec3(-3.8407429793389305, 1.1726991761196892, 0.070249998023594884),
               Vec3(-5.351770333574084, -0.7304665235113772, -2.7170223808851084)}};
}

// Exactly antiparallel pairs (a constant gap) under a bound on the law: the prisms' sides are
// the projected edges and the polygon is on one side of g = 0, so every output is the plain
// law's to roundoff, for every quadrature (the centroid rule's moments depend on the polygon's
// fan, not exact for λλ, and are left out). Returns the pairs compared.
int antiparallelPairsAreTheLaws(std::mt19937& rng, const ContactLaw& bounded) {
  const ContactLaw plain;
  int compared = 0;
  for (int trial = 0; trial < 200; ++trial) {
    const Pair pr = randomFacingPair(rng, -0.3, 0.05, 0.0);
    for (ContactQuadrature q : kAllQuadratures) {
      ContactMoments mp, mc;
      const TriangleContact p = computeTriangleContact(pr.a, pr.b, plain, q, &mp);
      const TriangleContact c = computeTriangleContact(pr.a, pr.b, bounded, q, &mc);
      EXPECT_EQ(c.active, p.active) << trial;
      if (!p.active || !c.active || p.area < 1e-6) continue;
      ++compared;
      const double fs = plain.k * p.area * 0.3 + 1e-12;
      EXPECT_NEAR(c.area, p.area, 1e-9 * p.area) << trial;
      EXPECT_NEAR(c.mean_gap, p.mean_gap, 1e-9) << trial;
      EXPECT_NEAR(c.force.dot(p.normal), p.force.dot(p.normal), 1e-9 * fs) << trial;
      EXPECT_NEAR(c.energy, p.energy, 1e-9 * fs) << trial;
      for (int i = 0; i < 3; ++i) {
        EXPECT_NEAR(c.force_weight_a[i], p.force_weight_a[i], 1e-9 * fs) << trial;
        EXPECT_NEAR(c.force_weight_b[i], p.force_weight_b[i], 1e-9 * fs) << trial;
      }
      if (q == ContactQuadrature::Centroid) continue;
      for (int i = 0; i < 9; ++i) {
        EXPECT_NEAR(mc.ab[i], mp.ab[i], 1e-9 * p.area) << trial;
        EXPECT_NEAR(mc.aa[i], mp.aa[i], 1e-9 * p.area) << trial;
        EXPECT_NEAR(mc.bb[i], mp.bb[i], 1e-9 * p.area) << trial;
      }
    }
  }
  return compared;
}

// The engine's icosphere as plain vectors.
struct LocalMesh {
  std::vector<Vec3> x;
  std::vector<Tri> tri;
};

LocalMesh localIcosphere(int levels) {
  const TriMesh m = icosphere(levels);
  LocalMesh out;
  for (int i = 0; i < m.numVertices(); ++i) out.x.push_back(m.x.col(i));
  out.tri = m.tri;
  return out;
}

struct Scene {
  Eigen::Matrix3Xd x;
  std::vector<Tri> tri;
  std::vector<int> tri_cell;
};

void appendCell(Scene& s, const std::vector<Vec3>& verts, const std::vector<Tri>& tris, int cell) {
  const int base = static_cast<int>(s.x.cols());
  s.x.conservativeResize(3, base + static_cast<int>(verts.size()));
  for (size_t i = 0; i < verts.size(); ++i) s.x.col(base + i) = verts[i];
  for (const Tri& f : tris) {
    s.tri.push_back({f[0] + base, f[1] + base, f[2] + base});
    s.tri_cell.push_back(cell);
  }
}

// ---- 1. broad phase -------------------------------------------------------------------------

TEST(ContactBroadPhase, EqualsBruteForceOnRandomIcosphereCells) {
  std::mt19937 rng(11);
  const LocalMesh ico = localIcosphere(2);
  std::uniform_real_distribution<double> u01(0, 1);
  for (int config = 0; config < 8; ++config) {
    Scene s;
    s.x.resize(3, 0);
    const int n_cells = 10 + static_cast<int>(20 * u01(rng));
    const double box = 1.2 * std::cbrt(static_cast<double>(n_cells));  // dense enough to overlap
    for (int c = 0; c < n_cells; ++c) {
      const Vec3 center(box * u01(rng), box * u01(rng), box * u01(rng));
      const double r = 0.6 + 0.5 * u01(rng);
      std::vector<Vec3> v;
      for (const Vec3& p : ico.x) v.push_back(center + r * (1 + 0.05 * (u01(rng) - 0.5)) * p);
      // Non-contiguous cell ids exercise the id compression.
      appendCell(s, v, ico.tri, 3 * c + (config % 2));
    }
    const double margin = config == 0 ? 0.0 : 0.01 + 0.1 * u01(rng);
    const auto fast = findContactCandidates(s.x, s.tri, s.tri_cell, margin);
    const auto brute = findContactCandidatesBruteForce(s.x, s.tri, s.tri_cell, margin);
    EXPECT_GT(brute.size(), 0u) << "configuration " << config << " has no contacts";
    EXPECT_EQ(fast, brute) << "configuration " << config;
    // In the documented order: by the pair of cells, then by the triangles.
    auto key = [&](const std::pair<int, int>& pq) {
      const int c = s.tri_cell[pq.first], e = s.tri_cell[pq.second];
      return std::tuple(std::min(c, e), std::max(c, e), pq.first, pq.second);
    };
    EXPECT_TRUE(std::is_sorted(fast.begin(), fast.end(),
                               [&](const auto& p, const auto& q) { return key(p) < key(q); }));
    for (const auto& [p, q] : fast) {
      ASSERT_LT(p, q);
      EXPECT_NE(s.tri_cell[p], s.tri_cell[q]);
    }
  }
}

TEST(ContactBroadPhase, EqualsBruteForceOnRandomTriangleSoups) {
  std::mt19937 rng(12);
  std::uniform_real_distribution<double> u01(0, 1);
  for (int config = 0; config < 10; ++config) {
    Scene s;
    s.x.resize(3, 0);
    const int n_cells = 10 + static_cast<int>(20 * u01(rng));
    for (int c = 0; c < n_cells; ++c) {
      const Vec3 center = 3.0 * Vec3(u01(rng), u01(rng), u01(rng));
      std::vector<Vec3> v;
      std::vector<Tri> f;
      const int n_tri = 5 + static_cast<int>(30 * u01(rng));
      for (int t = 0; t < n_tri; ++t) {
        // Mostly small triangles, a few large ones, a few degenerate.
        const double size = u01(rng) < 0.05 ? 3.0 : 0.3 * u01(rng);
        const Vec3 p = center + Vec3(u01(rng), u01(rng), u01(rng)) - Vec3::Constant(0.5);
        const int base = static_cast<int>(v.size());
        v.push_back(p);
        auto randomDir = [&] { return Vec3(2 * u01(rng) - 1, 2 * u01(rng) - 1, 2 * u01(rng) - 1); };
        v.push_back(p + size * randomDir());
        v.push_back(u01(rng) < 0.05 ? v.back() : Vec3(p + size * randomDir()));
        f.push_back({base, base + 1, base + 2});
      }
      // Large, sparse ids in half the configurations (the id-compression fallback).
      appendCell(s, v, f, config % 2 ? c : 50'000'000 * c + 7);
    }
    const double margin = 0.05 * u01(rng);
    const auto fast = findContactCandidates(s.x, s.tri, s.tri_cell, margin);
    const auto brute = findContactCandidatesBruteForce(s.x, s.tri, s.tri_cell, margin);
    EXPECT_GT(brute.size(), 0u);
    EXPECT_EQ(fast, brute) << "configuration " << config;
  }
}

#ifdef _OPENMP
TEST(ContactBroadPhase, ResultIndependentOfThreadCount) {
  const LocalMesh ico = localIcosphere(2);
  Scene s;
  s.x.resize(3, 0);
  for (int c = 0; c < 27; ++c) {  // 3×3×3 block of overlapping spheres
    const Vec3 center = 1.9 * Vec3(c % 3, (c / 3) % 3, c / 9);
    std::vector<Vec3> v;
    for (const Vec3& p : ico.x) v.push_back(center + p);
    appendCell(s, v, ico.tri, c);
  }
  const int saved = omp_get_max_threads();
  omp_set_num_threads(1);
  const auto one = findContactCandidates(s.x, s.tri, s.tri_cell, 0.06);
  omp_set_num_threads(4);
  const auto four = findContactCandidates(s.x, s.tri, s.tri_cell, 0.06);
  omp_set_num_threads(saved);
  EXPECT_GT(one.size(), 0u);
  EXPECT_EQ(one, four);
  EXPECT_EQ(one, findContactCandidatesBruteForce(s.x, s.tri, s.tri_cell, 0.06));
}
#endif

// ---- 1b. the broad phase's Verlet lists (CandidateCache) --------------------------------------

// 27 unit icosphere cells on a 3×3×3 block, neighbours overlapping.
CellSet blockOfCells(double spacing) {
  CellSet cells;
  for (int c = 0; c < 27; ++c) {
    TriMesh m = icosphere(2);
    m.x.colwise() += spacing * Vec3(c % 3, (c / 3) % 3, c / 9);
    cells.addCell(m, 1.0);
  }
  return cells;
}

std::vector<std::pair<int, int>> fresh(const CellSet& cells, double margin) {
  return findContactCandidates(cells.x, cells.tri, cells.tri_cell, margin);
}

TEST(CandidateCache, EqualsTheFreshBroadPhaseWhileCellsJitterDriftAndAreRemeshed) {
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> u(-1, 1);
  CellSet cells = blockOfCells(1.95);
  const double margin = 0.06;
  for (double skin : {0.0, 0.05, 0.2, 0.5}) {
    CandidateCache cache(skin);
    CellSet c = cells;
    for (int step = 0; step < 80; ++step) {
      // Every vertex jitters; cell 13 (the centre) drifts through its neighbours; every 10th
      // step some cell gets a different triangulation (more triangles), as a remesh would.
      for (int i = 0; i < c.numVertices(); ++i) c.x.col(i) += 0.01 * Vec3(u(rng), u(rng), u(rng));
      for (int i = c.cell_vertex_begin[13]; i < c.cell_vertex_begin[14]; ++i)
        c.x.col(i) += Vec3(0.013, 0.004, -0.007);
      if (step % 10 == 9) {
        std::vector<TriMesh> meshes;
        for (int k = 0; k < c.numCells(); ++k) meshes.push_back(c.cellMesh(k));
        const int k = (step * 7) % 27;
        const Vec3 centre = meshes[k].x.rowwise().mean();
        TriMesh finer = icosphere(3);
        finer.x.colwise() += centre;
        finer.v = Eigen::Matrix3Xd::Zero(3, finer.numVertices());
        meshes[k] = finer;
        c.setCellMeshes(meshes);
      }
      ASSERT_EQ(cache.find(c, margin), fresh(c, margin)) << "skin " << skin << ", step " << step;
    }
    EXPECT_GT(cache.stats().cell_pairs_built, 0);
    if (skin >= 0.2) {
      EXPECT_GT(cache.stats().cell_pairs_reused, cache.stats().cell_pairs_built);
    }
  }
}

TEST(CandidateCache, FindsPairsThatAppearWithoutARebuild) {
  // Two columns of cells pressed towards each other by just under skin/2 each: no cell is
  // rebuilt, yet the fresh broad phase finds new pairs — the stored lists must hold them.
  const double skin = 0.2, margin = 0.06;
  CellSet cells = blockOfCells(2.05);  // neighbours 0.05 apart: within reach of the margin
  CandidateCache cache(skin);
  const auto before = cache.find(cells, margin);
  ASSERT_EQ(before, fresh(cells, margin));
  const auto s0 = cache.stats();
  for (int c = 0; c < cells.numCells(); ++c) {
    const double dx = c % 3 == 0 ? 0.0999 : c % 3 == 1 ? -0.0999 : 0.0;
    for (int i = cells.cell_vertex_begin[c]; i < cells.cell_vertex_begin[c + 1]; ++i)
      cells.x(0, i) += dx;
  }
  const auto after = cache.find(cells, margin);
  EXPECT_EQ(after, fresh(cells, margin));
  EXPECT_GT(after.size(), before.size());
  EXPECT_EQ(cache.stats().cells_rebuilt, s0.cells_rebuilt);
  EXPECT_EQ(cache.stats().cell_pairs_built, s0.cell_pairs_built);
  // Unchanged input: nothing is swept again.
  EXPECT_EQ(cache.find(cells, margin), after);
  EXPECT_EQ(cache.stats().cell_pairs_built, s0.cell_pairs_built);
  // One cell moved past skin/2: only it is rebuilt, with its pairs.
  for (int i = cells.cell_vertex_begin[4]; i < cells.cell_vertex_begin[5]; ++i)
    cells.x(1, i) += 0.11;
  EXPECT_EQ(cache.find(cells, margin), fresh(cells, margin));
  EXPECT_EQ(cache.stats().cells_rebuilt, s0.cells_rebuilt + 1);
  EXPECT_GT(cache.stats().cell_pairs_built, s0.cell_pairs_built);
  // A different margin starts over.
  EXPECT_EQ(cache.find(cells, 0.3), fresh(cells, 0.3));
  EXPECT_EQ(cache.stats().cells_rebuilt, s0.cells_rebuilt + 1 + 27);
}

TEST(CandidateCache, NanPositionsCountAsMoved) {
  CellSet cells = blockOfCells(1.95);
  CandidateCache cache(0.2);
  cache.find(cells, 0.06);
  const auto s0 = cache.stats();
  cells.x(0, cells.cell_vertex_begin[3]) = NAN;
  cache.find(cells, 0.06);
  EXPECT_EQ(cache.stats().cells_rebuilt, s0.cells_rebuilt + 1);
}

TEST(ContactBroadPhase, TwoCellsInContactAndTrivialInputs) {
  // Two unit spheres overlapping by 0.1: facing pairs exist only near the contact.
  const LocalMesh ico = localIcosphere(2);
  Scene s;
  s.x.resize(3, 0);
  std::vector<Vec3> v0, v1;
  for (const Vec3& p : ico.x) {
    v0.push_back(p);
    v1.push_back(p + Vec3(1.9, 0, 0));
  }
  appendCell(s, v0, ico.tri, 0);
  appendCell(s, v1, ico.tri, 1);
  const auto fast = findContactCandidates(s.x, s.tri, s.tri_cell, 0.06);
  EXPECT_EQ(fast, findContactCandidatesBruteForce(s.x, s.tri, s.tri_cell, 0.06));
  ASSERT_GT(fast.size(), 0u);
  for (const auto& [p, q] : fast) {
    // Every candidate lies in the slab around the contact plane x = 0.95.
    for (int t : {p, q})
      for (int k = 0; k < 3; ++k) EXPECT_NEAR(s.x(0, s.tri[t][k]), 0.95, 0.5);
  }
  // One cell only, or no triangles: nothing.
  Scene one;
  one.x.resize(3, 0);
  appendCell(one, v0, ico.tri, 7);
  EXPECT_TRUE(findContactCandidates(one.x, one.tri, one.tri_cell, 0.1).empty());
  EXPECT_TRUE(findContactCandidates(one.x, {}, {}, 0.1).empty());
}

// ---- 2. Newton's third law -------------------------------------------------------------------

TEST(ContactNarrowPhase, ActionReactionForceAndTorqueVanish) {
  std::mt19937 rng(21);
  const ContactLaw law;
  int active = 0;
  for (int trial = 0; trial < 400; ++trial) {
    const Pair pr = randomFacingPair(rng, -0.1, 0.1, 0.3);
    for (ContactQuadrature q : kAllQuadratures) {
      const TriangleContact c = computeTriangleContact(pr.a, pr.b, law, q);
      ASSERT_TRUE(allFinite(c));
      if (!c.active) continue;
      ++active;
      const auto f = nodalForces(c);
      Vec3 fsum = Vec3::Zero(), torque = Vec3::Zero();
      double fabs_sum = 0, rmax = 0;
      for (int i = 0; i < 3; ++i) {
        fsum += f[i] + f[3 + i];
        torque += pr.a[i].cross(f[i]) + pr.b[i].cross(f[3 + i]);
        fabs_sum += f[i].norm() + f[3 + i].norm();
        rmax = std::max({rmax, pr.a[i].norm(), pr.b[i].norm()});
      }
      EXPECT_LE(fsum.norm(), 1e-12 * fabs_sum);
      EXPECT_LE(torque.norm(), 1e-10 * fabs_sum * rmax);
      // A's share reproduces the total force.
      EXPECT_LE((f[0] + f[1] + f[2] - c.force).norm(), 1e-12 * fabs_sum);
    }
  }
  EXPECT_GT(active, 300);
}

// ---- 3. energy consistency -------------------------------------------------------------------

TEST(ContactNarrowPhase, ForceIsMinusEnergyGradientAlongNormal) {
  std::mt19937 rng(31);
  int checked = 0;
  for (int trial = 0; trial < 300; ++trial) {
    // Half the pairs with the default range and small tilt/gaps (whole polygon below h0),
    // half with a range far beyond any gap (large tilts, strongly interpenetrating parts).
    const bool default_range = trial % 2 == 0;
    ContactLaw law;
    if (!default_range) law.h0 = 1e3;
    const Pair pr = default_range ? randomFacingPair(rng, -0.04, 0.0, 0.01)
                                  : randomFacingPair(rng, -0.2, 0.2, 0.5);
    for (ContactQuadrature q : {ContactQuadrature::Exact, ContactQuadrature::Dunavant7}) {
      const TriangleContact c = computeTriangleContact(pr.a, pr.b, law, q);
      if (!c.active) continue;
      // The h0 clip must not be active: same area with an unlimited range.
      const TriangleContact unlimited =
          computeTriangleContact(pr.a, pr.b, ContactLaw{law.k, 1e9}, q);
      if (std::abs(unlimited.area - c.area) > 1e-14 * c.area) continue;
      const double ds = 1e-5;
      auto energyAt = [&](double s) {
        Tri3 moved = pr.a;
        for (Vec3& p : moved) p += s * c.normal;
        const TriangleContact cs = computeTriangleContact(moved, pr.b, law, q);
        EXPECT_NEAR(cs.area, c.area, 1e-10 * c.area);  // the polygon does not change
        return cs.energy;
      };
      const double dEds = (energyAt(ds) - energyAt(-ds)) / (2 * ds);
      const double fn = c.force.dot(c.normal);
      EXPECT_NEAR(-dEds, fn, 1e-6 * (std::abs(fn) + law.k * c.area * 1e-3))
          << "trial " << trial << " mean gap " << c.mean_gap;
      ++checked;
    }
  }
  EXPECT_GT(checked, 300);
}

// ---- 4. force and moment reproduction (S18) --------------------------------------------------

TEST(ContactNarrowPhase, NodalForcesReproduceForceAndMomentAboutCentreOfPressure) {
  std::mt19937 rng(41);
  const ContactLaw law;
  int checked = 0;
  for (int trial = 0; trial < 400; ++trial) {
    const Pair pr = randomFacingPair(rng, -0.1, 0.1, 0.3);
    const TriangleContact c = computeTriangleContact(pr.a, pr.b, law, ContactQuadrature::Exact);
    if (!c.active) continue;
    const auto f = nodalForces(c);
    double fabs_sum = 0, diam = 0;
    for (int i = 0; i < 6; ++i) fabs_sum += f[i].norm();
    for (int i = 0; i < 3; ++i) diam = std::max(diam, (pr.a[i] - c.centroid).norm());
    // Σ F_i = F for A and −F for B; all nodal forces are collinear with n̂_AB.
    EXPECT_LE((f[0] + f[1] + f[2] - c.force).norm(), 1e-12 * fabs_sum);
    EXPECT_LE((f[3] + f[4] + f[5] + c.force).norm(), 1e-12 * fabs_sum);
    for (int i = 0; i < 6; ++i) EXPECT_LE(f[i].cross(c.normal).norm(), 1e-14 * fabs_sum);
    // Moment of the nodal forces about the polygon centroid x_AB (S18) equals the moment of the
    // pressure, (x_p − x_AB) × F; in particular it vanishes about the centre of pressure.
    Vec3 m_centroid = Vec3::Zero(), m_cop = Vec3::Zero();
    for (int i = 0; i < 3; ++i) {
      m_centroid += (pr.a[i] - c.centroid).cross(f[i]);
      m_cop += (pr.a[i] - c.center_of_pressure).cross(f[i]);
    }
    const Vec3 expected = (c.center_of_pressure - c.centroid).cross(c.force);
    const double lever = diam + (c.center_of_pressure - c.centroid).norm();
    EXPECT_LE((m_centroid - expected).norm(), 1e-10 * fabs_sum * lever);
    // Only meaningful where the net load does not nearly cancel.
    if (std::abs(c.force.dot(c.normal)) > 0.1 * fabs_sum / 2) {
      EXPECT_LE(m_cop.norm(), 1e-10 * fabs_sum * lever);
      ++checked;
    }
  }
  EXPECT_GT(checked, 100);
}

TEST(ContactNarrowPhase, MatchesIndependentGridIntegration) {
  std::mt19937 rng(42);
  const ContactLaw law;
  int checked = 0;
  for (int trial = 0; trial < 30; ++trial) {
    const Pair pr = randomFacingPair(rng, -0.05, 0.08, 0.15);
    const TriangleContact c = computeTriangleContact(pr.a, pr.b, law, ContactQuadrature::Exact);
    const GridReference r = gridIntegrate(pr.a, pr.b, law, 800);
    const double area_scale = triArea(pr.a);
    if (!c.active) {
      EXPECT_LT(r.area, 1e-2 * area_scale);
      continue;
    }
    ++checked;
    const double p_scale = law.k * area_scale * 0.1;
    EXPECT_NEAR(c.area, r.area, 5e-3 * area_scale);
    EXPECT_NEAR(c.force.dot(c.normal), r.int_p, 5e-3 * p_scale);
    EXPECT_NEAR(c.energy, r.energy, 5e-3 * p_scale * 0.1);
    for (int i = 0; i < 3; ++i) {
      EXPECT_NEAR(c.force_weight_a[i], r.wa[i], 5e-3 * p_scale);
      EXPECT_NEAR(c.force_weight_b[i], r.wb[i], 5e-3 * p_scale);
    }
    if (c.area > 0.05 * area_scale) {
      EXPECT_LT((c.centroid - r.centroid).norm(), 1e-2);
    }
  }
  EXPECT_GT(checked, 15);
}

// ---- 5. special cases ------------------------------------------------------------------------

TEST(ContactNarrowPhase, ParallelFacingTrianglesHexagonOverlap) {
  // A = {x ≥ 0, y ≥ 0, x + y ≤ 2} in z = 0 (normal +z); B = {x ≤ 1.5, y ≤ 1.5, x + y ≥ 1} in
  // z = g0 (normal −z). Overlap = A minus three corner triangles: 2 − 0.5 − 2·0.125 = 1.25.
  const ContactLaw law;
  const double g0 = 0.03;
  const Tri3 a{Vec3(0, 0, 0), Vec3(2, 0, 0), Vec3(0, 2, 0)};
  const Tri3 b{Vec3(1.5, 1.5, g0), Vec3(1.5, -0.5, g0), Vec3(-0.5, 1.5, g0)};
  ASSERT_LT(triNormal(b).z(), 0);
  std::mt19937 rng(51);
  for (int motion = 0; motion < 5; ++motion) {
    const Eigen::Matrix3d R = motion == 0 ? Eigen::Matrix3d::Identity() : randomRotation(rng);
    const Vec3 shift = motion == 0 ? Vec3::Zero() : Vec3(3, -2, 7);
    for (ContactQuadrature q : kAllQuadratures) {
      const TriangleContact c =
          computeTriangleContact(transformed(a, R, shift), transformed(b, R, shift), law, q);
      ASSERT_TRUE(c.active);
      const Vec3 n = R * Vec3::UnitZ();
      EXPECT_NEAR((c.normal - n).norm(), 0, 1e-14);
      EXPECT_NEAR(c.area, 1.25, 1e-13);
      EXPECT_NEAR((c.force - law.k * g0 * 1.25 * n).norm(), 0, 1e-12);
      EXPECT_NEAR(c.energy, 0.5 * law.k * g0 * g0 * 1.25, 1e-14);
      EXPECT_NEAR(c.mean_gap, g0, 1e-13);
      // Uniform pressure: centre of pressure = centroid, on the mid plane z = g0/2. The hexagon
      // is symmetric about x = y; its centroid from the corner cut-outs:
      // (2·(2/3) − 0.5·(1/3) − 0.125·(5/3 + 1/6)) / 1.25 on both axes.
      const double cxy = (2.0 * (2.0 / 3.0) - 0.5 / 3.0 - 0.125 * (5.0 / 3.0 + 1.0 / 6.0)) / 1.25;
      const Vec3 centroid = R * Vec3(cxy, cxy, g0 / 2) + shift;
      EXPECT_NEAR((c.centroid - centroid).norm(), 0, 1e-12);
      EXPECT_NEAR((c.center_of_pressure - centroid).norm(), 0, 1e-12);
      // Weights: k g0 ∫λ_i = k g0 S λ_i(centroid) = k g0 S · bary (λ affine).
      for (int i = 0; i < 3; ++i) {
        EXPECT_NEAR(c.force_weight_a[i], law.k * g0 * 1.25 * c.bary_a[i], 1e-11);
        EXPECT_NEAR(c.force_weight_b[i], law.k * g0 * 1.25 * c.bary_b[i], 1e-11);
      }
    }
  }
}

TEST(ContactNarrowPhase, ParallelShiftedTrianglesAndSmallTriangleInside) {
  const ContactLaw law;
  // B = A shifted by t along x (and facing down): overlap is a right triangle of legs 2 − t.
  const double t = 0.5, g0 = -0.02;
  const Tri3 a{Vec3(0, 0, 0), Vec3(2, 0, 0), Vec3(0, 2, 0)};
  const Tri3 b{Vec3(t, 0, g0), Vec3(t, 2, g0), Vec3(t + 2, 0, g0)};
  const TriangleContact c = computeTriangleContact(a, b, law, ContactQuadrature::Exact);
  ASSERT_TRUE(c.active);
  EXPECT_NEAR(c.area, 0.5 * (2 - t) * (2 - t), 1e-13);
  EXPECT_NEAR(c.force.z(), law.k * g0 * c.area, 1e-12);  // repulsive: pushes A down
  EXPECT_LT(c.force.z(), 0);

  // A small tilted triangle whose projection lies inside the big one: area = its area
  // projected onto the plane ⟂ n̂_AB.
  const Tri3 big{Vec3(-5, -5, 0), Vec3(5, -5, 0), Vec3(0, 6, 0)};
  const Eigen::Matrix3d tilt = rotationAbout(Vec3(1, 2, 0), 0.4);
  Tri3 small{Vec3(0, 0, 0), Vec3(0, 0.5, 0), Vec3(0.5, 0, 0)};  // normal −z
  for (Vec3& p : small) p = tilt * p + Vec3(0.3, -0.2, 0.02);
  for (ContactQuadrature q : kAllQuadratures) {
    const TriangleContact cs = computeTriangleContact(big, small, ContactLaw{law.k, 10.0}, q);
    ASSERT_TRUE(cs.active);
    EXPECT_NEAR(cs.area, triArea(small) * std::abs(triNormal(small).dot(cs.normal)), 1e-13);
    // The gap at the centroid of the small triangle, measured along n̂_AB.
    const Vec3 cen = (small[0] + small[1] + small[2]) / 3.0;
    const double g_cen = cen.z() / cs.normal.z();  // distance to z = 0 along n̂_AB
    EXPECT_NEAR(cs.mean_gap, g_cen, 1e-12);
    // Friction weights of B are those of its own centroid: 1/3 each.
    for (int i = 0; i < 3; ++i) EXPECT_NEAR(cs.bary_b[i], 1.0 / 3.0, 1e-12);
  }
}

TEST(ContactNarrowPhase, PartlyBeyondRangeIsClippedAnalytically) {
  // A = {x ≥ 0, y ≥ 0, x + y ≤ 2} in z = 0; B is a large triangle on the tilted plane
  // z = g0 + τx facing down. The line from (x, y, 0) along n̂ = (nx, 0, nz) meets B after
  // s = (g0 + τx)/(nz − τ nx): the gap grows linearly with x and reaches h0 at
  // x_c = (h0 (nz − τ nx) − g0)/τ. The contact is A ∩ {x < x_c}, scaled by n̂_A·n̂ = nz.
  const ContactLaw law;  // h0 = 0.06
  const double g0 = 0.01, tau = 0.05;
  const Tri3 a{Vec3(0, 0, 0), Vec3(2, 0, 0), Vec3(0, 2, 0)};
  auto onB = [&](double x, double y) { return Vec3(x, y, g0 + tau * x); };
  const Tri3 b{onB(-2, -2), onB(-2, 6), onB(6, -2)};
  const Vec3 na(0, 0, 1), nb = triNormal(b);
  const Vec3 n = (na - nb).normalized();
  const double nx = n.x(), nz = n.z(), denom = nz - tau * nx;
  const double xc = (law.h0 * denom - g0) / tau;
  ASSERT_GT(xc, 0.2);
  ASSERT_LT(xc, 1.8);
  const double area_on_a = 2.0 - 0.5 * (2 - xc) * (2 - xc);
  // ∫ g over the region on A: ∫_0^xc (α + βx)(2 − x) dx with α = g0/denom, β = τ/denom.
  const double al = g0 / denom, be = tau / denom;
  auto prim = [&](double x) { return 2 * al * x + (2 * be - al) * x * x / 2 - be * x * x * x / 3; };
  const double int_g_on_a = prim(xc);
  for (ContactQuadrature q : kAllQuadratures) {
    const TriangleContact c = computeTriangleContact(a, b, law, q);
    ASSERT_TRUE(c.active);
    EXPECT_NEAR((c.normal - n).norm(), 0, 1e-14);
    EXPECT_NEAR(c.area, area_on_a * nz, 1e-12);
    EXPECT_NEAR(c.force.dot(n), law.k * int_g_on_a * nz, 1e-10);
    EXPECT_NEAR(c.mean_gap, int_g_on_a / area_on_a, 1e-12);
    EXPECT_GT(c.mean_gap, 0);
    EXPECT_LT(c.mean_gap, law.h0);
  }
}

TEST(ContactNarrowPhase, GapBeyondRangeIsInactive) {
  const ContactLaw law;
  const Tri3 a{Vec3(0, 0, 0), Vec3(2, 0, 0), Vec3(0, 2, 0)};
  for (double g0 : {law.h0 * 1.0001, 0.1, 1.0}) {
    const Tri3 b{Vec3(0, 0, g0), Vec3(0, 2, g0), Vec3(2, 0, g0)};
    expectInactiveAndZero(computeTriangleContact(a, b, law, ContactQuadrature::Exact));
  }
  // Tilted, minimum gap above h0 everywhere.
  const Tri3 b{Vec3(0, 0, 0.07), Vec3(0, 2, 0.07), Vec3(2, 0, 0.2)};
  expectInactiveAndZero(computeTriangleContact(a, b, law, ContactQuadrature::Exact));
  // Projections do not overlap.
  const Tri3 far{Vec3(3, 3, 0.01), Vec3(3, 5, 0.01), Vec3(5, 3, 0.01)};
  expectInactiveAndZero(computeTriangleContact(a, far, law, ContactQuadrature::Exact));
}

TEST(ContactNarrowPhase, NotFacingOrDegenerateIsInactiveAndFinite) {
  const ContactLaw law;
  const Tri3 a{Vec3(0, 0, 0), Vec3(2, 0, 0), Vec3(0, 2, 0)};
  // Same orientation (not facing), and exactly perpendicular.
  expectInactiveAndZero(computeTriangleContact(
      a, {Vec3(0, 0, 0.01), Vec3(2, 0, 0.01), Vec3(0, 2, 0.01)}, law, ContactQuadrature::Exact));
  expectInactiveAndZero(
      computeTriangleContact(a, {Vec3(0.5, 0.5, -1), Vec3(0.5, 0.5, 1), Vec3(1.5, 0.5, 0)}, law,
                             ContactQuadrature::Exact));
  // Degenerate B: collinear, coincident vertices, nearly collinear.
  const std::vector<Tri3> degenerate{
      {Vec3(0, 0, 0.01), Vec3(1, 1, 0.01), Vec3(2, 2, 0.01)},
      {Vec3(0.5, 0.5, 0.01), Vec3(0.5, 0.5, 0.01), Vec3(0.5, 0.5, 0.01)},
      {Vec3(0, 0, 0.01), Vec3(1, 1e-16, 0.01), Vec3(2, 0, 0.01)},
      {Vec3(0, 0, 0.01), Vec3(0, 1, 0.01), Vec3(0, 1 + 1e-15, 0.01)}};
  for (const Tri3& d : degenerate) {
    expectInactiveAndZero(computeTriangleContact(a, d, law, ContactQuadrature::Exact));
    expectInactiveAndZero(computeTriangleContact(d, a, law, ContactQuadrature::Exact));
  }
  // Non-finite input.
  const Tri3 bad{Vec3(NAN, 0, 0.01), Vec3(0, 1, 0.01), Vec3(1, 0, 0.01)};
  expectInactiveAndZero(computeTriangleContact(a, bad, law, ContactQuadrature::Exact));
}

TEST(ContactNarrowPhase, NearlyPerpendicularFacingTrianglesAreFiniteAndConsistent) {
  // B's normal makes an angle just beyond 90° with A's: n̂_A·n̂_B = −sin(ε).
  const ContactLaw law;
  const Tri3 a{Vec3(-1, -1, 0), Vec3(1, -1, 0), Vec3(0, 1, 0)};
  for (double eps : {1e-12, 1e-6, 1e-2, 0.3}) {
    // B's plane contains the y axis direction rotated so that its normal is
    // (−cos ε, 0, −sin ε); it passes through (0.02, 0, 0) so it crosses A.
    const Vec3 nb(-std::cos(eps), 0, -std::sin(eps));
    const Vec3 u(0, 1, 0), w = nb.cross(u);  // in-plane directions of B, (u, w) ⟂ nb
    const Vec3 p(0.02, 0, 0);
    Tri3 b{p - 0.5 * u - 0.5 * w, p + 0.5 * u - 0.5 * w, p + 0.6 * w};
    if (triNormal(b).dot(nb) < 0) std::swap(b[1], b[2]);
    ASSERT_LT(triNormal(a).dot(triNormal(b)), 0);
    for (ContactQuadrature q : kAllQuadratures) {
      const TriangleContact c = computeTriangleContact(a, b, law, q);
      ASSERT_TRUE(allFinite(c)) << eps;
      ASSERT_TRUE(c.active) << eps;
      EXPECT_GT(c.area, 0);
      EXPECT_LE(c.mean_gap, law.h0);
      const auto f = nodalForces(c);
      Vec3 fsum = Vec3::Zero(), torque = Vec3::Zero();
      double fabs_sum = 0;
      for (int i = 0; i < 3; ++i) {
        fsum += f[i] + f[3 + i];
        torque += a[i].cross(f[i]) + b[i].cross(f[3 + i]);
        fabs_sum += f[i].norm() + f[3 + i].norm();
      }
      EXPECT_LE(fsum.norm(), 1e-12 * fabs_sum);
      EXPECT_LE(torque.norm(), 1e-10 * fabs_sum);
    }
    if (eps >= 1e-2) {
      const TriangleContact c = computeTriangleContact(a, b, law, ContactQuadrature::Exact);
      const GridReference r = gridIntegrate(a, b, law, 1000);
      EXPECT_NEAR(c.area, r.area, 2e-2 * c.area);
      EXPECT_NEAR(c.force.dot(c.normal), r.int_p, 2e-2 * law.k * c.area * law.h0);
    }
  }
}

// numerics.contact_law = prisms: a pair's polygon keeps only the points where B's point lies
// over A and A's over B. The pair that started the runaway of step fitness's seed 8 at Δt 0.5 s
// (cells 20 and 27 at t = 4 099.5 s; docs/science/motion-convergence.md): two triangles 0.19 µm
// apart at n̂_A·n̂_B = −0.13 whose planes cross beside them read a mean gap of −1.85 µm over
// 0.445 µm² along the bisector (58.6 nN); over each other they are nowhere within h0.
TEST(ContactNarrowPhase, WithinPrismsTheObliquePairThatBlewUpSeed8IsApart) {
  const auto [a, b] = seed8ObliquePair();
  ContactLaw law;
  law.k = 71.1;
  law.h0 = 0.0632;
  EXPECT_NEAR(triNormal(a).dot(triNormal(b)), -0.127, 1e-3);
  const TriangleContact plain = computeTriangleContact(a, b, law, ContactQuadrature::Exact);
  ASSERT_TRUE(plain.active);
  EXPECT_NEAR(plain.mean_gap, -1.854, 1e-3);
  EXPECT_NEAR(plain.area, 0.4449, 1e-3);
  ContactLaw prisms = law;
  prisms.kind = ContactLawKind::Prisms;
  for (ContactQuadrature q : kAllQuadratures) {
    const TriangleContact c = computeTriangleContact(a, b, prisms, q);
    EXPECT_FALSE(c.active);
    EXPECT_EQ(c.force, Vec3::Zero());
  }
  // The grid agrees: no sample of the plain polygon has both points over the other triangle.
  EXPECT_GT(gridIntegrate(a, b, law, 400).area, 0.4);
  EXPECT_EQ(gridIntegrate(a, b, prisms, 400).area, 0);
}

// Within prisms, random facing pairs up to 70° from antiparallel match the brute-force grid
// (area, ∫P, nodal weights, energy); between exactly antiparallel triangles the prisms' sides are
// the projected edges, and the polygon is the plain law's (to roundoff).
TEST(ContactNarrowPhase, WithinPrismsMatchesTheGridAndKeepsParallelPairs) {
  ContactLaw plain;
  ContactLaw prisms;
  prisms.kind = ContactLawKind::Prisms;
  std::mt19937 rng(11);
  int gridded = 0, clipped = 0;
  for (int trial = 0; trial < 300; ++trial) {
    const Pair pr = randomFacingPair(rng, -0.4, 0.05, 1.2);
    const TriangleContact p = computeTriangleContact(pr.a, pr.b, plain, ContactQuadrature::Exact);
    const TriangleContact c = computeTriangleContact(pr.a, pr.b, prisms, ContactQuadrature::Exact);
    ASSERT_TRUE(allFinite(c));
    if (!p.active) {
      EXPECT_FALSE(c.active) << trial;  // the prisms only take away
      continue;
    }
    if (c.active) {
      EXPECT_LE(c.area, p.area * (1 + 1e-12)) << trial;
    }
    if (c.area < p.area * (1 - 1e-6)) ++clipped;
    if (!(c.active && c.area > 0.02)) continue;
    ++gridded;
    expectMatchesGrid(c, gridIntegrate(pr.a, pr.b, prisms, 500), prisms.k, trial);
  }
  EXPECT_GT(gridded, 60);
  EXPECT_GT(clipped, 30);
  EXPECT_GT(antiparallelPairsAreTheLaws(rng, prisms), 150);
}

// A corner of one cell pressed 0.2 µm into the face of another, its triangle 50° from
// antiparallel: where the corner is under the face both points lie over the other triangle, so
// the prisms keep a repulsive contact there.
TEST(ContactNarrowPhase, WithinPrismsACornerPressedIntoAFaceStillRepels) {
  const Tri3 a{Vec3(-2, -2, 0), Vec3(2, -2, 0), Vec3(0, 2, 0)};  // n̂_A = +z
  Tri3 b{Vec3(0, 0, -0.2), Vec3(1, -0.6, 1), Vec3(1, 0.6, 1)};
  if (triNormal(b).z() > 0) std::swap(b[1], b[2]);
  ASSERT_LT(triNormal(a).dot(triNormal(b)), -0.5);
  ContactLaw prisms;
  prisms.kind = ContactLawKind::Prisms;
  const TriangleContact plain =
      computeTriangleContact(a, b, ContactLaw{}, ContactQuadrature::Exact);
  const TriangleContact c = computeTriangleContact(a, b, prisms, ContactQuadrature::Exact);
  ASSERT_TRUE(plain.active);
  ASSERT_TRUE(c.active);
  EXPECT_LT(c.mean_gap, 0);
  EXPECT_LT(c.force.dot(c.normal), 0);  // P = k g < 0 over the polygon: the cells pushed apart
  const GridReference r = gridIntegrate(a, b, prisms, 1000);
  EXPECT_NEAR(c.area, r.area, 2e-2 * c.area);
  EXPECT_NEAR(c.force.dot(c.normal), r.int_p, 2e-2 * std::abs(r.int_p));
}

// numerics.contact_law = prisms-overlap: the prisms bound only the overlapping part (g < 0), the
// adhesive part (0 ≤ g < h0) is kept whole. Seed 8's oblique pair, all of it read as overlap, is
// apart (no repulsion of micrometres); random pairs match the grid, whose points are kept by the
// same rule; a pair with no overlap is the plain law's bit for bit, an antiparallel one to
// roundoff; touching faces count once; a corner pressed into a face still repels.
TEST(ContactNarrowPhase, PrismsOnTheOverlapOnlyKeepTheAdhesivePartWhole) {
  ContactLaw plain;
  ContactLaw all = plain;
  all.kind = ContactLawKind::Prisms;
  ContactLaw overlap = all;
  overlap.kind = ContactLawKind::PrismsOverlap;
  {
    const auto [a, b] = seed8ObliquePair();
    ContactLaw law = overlap;
    law.h0 = 0.0632;
    ContactLaw its_plain = plain;
    its_plain.h0 = law.h0;
    // The law's whole polygon reads as overlap (no adhesive part to keep), and none of it lies
    // within the prisms: the pair is apart, as within prisms.
    const GridReference rp = gridIntegrate(a, b, its_plain, 400);
    ASSERT_GT(rp.area, 0.4);
    EXPECT_LT(rp.g_max, 0);
    EXPECT_EQ(gridIntegrate(a, b, law, 400).area, 0);
    for (ContactQuadrature q : kAllQuadratures) {
      const TriangleContact c = computeTriangleContact(a, b, law, q);
      EXPECT_FALSE(c.active);
      EXPECT_EQ(c.force, Vec3::Zero());
    }
  }
  std::mt19937 rng(13);
  int gridded = 0, differs = 0, adhesive_kept = 0, same = 0, two_pieces = 0;
  for (int trial = 0; trial < 300; ++trial) {
    const Pair pr = randomFacingPair(rng, -0.4, 0.05, 1.2);
    const TriangleContact p = computeTriangleContact(pr.a, pr.b, plain, ContactQuadrature::Exact);
    const TriangleContact c = computeTriangleContact(pr.a, pr.b, overlap, ContactQuadrature::Exact);
    const TriangleContact w = computeTriangleContact(pr.a, pr.b, all, ContactQuadrature::Exact);
    ASSERT_TRUE(allFinite(c));
    if (!p.active) {
      EXPECT_FALSE(c.active) << trial;
      continue;
    }
    if (c.active) {
      EXPECT_LE(c.area, p.area * (1 + 1e-12)) << trial;
      EXPECT_GE(c.area, w.area * (1 - 1e-12)) << trial;  // between the plain law and all-prisms
    }
    if (c.area < p.area * (1 - 1e-6)) ++differs;
    if (c.area > w.area * (1 + 1e-6)) ++adhesive_kept;
    if (!(c.active && c.area > 0.02)) continue;
    ++gridded;
    const GridReference r = gridIntegrate(pr.a, pr.b, overlap, 500);
    expectMatchesGrid(c, r, overlap.k, trial);
    // Pairs in two pieces: what else the step reads — the mean gap, the centroid (friction's
    // barycentrics), the friction and stiffness moments — against the grid, for every rule
    // that is exact for them.
    if (!(r.g_min < -0.01 && r.g_max > 0.01)) continue;
    ++two_pieces;
    EXPECT_NEAR(c.mean_gap, r.int_p / (overlap.k * r.area), 2e-2 * 0.4) << trial;
    EXPECT_LT((c.centroid - r.centroid).norm(), 2e-2) << trial;
    for (ContactQuadrature q : {ContactQuadrature::Exact, ContactQuadrature::Dunavant7}) {
      ContactMoments m;
      computeTriangleContact(pr.a, pr.b, overlap, q, &m);
      for (int i = 0; i < 9; ++i) EXPECT_NEAR(m.ab[i], r.ab[i], 2e-2 * c.area) << trial;
    }
  }
  EXPECT_GT(gridded, 60);
  EXPECT_GT(differs, 20);
  EXPECT_GT(adhesive_kept, 10);
  EXPECT_GT(two_pieces, 10);
  // Without overlap (nearly antiparallel, 0.02–0.055 µm apart) the pair is the plain law's, bit
  // for bit.
  for (int trial = 0; trial < 100; ++trial) {
    const Pair pr = randomFacingPair(rng, 0.02, 0.055, 0.01);
    if (!(gridIntegrate(pr.a, pr.b, plain, 100).g_min > 0.005)) continue;
    ContactMoments mp, mc;
    const TriangleContact p =
        computeTriangleContact(pr.a, pr.b, plain, ContactQuadrature::Exact, &mp);
    const TriangleContact c =
        computeTriangleContact(pr.a, pr.b, overlap, ContactQuadrature::Exact, &mc);
    if (!p.active) continue;
    ++same;
    EXPECT_EQ(c.force, p.force) << trial;
    EXPECT_EQ(c.area, p.area) << trial;
    EXPECT_EQ(c.energy, p.energy) << trial;
    EXPECT_EQ(c.force_weight_a, p.force_weight_a) << trial;
    EXPECT_EQ(c.force_weight_b, p.force_weight_b) << trial;
    EXPECT_EQ(mc.ab, mp.ab) << trial;
    EXPECT_EQ(c.mean_gap, p.mean_gap) << trial;
    EXPECT_EQ(c.centroid, p.centroid) << trial;
  }
  EXPECT_GT(same, 30);
  // Touching antiparallel faces, g ≡ 0 over the polygon: one piece, not counted twice.
  {
    const Tri3 a{Vec3(-1, -1, 0), Vec3(1, -1, 0), Vec3(0, 1, 0)};
    const Tri3 b{Vec3(-1, 1, 0), Vec3(1, 1, 0), Vec3(0, -1, 0)};
    ASSERT_NEAR(triNormal(a).dot(triNormal(b)), -1, 1e-15);
    ContactMoments mp, mc;
    const TriangleContact p = computeTriangleContact(a, b, plain, ContactQuadrature::Exact, &mp);
    const TriangleContact c = computeTriangleContact(a, b, overlap, ContactQuadrature::Exact, &mc);
    ASSERT_TRUE(p.active);
    EXPECT_EQ(c.area, p.area);
    EXPECT_EQ(mc.ab, mp.ab);
  }
  // Antiparallel pairs (a constant gap: one piece each, overlapping or adhesive) are the plain
  // law's, their moments included.
  EXPECT_GT(antiparallelPairsAreTheLaws(rng, overlap), 150);
  // The corner pressed 0.2 µm into a face, 50° from antiparallel: still repelled.
  const Tri3 a{Vec3(-2, -2, 0), Vec3(2, -2, 0), Vec3(0, 2, 0)};
  Tri3 b{Vec3(0, 0, -0.2), Vec3(1, -0.6, 1), Vec3(1, 0.6, 1)};
  if (triNormal(b).z() > 0) std::swap(b[1], b[2]);
  const TriangleContact c = computeTriangleContact(a, b, overlap, ContactQuadrature::Exact);
  ASSERT_TRUE(c.active);
  EXPECT_LT(c.force.dot(c.normal), 0);
  const GridReference r = gridIntegrate(a, b, overlap, 1000);
  EXPECT_NEAR(c.force.dot(c.normal), r.int_p, 2e-2 * std::abs(r.int_p));
}

// ---- 6. quadratures --------------------------------------------------------------------------

TEST(ContactNarrowPhase, QuadratureRulesAgreeWhereExact) {
  std::mt19937 rng(61);
  const ContactLaw law;
  int weights_differ = 0, checked = 0;
  for (int trial = 0; trial < 300; ++trial) {
    const Pair pr = randomFacingPair(rng, -0.1, 0.1, 0.3);
    ContactMoments em, dm;
    const TriangleContact e =
        computeTriangleContact(pr.a, pr.b, law, ContactQuadrature::Exact, &em);
    const TriangleContact d =
        computeTriangleContact(pr.a, pr.b, law, ContactQuadrature::Dunavant7, &dm);
    const TriangleContact m = computeTriangleContact(pr.a, pr.b, law, ContactQuadrature::Centroid);
    ASSERT_EQ(e.active, d.active);
    ASSERT_EQ(e.active, m.active);
    if (!e.active) continue;
    ++checked;
    const double fs = law.k * e.area * 0.1;  // force scale
    // Exact and Dunavant7 are both exact for these degree ≤ 2 integrands.
    EXPECT_NEAR(e.area, d.area, 1e-12 * e.area);
    EXPECT_NEAR((e.force - d.force).norm(), 0, 1e-10 * fs);
    EXPECT_NEAR(e.energy, d.energy, 1e-10 * fs * 0.1);
    EXPECT_NEAR((e.center_of_pressure - d.center_of_pressure).norm(), 0,
                1e-10 * (1 + (e.center_of_pressure - e.centroid).norm()));
    for (int i = 0; i < 3; ++i) {
      EXPECT_NEAR(e.force_weight_a[i], d.force_weight_a[i], 1e-10 * fs);
      EXPECT_NEAR(e.force_weight_b[i], d.force_weight_b[i], 1e-10 * fs);
    }
    // The stiffness moments ∫λλ dS (degree 2) agree too.
    for (int j = 0; j < 9; ++j) {
      EXPECT_NEAR(em.ab[j], dm.ab[j], 1e-12 * e.area);
      EXPECT_NEAR(em.aa[j], dm.aa[j], 1e-12 * e.area);
      EXPECT_NEAR(em.bb[j], dm.bb[j], 1e-12 * e.area);
    }
    // Centroid rule: exact for the affine pressure (same total force, area, centroid) ...
    EXPECT_NEAR(e.area, m.area, 1e-12 * e.area);
    EXPECT_NEAR((e.force - m.force).norm(), 0, 1e-10 * fs);
    EXPECT_NEAR((e.centroid - m.centroid).norm(), 0, 1e-10);
    // ... but not for the quadratic P·λ: weights generally differ, still summing to ∫P.
    double diff = 0, sum_a = 0, sum_b = 0;
    for (int i = 0; i < 3; ++i) {
      diff = std::max(diff, std::abs(e.force_weight_a[i] - m.force_weight_a[i]));
      sum_a += m.force_weight_a[i];
      sum_b += m.force_weight_b[i];
    }
    EXPECT_NEAR(sum_a, m.force.dot(m.normal), 1e-12 * fs);
    EXPECT_NEAR(sum_b, m.force.dot(m.normal), 1e-12 * fs);
    if (diff > 1e-6 * fs) ++weights_differ;
  }
  EXPECT_GT(checked, 150);
  EXPECT_GT(weights_differ, checked / 2);
}

// ---- 7. friction weights ---------------------------------------------------------------------

TEST(ContactNarrowPhase, FrictionBarycentricsAreAConvexCombinationGivingTheCentroid) {
  std::mt19937 rng(71);
  const ContactLaw law;
  int checked = 0;
  for (int trial = 0; trial < 400; ++trial) {
    const Pair pr = randomFacingPair(rng, -0.1, 0.1, 0.3);
    const TriangleContact c = computeTriangleContact(pr.a, pr.b, law, ContactQuadrature::Exact);
    if (!c.active) continue;
    ++checked;
    // Projection onto the plane ⟂ n̂_AB.
    const Eigen::Matrix3d proj = Eigen::Matrix3d::Identity() - c.normal * c.normal.transpose();
    double sa = 0, sb = 0;
    Vec3 ya = Vec3::Zero(), yb = Vec3::Zero();
    for (int i = 0; i < 3; ++i) {
      EXPECT_GE(c.bary_a[i], 0);
      EXPECT_GE(c.bary_b[i], 0);
      sa += c.bary_a[i];
      sb += c.bary_b[i];
      ya += c.bary_a[i] * (proj * pr.a[i]);
      yb += c.bary_b[i] * (proj * pr.b[i]);
    }
    EXPECT_NEAR(sa, 1, 1e-14);
    EXPECT_NEAR(sb, 1, 1e-14);
    const double size = (pr.a[1] - pr.a[0]).norm() + (pr.b[1] - pr.b[0]).norm();
    EXPECT_LE((ya - proj * c.centroid).norm(), 1e-12 * size);
    EXPECT_LE((yb - proj * c.centroid).norm(), 1e-12 * size);
    // The friction weights w_ik = λ_i^A λ_k^B then sum to 1 and are non-negative.
    double wsum = 0;
    for (int i = 0; i < 3; ++i)
      for (int k = 0; k < 3; ++k) wsum += c.bary_a[i] * c.bary_b[k];
    EXPECT_NEAR(wsum, 1, 1e-14);
  }
  EXPECT_GT(checked, 200);
}

// detectContacts asks only for what a ContactPair keeps: those fields must be the full
// computation's, bit for bit, for every quadrature and with moments, active or not.
TEST(ContactNarrowPhase, PairOnlyOutputsAreTheFullComputationsBits) {
  std::mt19937 rng(5);
  const ContactLaw law;
  int active = 0;
  for (int trial = 0; trial < 300; ++trial) {
    const Pair pr = randomFacingPair(rng, -0.1, 0.1, 0.3);
    const TriangleFrame fa = triangleFrame(pr.a), fb = triangleFrame(pr.b);
    for (const ContactQuadrature q : kAllQuadratures) {
      ContactMoments m_all, m_pair;
      const TriangleContact all = computeTriangleContact(pr.a, pr.b, fa, fb, law, q, &m_all);
      const TriangleContact pair =
          computeTriangleContact(pr.a, pr.b, fa, fb, law, q, &m_pair, ContactOutputs::PairOnly);
      ASSERT_EQ(pair.active, all.active);
      active += all.active;
      EXPECT_EQ(pair.normal, all.normal);
      EXPECT_EQ(pair.area, all.area);
      EXPECT_EQ(pair.force, all.force);
      EXPECT_EQ(pair.force_weight_a, all.force_weight_a);
      EXPECT_EQ(pair.force_weight_b, all.force_weight_b);
      EXPECT_EQ(pair.bary_a, all.bary_a);
      EXPECT_EQ(pair.bary_b, all.bary_b);
      EXPECT_EQ(pair.energy, all.energy);
      EXPECT_EQ(pair.mean_gap, all.mean_gap);
      EXPECT_EQ(m_pair.ab, m_all.ab);
      EXPECT_EQ(m_pair.aa, m_all.aa);
      EXPECT_EQ(m_pair.bb, m_all.bb);
      EXPECT_EQ(pair.centroid, Vec3::Zero());
      EXPECT_EQ(pair.center_of_pressure, Vec3::Zero());
      // The full computation's centroid is not zero where the pair is active.
      if (all.active) {
        EXPECT_GT(all.centroid.norm(), 0);
      }
    }
  }
  EXPECT_GT(active, 300);
}

}  // namespace
}  // namespace activefoam
