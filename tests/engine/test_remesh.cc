// Remeshing (docs/model.md §6.3): invariants and physics, never hard-coded outputs.
#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <fstream>
#include <iostream>
#include <map>
#include <random>
#include <set>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include <gtest/gtest.h>

#include "activefoam/cellset.h"
#include "activefoam/geometry.h"
#include "activefoam/remesh.h"
#include "activefoam/simulation.h"
#include "activefoam/spec.h"
#include "activefoam/step_guards.h"
#include "test_support.h"

using namespace activefoam;

namespace {

constexpr double kRadius = 8.88;  // µm, reference cell
const double kMeanArea = 4.0 * M_PI * kRadius * kRadius / 320.0;

TriMesh sphere(const Vec3& center = Vec3::Zero()) {
  TriMesh m = icosphere(2);
  m.x *= kRadius;
  m.x.colwise() += center;
  return m;
}

RemeshParams defaultParams() {
  RemeshParams p;
  p.min_area = kMeanArea / 3.0;
  p.max_area = 3.0 * kMeanArea;
  return p;
}

std::vector<int> valences(const TriMesh& m) {
  std::vector<int> val(m.numVertices(), 0);
  for (const Tri& f : m.tri)
    for (int k : f) ++val[k];
  return val;
}

int minValence(const TriMesh& m) {
  const auto val = valences(m);
  return *std::min_element(val.begin(), val.end());
}

std::pair<double, double> areaRange(const TriMesh& m) {
  double lo = 1e300, hi = 0;
  for (int t = 0; t < m.numTriangles(); ++t) {
    lo = std::min(lo, triangleArea(m, t));
    hi = std::max(hi, triangleArea(m, t));
  }
  return {lo, hi};
}

// Moves every vertex tangentially (Gaussian, σ = amp) and puts it back on the sphere of radius
// kRadius about `center`.
void perturbOnSphere(TriMesh& m, double amp, unsigned seed, const Vec3& center = Vec3::Zero()) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> n01;
  for (int i = 0; i < m.numVertices(); ++i) {
    Vec3 r = m.x.col(i) - center;
    const Vec3 nrm = r.normalized();
    Vec3 d(n01(rng), n01(rng), n01(rng));
    d -= d.dot(nrm) * nrm;
    r += amp * d;
    m.x.col(i) = center + kRadius * r.normalized();
  }
}

// Independent Delaunay test: interior angles opposite each edge, by atan2.
double angleAt(const Vec3& apex, const Vec3& a, const Vec3& b) {
  const Vec3 u = a - apex, v = b - apex;
  return std::atan2(u.cross(v).norm(), u.dot(v));
}

struct EdgeQuad {
  int i, j, k, l;  // triangles (i,j,k) and (j,i,l)
};

std::vector<EdgeQuad> edgeQuads(const TriMesh& m) {
  std::map<std::pair<int, int>, int> third;  // directed edge → opposite vertex in its triangle
  for (const Tri& f : m.tri)
    for (int e = 0; e < 3; ++e) third[{f[e], f[(e + 1) % 3]}] = f[(e + 2) % 3];
  std::vector<EdgeQuad> q;
  for (const auto& [ij, k] : third)
    if (ij.first < ij.second)
      q.push_back({ij.first, ij.second, k, third.at({ij.second, ij.first})});
  return q;
}

int countDelaunayViolations(const TriMesh& m, double tol = 1e-6) {
  int n = 0;
  for (const EdgeQuad& e : edgeQuads(m)) {
    const Vec3 xi = m.x.col(e.i), xj = m.x.col(e.j), xk = m.x.col(e.k), xl = m.x.col(e.l);
    if (angleAt(xk, xi, xj) + angleAt(xl, xi, xj) > M_PI + tol) ++n;
  }
  return n;
}

void expectValid(const TriMesh& m) {
  EXPECT_EQ(checkClosedManifold(m), "");
  EXPECT_GT(meshVolume(m), 0);
  EXPECT_GE(minValence(m), 4);
  EXPECT_EQ(m.v.cols(), m.x.cols());
}

}  // namespace

TEST(Remesh, IcosphereNeedsNoOperation) {
  const TriMesh ref = sphere();
  TriMesh m = ref;
  m.v.setRandom();
  const TriMesh withV = m;
  std::vector<int> map;
  const RemeshStats st = remesh(m, defaultParams(), map);
  EXPECT_EQ(st.splits, 0);
  EXPECT_EQ(st.collapses, 0);
  EXPECT_EQ(st.flips, 0);
  EXPECT_EQ(st.refused_collapses, 0);
  EXPECT_EQ(st.refused_flips, 0);
  EXPECT_EQ(st.volume_before, st.volume_after);
  EXPECT_EQ(st.volume_before, meshVolume(ref));
  // Bit-identical, identity renumbering.
  EXPECT_TRUE(m.x == withV.x);
  EXPECT_TRUE(m.v == withV.v);
  EXPECT_EQ(m.tri, withV.tri);
  ASSERT_EQ(static_cast<int>(map.size()), ref.numVertices());
  for (int i = 0; i < ref.numVertices(); ++i) EXPECT_EQ(map[i], i);
}

TEST(Remesh, DisabledThresholdsDoNothingOnIcosphere) {
  TriMesh m = sphere();
  const RemeshStats st = remesh(m, RemeshParams{});  // min_area = max_area = 0: off
  EXPECT_EQ(st.operations(), 0);
}

TEST(Remesh, ForcedSplitsKeepVolumeAndBoundArea) {
  // Off-origin centre: the volume bookkeeping must not depend on the frame.
  for (const Vec3& c : {Vec3(0, 0, 0), Vec3(120, -75, 40)}) {
    for (bool flips : {false, true}) {
      TriMesh m = sphere(c);
      const int nv0 = m.numVertices();
      const TriMesh before = m;
      std::vector<double> areas;
      for (int t = 0; t < m.numTriangles(); ++t) areas.push_back(triangleArea(m, t));
      std::sort(areas.begin(), areas.end());
      RemeshParams p;
      p.max_area = areas[areas.size() / 2];  // median: about half the triangles must split
      p.flips = flips;
      std::vector<int> map;
      const RemeshStats st = remesh(m, p, map);
      EXPECT_GT(st.splits, 0);
      EXPECT_EQ(st.collapses, 0);
      expectValid(m);
      EXPECT_EQ(m.numVertices(), nv0 + st.splits);
      EXPECT_EQ(m.numTriangles(), 320 + 2 * st.splits);
      // Guarantee: a split halves both triangles at the edge, and sweeps repeat until no
      // triangle exceeds max_area (within max_passes; met here).
      EXPECT_LE(areaRange(m).second, p.max_area);
      EXPECT_NEAR(st.volume_after, st.volume_before, 1e-12 * st.volume_before);
      EXPECT_NEAR(meshVolume(m), meshVolume(before), 1e-12 * meshVolume(before));
      if (!flips) {
        // Original vertices untouched and numbered as before.
        for (int i = 0; i < nv0; ++i) {
          EXPECT_EQ(map[i], i);
          EXPECT_TRUE(m.x.col(i) == before.x.col(i));
        }
        EXPECT_EQ(st.flips, 0);
      }
    }
  }
}

TEST(Remesh, SplitsStopAtMaxVertices) {
  TriMesh m = sphere();
  RemeshParams p;
  p.max_area = 1e-9;  // would split forever
  p.max_vertices = 1000;
  const RemeshStats st = remesh(m, p);
  expectValid(m);
  EXPECT_GE(m.numVertices(), p.max_vertices);
  EXPECT_LE(m.numVertices(), p.max_vertices + 1);
  EXPECT_NEAR(st.volume_after, st.volume_before, 1e-12 * st.volume_before);
}

TEST(Remesh, ForcedCollapsesPreserveVolume) {
  for (bool flips : {false, true}) {
    TriMesh m = sphere(Vec3(-30, 12, 55));
    double lo = 1e300, sum = 0;
    for (int t = 0; t < m.numTriangles(); ++t) {
      lo = std::min(lo, triangleArea(m, t));
      sum += triangleArea(m, t);
    }
    RemeshParams p;
    p.min_area = 0.5 * (lo + sum / m.numTriangles());  // between the smallest and the mean
    p.flips = flips;
    const RemeshStats st = remesh(m, p);
    EXPECT_GT(st.collapses, 0);
    EXPECT_EQ(st.splits, 0);
    expectValid(m);
    EXPECT_EQ(m.numVertices(), 162 - st.collapses);
    EXPECT_EQ(m.numTriangles(), 320 - 2 * st.collapses);
    // Closed-form volume-preserving placement (flip corrections too): round-off only.
    EXPECT_NEAR(st.volume_after, st.volume_before, 1e-12 * st.volume_before);
  }
}

TEST(Remesh, CollapseGuardsStopAtValidMesh) {
  // Every triangle is "too small": collapses run until the guards refuse; the mesh must stay
  // a valid closed 2-manifold with valence ≥ 4 and at least min_vertices vertices. With the
  // rescue (every triangle stays below half of A_m, so it runs) collapses may leave valence 3,
  // never less.
  for (int level : {1, 2})
    for (bool rescue : {false, true}) {
      SCOPED_TRACE(std::to_string(level) + (rescue ? " with the rescue" : ""));
      TriMesh m = icosphere(level);
      m.x *= kRadius;
      RemeshParams p;
      p.min_area = 1e6;
      p.max_passes = 50;
      p.rescue = rescue;
      const RemeshStats st = remesh(m, p);
      EXPECT_EQ(st.rescues, rescue ? 1 : 0);
      EXPECT_GT(st.collapses, 0);
      EXPECT_GT(st.refused_collapses, 0);
      EXPECT_EQ(checkClosedManifold(m), "");
      EXPECT_GT(meshVolume(m), 0);
      EXPECT_GE(minValence(m), rescue ? 3 : 4);
      EXPECT_GE(m.numVertices(), p.min_vertices);
      EXPECT_NEAR(st.volume_after, st.volume_before, 1e-10 * st.volume_before);
    }
}

using activefoam::testing::ObjCell;
using activefoam::testing::readObjCell;

// As Simulation::remeshCells sets them for a cell of this radius.
RemeshParams simulationParams(double radius, bool rescue) {
  const double a_ref = 4 * M_PI * radius * radius / 320;
  RemeshParams p;
  p.min_area = a_ref / 3;
  p.max_area = 3 * a_ref;
  p.smooth_min_angle_deg = 15;
  p.on_surface = true;
  p.rescue = rescue;
  return p;
}

// A cell that the remesher could not repair (tests/engine/data/locked-cell.obj): a squeezed cell
// of a motile fusion at Δt 1 s (p_a r/2γ = 1, α 0.4375, seed 3; docs/science/fig8-pa1-probe),
// remeshed at every step for 78 steps while its smallest triangle flattened to 2e-5 of 4πr²/N
// and then inverted. That triangle's vertices are three of valence 4 inside a triangle of three
// others: every collapse of its edges would leave one at valence 3, and every flip too, so both
// were refused.
TEST(Remesh, ALockedCellIsRepairedByTheRescue) {
  const ObjCell cell = readObjCell(std::string(ENGINE_TEST_DATA) + "/locked-cell.obj");
  const TriMesh& locked = cell.mesh;
  ASSERT_GT(cell.radius, 0);
  ASSERT_EQ(checkClosedManifold(locked), "");
  const double amin = simulationParams(cell.radius, false).min_area;
  ASSERT_LT(areaRange(locked).first, 1e-3 * amin);

  // Without the rescue: every collapse is refused, nothing changes, the sliver stays.
  TriMesh kept = locked;
  const RemeshStats refused = remesh(kept, simulationParams(cell.radius, false));
  EXPECT_GT(refused.refused_collapses, 0);
  EXPECT_EQ(refused.operations(), 0);
  EXPECT_EQ(refused.rescues, 0);
  EXPECT_LT(areaRange(kept).first, 1e-3 * amin);

  // With it: the collapses go through, and no triangle is left below the policy's trigger (half
  // of A_m); the mesh stays closed and oriented, of the same volume.
  TriMesh freed = locked;
  std::vector<int> old_to_new;
  const RemeshStats st = remesh(freed, simulationParams(cell.radius, true), old_to_new);
  EXPECT_EQ(st.rescues, 1);
  EXPECT_GT(st.collapses, 0);
  EXPECT_EQ(checkClosedManifold(freed), "");
  EXPECT_GE(minValence(freed), 3);
  EXPECT_GE(areaRange(freed).first, 0.5 * amin);
  EXPECT_NEAR(meshVolume(freed), meshVolume(locked), 1e-12 * meshVolume(locked));  // on_surface
  EXPECT_EQ(freed.numVertices(), locked.numVertices() - st.collapses);
  ASSERT_EQ(static_cast<int>(old_to_new.size()), locked.numVertices());
  for (int i = 0; i < locked.numVertices(); ++i) {
    ASSERT_GE(old_to_new[i], 0);
    ASSERT_LT(old_to_new[i], freed.numVertices());
  }
}

// A remesh that leaves no triangle below half of A_m runs no rescue: with it on, the mesh comes
// out bit for bit as without it (so runs that never lock keep their bits).
TEST(Remesh, TheRescueChangesNothingWhereNoTriangleIsLeftSmall) {
  int rescued = 0;
  for (unsigned seed : {1u, 2u, 3u, 4u, 5u}) {
    TriMesh a = sphere();
    perturbOnSphere(a, 0.8, seed);
    TriMesh b = a;
    const RemeshStats sa = remesh(a, simulationParams(kRadius, false));
    const RemeshStats sb = remesh(b, simulationParams(kRadius, true));
    rescued += sb.rescues;
    if (sb.rescues) continue;
    EXPECT_GT(sa.operations(), 0) << seed;
    EXPECT_EQ(a.tri, b.tri) << seed;
    EXPECT_EQ(a.x, b.x) << seed;
  }
  EXPECT_LT(rescued, 5);  // else this test compared nothing
}

// A cell the rescue could not repair (tests/engine/data/locked-cell-rescue-refused.obj): crumpled,
// 122 of its 162 vertices left, its rescued collapses refused in turn while its smallest triangle
// flattened to 9e-4 of A_m. With the rebuild the remesh lays a fresh icosphere on it: closed,
// oriented, of the icosphere's count, of the same volume, its vertices on the old surface (to the
// volume's rescaling), no triangle below the policy's trigger; its velocities interpolated.
TEST(Remesh, ACellTheRescueCannotRepairIsRebuilt) {
  const ObjCell cell =
      readObjCell(std::string(ENGINE_TEST_DATA) + "/locked-cell-rescue-refused.obj");
  ASSERT_GT(cell.radius, 0);
  TriMesh locked = cell.mesh;
  ASSERT_EQ(checkClosedManifold(locked), "");
  // A velocity field linear in x, which interpolation on the surface keeps exactly.
  const Eigen::Matrix3d grad =
      (Eigen::Matrix3d() << 0.1, 0.02, 0, -0.03, 0.05, 0.01, 0, 0.04, -0.02).finished();
  locked.v = grad * locked.x;
  RemeshParams p = simulationParams(cell.radius, true);
  const double amin = p.min_area;

  TriMesh rescued = locked;
  const RemeshStats only = remesh(rescued, p);
  EXPECT_EQ(only.rescues, 1);
  EXPECT_EQ(only.rebuilds, 0);
  EXPECT_LT(areaRange(rescued).first, 0.5 * amin);  // what the rebuild is for

  p.rebuild_triangles = 320;
  TriMesh rebuilt = locked;
  std::vector<int> old_to_new;
  const RemeshStats st = remesh(rebuilt, p, old_to_new);
  EXPECT_EQ(st.rescues, 1);
  EXPECT_EQ(st.rebuilds, 1);
  EXPECT_EQ(checkClosedManifold(rebuilt), "");
  EXPECT_EQ(rebuilt.numTriangles(), 320);
  EXPECT_GE(minValence(rebuilt), 5);
  EXPECT_GE(areaRange(rebuilt).first, 0.5 * amin);
  EXPECT_NEAR(meshVolume(rebuilt), meshVolume(locked), 1e-12 * meshVolume(locked));
  EXPECT_NEAR(st.volume_after, st.volume_before, 1e-12 * st.volume_before);
  // The area is not kept: the crumpled cell's folds are not resampled (0.958 of it here).
  EXPECT_NEAR(meshArea(rebuilt) / meshArea(locked), 1.0, 0.06);
  double off = 0;
  for (int i = 0; i < rebuilt.numVertices(); ++i) {
    double d2 = std::numeric_limits<double>::infinity();
    const Vec3 x = rebuilt.x.col(i);
    for (const Tri& f : locked.tri)
      d2 = std::min(
          d2, (closestOnTriangle(x, locked.x.col(f[0]), locked.x.col(f[1]), locked.x.col(f[2])) - x)
                  .squaredNorm());
    off = std::max(off, std::sqrt(d2));
  }
  EXPECT_LT(off, 0.05 * cell.radius);  // the rescaling moves them, by well under an edge
  // The interpolated velocities: those of the linear field where each vertex was laid, before
  // the rescaling moved it by at most `off`.
  for (int i = 0; i < rebuilt.numVertices(); ++i)
    EXPECT_LT((rebuilt.v.col(i) - grad * rebuilt.x.col(i)).norm(), grad.norm() * (off + 1e-9)) << i;
  ASSERT_EQ(static_cast<int>(old_to_new.size()), locked.numVertices());
  for (const int k : old_to_new) {
    ASSERT_GE(k, 0);
    ASSERT_LT(k, rebuilt.numVertices());
  }
}

// How deep p lies inside the closed mesh m (0 outside): winding number, then the nearest triangle.
double depthIn(const TriMesh& m, const Vec3& p) {
  double omega = 0, d2 = std::numeric_limits<double>::infinity();
  for (const Tri& f : m.tri) {
    const Vec3 a = m.x.col(f[0]) - p, b = m.x.col(f[1]) - p, c = m.x.col(f[2]) - p;
    const double la = a.norm(), lb = b.norm(), lc = c.norm();
    omega += 2 * std::atan2(a.dot(b.cross(c)),
                            la * lb * lc + a.dot(b) * lc + b.dot(c) * la + c.dot(a) * lb);
    d2 = std::min(
        d2, (closestOnTriangle(p, m.x.col(f[0]), m.x.col(f[1]), m.x.col(f[2])) - p).squaredNorm());
  }
  return omega / (4 * M_PI) > 0.5 ? std::sqrt(d2) : 0.0;
}

// The rebuild lays the new surface over the crumpled cell's folds: a neighbour's vertex pressed
// into a fold, outside the cell, can end up inside the rebuilt one (fig8, p_a r/2γ = 1, α 0.4375:
// 1.71 µm, a failure at every Δt; docs/numerics.md). With keep_out_points such a rebuild is
// refused and the cell keeps the mesh it had, bit for bit; one that engulfs nothing, or takes a
// point no deeper than the old surface did, is done as without it.
TEST(Remesh, ARebuildThatWouldEngulfATouchingCellsVertexIsRefused) {
  const ObjCell cell =
      readObjCell(std::string(ENGINE_TEST_DATA) + "/locked-cell-rescue-refused.obj");
  const TriMesh locked = cell.mesh;
  RemeshParams p = simulationParams(cell.radius, true);
  TriMesh rescued = locked;
  remesh(rescued, p);
  p.rebuild_triangles = 320;
  TriMesh rebuilt = locked;
  ASSERT_EQ(remesh(rebuilt, p).rebuilds, 1);

  // Points the rebuild engulfs: outside the rescued cell (where a neighbour may be), inside the
  // rebuilt one, the deepest of a grid over the cell's box.
  const Vec3 lo = locked.x.rowwise().minCoeff(), hi = locked.x.rowwise().maxCoeff();
  std::vector<std::array<double, 2>> depths;  // in the rescued mesh, in the rebuilt one
  std::vector<Vec3> grid;
  const int n = 20;
  for (int i = 0; i <= n; ++i)
    for (int j = 0; j <= n; ++j)
      for (int k = 0; k <= n; ++k) {
        grid.push_back(lo + (hi - lo).cwiseProduct(Vec3(i, j, k) / n));
        depths.push_back({depthIn(rescued, grid.back()), depthIn(rebuilt, grid.back())});
      }
  Vec3 engulfed = Vec3::Zero();
  double deepest = 0;
  for (std::size_t g = 0; g < grid.size(); ++g)
    if (depths[g][0] == 0 && depths[g][1] > deepest) deepest = depths[g][1], engulfed = grid[g];
  ASSERT_GT(deepest, 0.02) << "the rebuild bridges no fold of this cell";
  // Inside both, past the keep-out in the rebuilt mesh but deeper still in the one it replaces.
  Vec3 deeper_before = Vec3::Zero();
  bool found = false;
  for (std::size_t g = 0; g < grid.size() && !found; ++g)
    if (depths[g][1] > 0.5 * deepest && depths[g][0] > depths[g][1])
      deeper_before = grid[g], found = true;
  ASSERT_TRUE(found);
  const Vec3 far = hi + Vec3::Constant(5.0);

  p.keep_out_um = 0.5 * deepest;
  for (const auto& [points, refused] : std::vector<std::pair<std::vector<Vec3>, bool>>{
           {{far}, false}, {{deeper_before}, false}, {{far, engulfed}, true}}) {
    RemeshParams q = p;
    q.keep_out_points = [&pts = points](std::vector<Vec3>& out) {
      out.insert(out.end(), pts.begin(), pts.end());
    };
    TriMesh m = locked;
    const RemeshStats st = remesh(m, q);
    EXPECT_EQ(st.rebuilds, refused ? 0 : 1);
    EXPECT_EQ(st.rebuilds_kept_out, refused ? 1 : 0);
    const TriMesh& want = refused ? rescued : rebuilt;
    EXPECT_EQ(m.tri, want.tri);
    EXPECT_EQ(m.x, want.x);
  }
  // Deeper than the keep-out only: the same point at a keep-out above its depth is no reason.
  p.keep_out_um = 1.01 * deepest;
  p.keep_out_points = [&engulfed](std::vector<Vec3>& out) { out.push_back(engulfed); };
  TriMesh m = locked;
  EXPECT_EQ(remesh(m, p).rebuilds, 1);
  EXPECT_EQ(m.x, rebuilt.x);
}

// A remesh that leaves no triangle below half of A_m is the same with the rebuild as without it;
// and a mesh that is not star-shaped from its centroid is refused, unchanged.
TEST(Remesh, TheRebuildChangesNothingWhereNoTriangleIsLeftSmall) {
  for (unsigned seed : {1u, 2u, 3u}) {
    TriMesh a = sphere();
    perturbOnSphere(a, 0.8, seed);
    TriMesh b = a;
    RemeshParams pa = simulationParams(kRadius, true), pb = pa;
    pb.rebuild_triangles = 320;
    const RemeshStats sa = remesh(a, pa);
    const RemeshStats sb = remesh(b, pb);
    ASSERT_GE(areaRange(a).first, 0.5 * pa.min_area) << seed;
    EXPECT_GT(sa.operations(), 0) << seed;
    EXPECT_EQ(sb.rebuilds, 0) << seed;
    EXPECT_EQ(a.tri, b.tri) << seed;
    EXPECT_EQ(a.x, b.x) << seed;
  }
  // A sphere with a dimple pushed in past its centre: its centroid lies in the dent, where the
  // rays leave through the opening without meeting the surface.
  TriMesh dented = sphere();
  for (int i = 0; i < dented.numVertices(); ++i) {
    Vec3 x = dented.x.col(i);
    if (x[0] > 0.3 * kRadius) x[0] = 0.3 * kRadius - 1.6 * (x[0] - 0.3 * kRadius);
    dented.x.col(i) = x;
  }
  const TriMesh before = dented;
  EXPECT_FALSE(rebuildRadially(dented, 320));
  EXPECT_EQ(dented.x, before.x);
  EXPECT_EQ(dented.tri, before.tri);
}

// The simulation counts a rebuild (numerics.remesh_repair = rescue-rebuild) over the run, and a
// checkpoint of a run with the key carries the count, the key being in its fingerprint; with the
// key off the same cell keeps its mesh.
TEST(Remesh, TheSimulationCountsARebuildAndItsCheckpointKeepsIt) {
  const ObjCell cell =
      readObjCell(std::string(ENGINE_TEST_DATA) + "/locked-cell-rescue-refused.obj");
  SceneSpec s = activefoam::testing::cellSpec(1.0, 320);
  s.numerics.remesh_repair = RemeshRepair::Rescue;
  s = resolve(s);
  CellSet cells;
  cells.addCell(cell.mesh, cell.radius);
  for (const bool key : {false, true}) {
    SceneSpec k = s;
    k.numerics.remesh_repair = key ? RemeshRepair::RescueRebuild : RemeshRepair::Rescue;
    Simulation sim(k, cells);
    sim.remeshAll();
    EXPECT_EQ(sim.remeshRescues(), 1) << key;
    EXPECT_EQ(sim.remeshRebuilds(), key ? 1 : 0);
    EXPECT_EQ(sim.cells().numTriangles() == 320, key) << sim.cells().numTriangles();
    if (!key) continue;
    const std::string state = sim.saveState();
    Simulation back(k, cells);
    back.loadState(state);
    EXPECT_EQ(back.remeshRebuilds(), 1);
    EXPECT_EQ(back.cells().x, sim.cells().x);
    SceneSpec off = s;
    Simulation other(off, cells);
    EXPECT_THROW(other.loadState(state), std::invalid_argument);
  }
}

TEST(Remesh, FlipsRestoreDelaunayUnlessGuarded) {
  for (double amp : {0.5, 1.0}) {
    TriMesh m = sphere(Vec3(40, 40, -40));
    perturbOnSphere(m, amp, 12345, Vec3(40, 40, -40));
    ASSERT_EQ(checkClosedManifold(m), "");
    const int before = countDelaunayViolations(m);
    ASSERT_GT(before, 0);
    const TriMesh m0 = m;
    RemeshParams p;  // flips only
    p.max_passes = 20;
    const RemeshStats st = remesh(m, p);
    EXPECT_GT(st.flips, 0);
    EXPECT_EQ(st.splits + st.collapses, 0);
    expectValid(m);
    EXPECT_EQ(m.numVertices(), m0.numVertices());
    EXPECT_NEAR(st.volume_after, st.volume_before, 1e-12 * st.volume_before);
    // Volume correction moves vertices only slightly (far below the edge length ~2.7 µm).
    const double moved = (m.x - m0.x).colwise().norm().maxCoeff();
    // Each flip moves its four vertices by at most 5% of the shortest quad edge (measured max
    // over the call: 0.038 µm at amp 0.5, 0.23 µm at the strongly distorted amp 1.0).
    EXPECT_LT(moved, amp <= 0.5 ? 0.05 : 0.3);
    const int after = countDelaunayViolations(m);
    EXPECT_LT(after, before);
    // Converged: a second call flips nothing, and every remaining violation is one the guards
    // refuse (one sweep examines every edge once, so refusals = violations).
    const RemeshStats again = remesh(m, p);
    EXPECT_EQ(again.flips, 0);
    EXPECT_EQ(again.refused_flips, after);
    const std::string tag = amp <= 0.5 ? "_amp05" : "_amp10";
    RecordProperty("violations_before" + tag, before);
    RecordProperty("violations_after" + tag, after);
    RecordProperty("flips" + tag, st.flips);
    RecordProperty("max_move_nm" + tag, static_cast<int>(moved * 1e3));
  }
}

TEST(Remesh, FlipsWithoutCorrectionChangeVolumeByBoundedAmount) {
  TriMesh m = sphere();
  perturbOnSphere(m, 0.5, 777);
  const TriMesh m0 = m;
  RemeshParams p;
  p.flip_volume_correction = false;
  p.flip_max_volume = 1e-5;
  const RemeshStats st = remesh(m, p);
  expectValid(m);
  EXPECT_TRUE(m.x == m0.x);  // positions untouched without the correction
  // Each flip changes the volume by at most flip_max_volume·V.
  EXPECT_LE(std::abs(st.volume_after - st.volume_before),
            st.flips * p.flip_max_volume * st.volume_before * (1 + 1e-9));
}

namespace {

// Moves every vertex by Gaussian steps (σ = tangential µm along the surface, 0.02 µm across it,
// relative to the mesh's centroid): a cell jostled between remeshes.
void jostle(TriMesh& m, std::mt19937& rng, std::normal_distribution<double>& n01,
            double tangential) {
  Vec3 c = Vec3::Zero();
  for (int i = 0; i < m.numVertices(); ++i) c += m.x.col(i);
  c /= m.numVertices();
  for (int i = 0; i < m.numVertices(); ++i) {
    const Vec3 nrm = (m.x.col(i) - c).normalized();
    Vec3 d(n01(rng), n01(rng), n01(rng));
    const Vec3 radial = d.dot(nrm) * nrm;
    m.x.col(i) += tangential * (d - radial) + 0.02 * radial;  // µm
  }
}

}  // namespace

TEST(Remesh, RandomStress) {
  TriMesh m = sphere();
  const RemeshParams p = defaultParams();
  std::mt19937 rng(2024);
  std::normal_distribution<double> n01;
  RemeshStats total;
  double worstDv = 0;
  for (int round = 0; round < 200; ++round) {
    jostle(m, rng, n01, 0.1);
    const RemeshStats st = remesh(m, p);
    total.splits += st.splits;
    total.collapses += st.collapses;
    total.flips += st.flips;
    total.refused_collapses += st.refused_collapses;
    total.refused_flips += st.refused_flips;
    const double dv = std::abs(st.volume_after - st.volume_before) / st.volume_before;
    worstDv = std::max(worstDv, dv);
    ASSERT_EQ(checkClosedManifold(m), "") << "round " << round;
    ASSERT_GT(meshVolume(m), 0) << "round " << round;
    ASSERT_GE(minValence(m), 4) << "round " << round;
    const auto [lo, hi] = areaRange(m);
    ASSERT_GE(lo, p.min_area / 2) << "round " << round;
    ASSERT_LE(hi, 2 * p.max_area) << "round " << round;
    ASSERT_LT(dv, 1e-3) << "round " << round;   // docs/model.md §6.3 bound
    ASSERT_LT(dv, 1e-12) << "round " << round;  // what the placement/correction achieves
  }
  EXPECT_GT(total.splits, 0);
  EXPECT_GT(total.collapses, 0);
  EXPECT_GT(total.flips, 0);
  RecordProperty("splits", total.splits);
  RecordProperty("collapses", total.collapses);
  RecordProperty("flips", total.flips);
  RecordProperty("refused_collapses", total.refused_collapses);
  RecordProperty("refused_flips", total.refused_flips);
  RecordProperty("worst_rel_dV_e15", static_cast<int>(worstDv * 1e15));
}

// The simulation's settings with the rescue, on a cell jostled hard (0.5 µm a round) for 200
// rounds: every remesh, rescued or not, leaves a closed manifold (valence ≥ 3) of the same volume
// with no triangle below the trigger.
TEST(Remesh, RandomStressWithTheRescueKeepsTheMeshValid) {
  TriMesh m = sphere();
  const RemeshParams p = simulationParams(kRadius, true);
  int rescues = 0;
  std::mt19937 rng(7);
  std::normal_distribution<double> n01;
  int collapses = 0;
  for (int round = 0; round < 200; ++round) {
    jostle(m, rng, n01, 0.5);
    const double v0 = meshVolume(m);
    const RemeshStats st = remesh(m, p);
    collapses += st.collapses;
    rescues += st.rescues;
    ASSERT_EQ(checkClosedManifold(m), "") << "round " << round;
    ASSERT_GE(minValence(m), 3) << "round " << round;
    ASSERT_NEAR(meshVolume(m), v0, 1e-10 * v0) << "round " << round;
    ASSERT_GE(areaRange(m).first, p.min_area / 2) << "round " << round;
  }
  EXPECT_GT(collapses, 0);
  EXPECT_GT(rescues, 0);  // jostled this hard, some remeshes need the rescue (8 of 200 measured)
  RecordProperty("rescues", rescues);
}

TEST(Remesh, VelocitiesAveraged) {
  // Uniform velocity stays uniform through splits, collapses and flips.
  {
    TriMesh m = sphere();
    perturbOnSphere(m, 0.8, 99);
    const Vec3 u(0.3, -1.2, 0.05);
    m.v.colwise() = u;
    RemeshParams p = defaultParams();
    p.min_area = 0.6 * kMeanArea;
    p.max_area = 1.4 * kMeanArea;
    const RemeshStats st = remesh(m, p);
    EXPECT_GT(st.splits, 0);
    EXPECT_GT(st.collapses, 0);
    for (int i = 0; i < m.numVertices(); ++i) EXPECT_LT((m.v.col(i) - u).norm(), 1e-14);
  }
  // A linear field v = B x + b stays exactly linear through splits (new vertices are edge
  // midpoints carrying the average of the endpoint velocities).
  {
    TriMesh m = sphere(Vec3(5, -3, 2));
    Eigen::Matrix3d B;
    B << 0.1, -0.4, 0.2, 0.3, 0.05, -0.1, -0.2, 0.15, 0.25;
    const Vec3 b(1, 2, -3);
    m.v = (B * m.x).colwise() + b;
    RemeshParams p;
    p.max_area = 0.5 * kMeanArea;
    p.flips = false;  // flip volume correction moves vertices, not velocities
    const RemeshStats st = remesh(m, p);
    EXPECT_GT(st.splits, 0);
    for (int i = 0; i < m.numVertices(); ++i)
      EXPECT_LT((m.v.col(i) - (B * m.x.col(i) + b)).norm(), 1e-12);
  }
}

TEST(Remesh, OldToNewMapping) {
  TriMesh m = sphere();
  perturbOnSphere(m, 0.8, 4242);
  const TriMesh m0 = m;
  RemeshParams p;
  p.min_area = 0.7 * kMeanArea;
  p.flips = false;
  std::vector<int> map;
  const RemeshStats st = remesh(m, p, map);
  ASSERT_GT(st.collapses, 0);
  ASSERT_EQ(static_cast<int>(map.size()), m0.numVertices());
  std::map<int, int> hits;
  for (int i = 0; i < m0.numVertices(); ++i) {
    ASSERT_GE(map[i], 0);
    ASSERT_LT(map[i], m.numVertices());
    ++hits[map[i]];
  }
  // Without splits every output vertex comes from an input vertex; merged ones have several.
  EXPECT_EQ(static_cast<int>(hits.size()), m.numVertices());
  int merged = 0;
  for (int i = 0; i < m0.numVertices(); ++i) {
    if (hits[map[i]] == 1) {
      EXPECT_TRUE(m.x.col(map[i]) == m0.x.col(i));  // untouched vertex, same position
    } else {
      ++merged;
    }
  }
  EXPECT_GE(merged, 2);  // at least one pair merged
  EXPECT_EQ(m0.numVertices() - m.numVertices(), st.collapses);
  // Surviving vertices keep their relative order.
  for (int i = 0, last = -1; i < m0.numVertices(); ++i)
    if (hits[map[i]] == 1) {
      EXPECT_GT(map[i], last);
      last = map[i];
    }
}

// Tangential smoothing fixes a cap (an angle near 180°) without touching the topology, keeps the
// volume and leaves the mesh closed and manifold.
TEST(Remesh, SmoothingOpensACapTriangleAndKeepsTheVolume) {
  TriMesh m = icosphere(2);
  m.x *= 8.0;
  // Push vertex k of triangle 0 onto the midpoint of its opposite edge: a cap of ~180°.
  const Tri f = m.tri[0];
  const Vec3 mid = 0.5 * (m.x.col(f[1]) + m.x.col(f[2]));
  m.x.col(f[0]) = mid + 0.02 * (m.x.col(f[0]) - mid);
  auto minAngle = [&](const TriMesh& mesh) {
    double worst = 180;
    for (const Tri& t : mesh.tri)
      for (int k = 0; k < 3; ++k) {
        const Vec3 a = mesh.x.col(t[(k + 1) % 3]) - mesh.x.col(t[k]);
        const Vec3 b = mesh.x.col(t[(k + 2) % 3]) - mesh.x.col(t[k]);
        worst = std::min(worst, std::acos(a.normalized().dot(b.normalized())) * 180 / M_PI);
      }
    return worst;
  };
  const double before = minAngle(m), vol = meshVolume(m);
  ASSERT_LT(before, 2.0);
  RemeshParams p;
  p.flips = false;  // smoothing alone (the guards may refuse flips and collapses at a crease)
  p.smooth_min_angle_deg = 15;
  const auto tri = m.tri;
  const RemeshStats st = remesh(m, p);
  EXPECT_GT(st.smooths, 0);
  EXPECT_EQ(m.tri, tri);  // no topology change
  EXPECT_GT(minAngle(m), 10.0) << "was " << before;
  EXPECT_NEAR(meshVolume(m), vol, 1e-10 * vol);
  EXPECT_TRUE(checkClosedManifold(m).empty());
}

// After a remesh of some cells, the edge lists of the others are shifted rather than sorted
// again: the result must be the edge list built from scratch, for a cell that grew (its
// successors' offsets move up), one that shrank (down) and the cells between.
TEST(Remesh, EdgesOfCellsNotRemeshedAreShiftedToTheFullRebuild) {
  CellSet cells;
  for (int c = 0; c < 4; ++c) cells.addCell(sphere(Vec3(20.0 * c, 0, 0)), kRadius);
  Topology topo;
  ASSERT_TRUE(updateTopology(cells, topo));
  std::vector<TriMesh> meshes;
  for (int c = 0; c < 4; ++c) meshes.push_back(cells.cellMesh(c));
  RemeshParams grow = defaultParams();
  grow.max_area = 0.5 * kMeanArea;  // forces splits
  RemeshParams shrink = defaultParams();
  shrink.min_area = 2.0 * kMeanArea;  // forces collapses
  ASSERT_GT(remesh(meshes[1], grow).operations(), 0);
  ASSERT_GT(remesh(meshes[2], shrink).operations(), 0);
  const int old_begin3 = cells.cell_vertex_begin[3];
  cells.setCellMeshes(meshes);
  ASSERT_NE(cells.cell_vertex_begin[3], old_begin3);  // cell 3 moved: its edges need a shift
  const std::vector<char> same = {1, 0, 0, 1};
  ASSERT_TRUE(updateTopology(cells, topo, &same));
  Topology fresh;
  ASSERT_TRUE(updateTopology(cells, fresh));
  ASSERT_EQ(topo.edges.size(), fresh.edges.size());
  for (std::size_t e = 0; e < fresh.edges.size(); ++e) {
    const Edge &a = topo.edges[e], &b = fresh.edges[e];
    ASSERT_TRUE(a.i == b.i && a.j == b.j && a.ta == b.ta && a.tb == b.tb)
        << "edge " << e << ": (" << a.i << ", " << a.j << ", " << a.ta << ", " << a.tb
        << ") against (" << b.i << ", " << b.j << ", " << b.ta << ", " << b.tb << ")";
  }
  // The flags are what is trusted: an edge of cell 0 marked wrong in the old list comes through
  // (shifted), which shows the shift, not a rebuild, produced the cells flagged the same.
  std::swap(topo.edges[0].ta, topo.edges[0].tb);
  cells.setCellMeshes(meshes);  // a new topology version, the same meshes
  const std::vector<char> all(4, 1);
  ASSERT_TRUE(updateTopology(cells, topo, &all));
  EXPECT_EQ(topo.edges[0].ta, fresh.edges[0].tb);
  EXPECT_EQ(topo.edges[0].tb, fresh.edges[0].ta);
}

namespace {

// A cell pressed flat against a neighbour: the sphere's vertices above z = h put onto the plane,
// after a tangential perturbation that leaves small and thin triangles at the rim.
TriMesh flattenedCell(double h, unsigned seed) {
  TriMesh m = sphere();
  perturbOnSphere(m, 0.9, seed);
  for (int i = 0; i < m.numVertices(); ++i) m.x(2, i) = std::min(m.x(2, i), h);
  return m;
}

struct SurfaceMove {
  double outside = 0;     // the farthest a vertex lies outside the surface before the remesh
  double inside = 0;      // and inside it
  double past_plane = 0;  // how far the farthest vertex went beyond the contact plane
  RemeshStats stats;
};

SurfaceMove remeshFlattened(bool on_surface, unsigned seed) {
  constexpr double h = 6.0;
  TriMesh m = flattenedCell(h, seed);
  CellSet before;  // the surface before the remesh, measured with the guard's own functions
  before.addCell(m, kRadius);
  RemeshParams p;  // smoothing alone: collapses and flips place vertices alike either way
  p.flips = false;
  p.smooth_min_angle_deg = 15;
  p.on_surface = on_surface;
  SurfaceMove out;
  out.stats = remesh(m, p);
  EXPECT_TRUE(checkClosedManifold(m).empty()) << checkClosedManifold(m);
  const double volume = meshVolume(before.cellMesh(0));
  EXPECT_NEAR(meshVolume(m), volume, 1e-10 * volume);
  for (int i = 0; i < m.numVertices(); ++i) {
    const double d = distanceToSurface(before, 0, m.x.col(i));
    double& side = windingNumber(before, 0, m.x.col(i)) > 0.5 ? out.inside : out.outside;
    side = std::max(side, d);
    out.past_plane = std::max(out.past_plane, m.x(2, i) - h);
  }

  return out;
}

}  // namespace

// A remesh is blind to the neighbouring cells, so it must not move a vertex out of the surface
// it had: the local volume corrections of collapses and smoothing moved vertices along their
// normals by up to half an edge, and on a cell pressed against a neighbour that is into the
// neighbour (a 20-cell spheroid: a vertex 1.0 µm deep after one remesh, which the
// interpenetration guard stops). With on_surface no vertex crosses the contact plane by more
// than the one normal offset that restores the volume, and none lies outside the old surface by
// more than a tenth of numerics.max_penetration_um (what is left: the new triangles are chords,
// a vertex smoothed on them may sit a few tens of nm off the old ones, and flips keep their
// correction of at most 5 % of an edge); the local corrections fail both on the same meshes.
TEST(Remesh, OnTheSurfaceNoVertexLeavesItOrCrossesTheContactPlane) {
  const double tenth = 0.1 * NumericsParams{}.max_penetration_um;
  double local_outside = 0, local_past = 0;
  for (unsigned seed : {1u, 2u, 3u}) {
    const SurfaceMove local = remeshFlattened(false, seed);
    const SurfaceMove kept = remeshFlattened(true, seed);
    SCOPED_TRACE("seed " + std::to_string(seed));
    EXPECT_GT(kept.stats.smooths, 5);
    const double offset = std::abs(kept.stats.volume_offset);  // µm, smoothing's volume
    EXPECT_LT(offset, 0.05);
    EXPECT_LE(kept.past_plane, offset + 1e-9);
    EXPECT_LT(kept.outside, tenth);
    local_outside = std::max(local_outside, local.outside);
    local_past = std::max(local_past, local.past_plane);
    std::cout << "seed " << seed << ": outside the surface " << local.outside << " µm (local), "
              << kept.outside << " µm (on the surface, offset " << kept.stats.volume_offset
              << " µm); inside " << local.inside << " / " << kept.inside
              << " µm; past the contact plane " << local.past_plane << " / " << kept.past_plane
              << " µm\n";
  }
  EXPECT_GT(local_outside, tenth);
  EXPECT_GT(local_past, tenth);
}

namespace {

// How deep the deepest vertex of `a` lies inside `b` (generalised winding number > 1/2; depth =
// distance to b's surface), as the interpenetration guard measures it.
double deepestInside(const TriMesh& a, const TriMesh& b, double rb) {
  CellSet two;
  two.addCell(b, rb);
  double deepest = 0;
  for (int i = 0; i < a.numVertices(); ++i) {
    const Vec3 x = a.x.col(i);
    if (windingNumber(two, 0, x) > 0.5) deepest = std::max(deepest, distanceToSurface(two, 0, x));
  }
  return deepest;
}

}  // namespace

// A cell pressed against its neighbour (tests/engine/data/pressed-pair-A.obj against -B.obj, a
// fig9 run's state before the remesh that failed it): collapses place the merged vertex to keep
// the volume, moving it along its ring's normal by up to half an edge, and two chained collapses
// merge three vertices into one more than 1 µm inside the neighbour, past the interpenetration
// guard, whatever the step. With keep_out that collapse is refused: no vertex deeper than the
// keep-out depth, the mesh closed and oriented, its volume kept and no sliver left; a keep_out
// that refuses nothing leaves the remesh bit for bit what it is without one.
TEST(Remesh, KeepOutRefusesTheCollapseThatPushesAVertexIntoTheNeighbour) {
  const ObjCell a = readObjCell(std::string(ENGINE_TEST_DATA) + "/pressed-pair-A.obj");
  const ObjCell b = readObjCell(std::string(ENGINE_TEST_DATA) + "/pressed-pair-B.obj");
  ASSERT_EQ(checkClosedManifold(a.mesh), "");
  ASSERT_EQ(checkClosedManifold(b.mesh), "");
  const double limit = NumericsParams{}.max_penetration_um;
  ASSERT_LT(deepestInside(a.mesh, b.mesh, b.radius), 0.01);
  ASSERT_LT(deepestInside(b.mesh, a.mesh, a.radius), 0.01);
  RemeshParams p = simulationParams(a.radius, true);
  p.rebuild_triangles = 320;

  TriMesh plain = a.mesh;
  const RemeshStats free = remesh(plain, p);
  EXPECT_GE(free.collapses, 2);
  EXPECT_GT(deepestInside(plain, b.mesh, b.radius), limit);  // what keep_out is for

  CellSet two;
  two.addCell(b.mesh, b.radius);
  RemeshParams kp = p;
  kp.keep_out_um = limit / 4;
  kp.keep_out = [&two](const Vec3& x) {
    return windingNumber(two, 0, x) > 0.5 ? distanceToSurface(two, 0, x) : 0.0;
  };
  TriMesh kept = a.mesh;
  const RemeshStats st = remesh(kept, kp);
  EXPECT_GE(st.kept_out, 1);
  EXPECT_GE(st.refused_collapses, st.kept_out);
  EXPECT_EQ(checkClosedManifold(kept), "");
  EXPECT_GE(minValence(kept), 3);
  EXPECT_LE(deepestInside(kept, b.mesh, b.radius), kp.keep_out_um);
  EXPECT_NEAR(meshVolume(kept), meshVolume(a.mesh), 1e-9 * meshVolume(a.mesh));
  EXPECT_GE(areaRange(kept).first, 0.5 * p.min_area);
  std::cout << "pressed cell: deepest vertex in the neighbour "
            << deepestInside(plain, b.mesh, b.radius) << " µm after the remesh, "
            << deepestInside(kept, b.mesh, b.radius) << " µm with keep_out (" << st.kept_out
            << " collapse refused)\n";

  // A keep_out that refuses nothing: the same bits as none.
  RemeshParams zero = p;
  zero.keep_out_um = limit / 4;
  zero.keep_out = [](const Vec3&) { return 0.0; };
  TriMesh same = a.mesh;
  const RemeshStats sz = remesh(same, zero);
  EXPECT_EQ(sz.kept_out, 0);
  EXPECT_EQ(same.tri, plain.tri);
  ASSERT_EQ(same.x.cols(), plain.x.cols());
  EXPECT_EQ(0, std::memcmp(same.x.data(), plain.x.data(), sizeof(double) * plain.x.size()));
}
