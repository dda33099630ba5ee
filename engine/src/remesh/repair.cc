// The repairs of a remesh that leaves a triangle below half of A_m (docs/numerics.md): the rescue
// (passes again, allowing collapses that leave a vertex of valence 3), the rebuild (a fresh
// icosphere laid on the cell's surface), and the keep-out that refuses a collapse or a rebuild
// that would push this cell into one it touches.
#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <utility>
#include <vector>

#include "activefoam/remesh.h"
#include "remesher.h"

namespace activefoam {
namespace {

double smallestArea(const TriMesh& m) {
  double a = std::numeric_limits<double>::infinity();
  for (int t = 0; t < m.numTriangles(); ++t) a = std::min(a, triangleArea(m, t));
  return a;
}

// How deep p lies inside the closed mesh m (0 outside).
double depthInside(const TriMesh& m, const Vec3& p) {
  if (windingNumber(m, p) <= 0.5) return 0;
  double d2 = std::numeric_limits<double>::infinity();
  for (const Tri& tr : m.tri)
    d2 = std::min(
        d2,
        (closestOnTriangle(p, m.x.col(tr[0]), m.x.col(tr[1]), m.x.col(tr[2])) - p).squaredNorm());
  return std::sqrt(d2);
}

// RemeshParams::keep_out_points: does the rebuilt mesh take a touching cell's vertex deeper than
// keep_out_um, and deeper than the mesh it replaces?
bool rebuildEngulfs(const TriMesh& before, const TriMesh& rebuilt, const RemeshParams& params) {
  if (!params.keep_out_points || !(params.keep_out_um > 0)) return false;
  std::vector<Vec3> points;
  params.keep_out_points(points);
  if (points.empty()) return false;
  Vec3 lo = rebuilt.x.rowwise().minCoeff(), hi = rebuilt.x.rowwise().maxCoeff();
  for (const Vec3& p : points) {
    if ((p.array() < lo.array()).any() || (p.array() > hi.array()).any()) continue;
    const double depth = depthInside(rebuilt, p);
    if (depth > params.keep_out_um && depth > depthInside(before, p)) return true;
  }
  return false;
}

}  // namespace

namespace remesh_internal {

void Remesher::run() {
  passes();
  // The rescue: only a remesh that leaves a triangle below half of A_m (the policy's trigger:
  // the cell would be due again at the next step, as locked as now) runs its passes again,
  // with collapses allowed to leave a vertex of valence 3. Every other remesh is the same as
  // without it, bit for bit.
  if (p_.rescue && p_.min_area > 0) {
    computeAreas();
    if (anyArea([&](double a) { return a < 0.5 * p_.min_area; })) {
      relaxed_ = true;
      ++st_.rescues;
      passes();
    }
  }
}

bool Remesher::keptOut(const Vec3& merged, int a, int b) {
  if (p_.keep_out) {
    const double depth = p_.keep_out(merged);
    if (depth > p_.keep_out_um && depth > p_.keep_out(x_[a]) && depth > p_.keep_out(x_[b])) {
      ++st_.kept_out;
      return true;
    }
  }
  return false;
}

void rebuildIfLeftSmall(TriMesh& mesh, const RemeshParams& params, std::vector<int>* old_to_new,
                        RemeshStats& st) {
  if (params.rebuild_triangles > 0 && params.min_area > 0) {
    const double smallest = smallestArea(mesh);
    if (smallest < 0.5 * params.min_area) {
      TriMesh rebuilt = mesh;
      const bool done =
          rebuildRadially(rebuilt, params.rebuild_triangles) && smallestArea(rebuilt) > smallest;
      const bool engulfs = done && rebuildEngulfs(mesh, rebuilt, params);
      if (engulfs) st.rebuilds_kept_out = 1;
      if (done && !engulfs) {
        if (old_to_new) {
          // Input vertex → the vertex it became → the new vertex nearest to that one.
          for (int& k : *old_to_new) {
            const Vec3 p = mesh.x.col(k);
            int best = 0;
            for (int j = 1; j < rebuilt.numVertices(); ++j)
              if ((rebuilt.x.col(j) - p).squaredNorm() < (rebuilt.x.col(best) - p).squaredNorm())
                best = j;
            k = best;
          }
        }
        mesh = std::move(rebuilt);
        st.rebuilds = 1;
      }
    }
  }
}

}  // namespace remesh_internal

bool rebuildRadially(TriMesh& mesh, int triangles) {
  const int level = icosphereLevelForTriangles(triangles);
  if (level < 0) throw std::invalid_argument("rebuildRadially: triangles must be 80, 320 or 1280");
  const int nt = mesh.numTriangles();
  // The volume centroid, about the vertices' mean (fewer digits lost than about the origin).
  Vec3 mean = mesh.x.rowwise().mean();
  double vol = 0;
  Vec3 moment = Vec3::Zero();
  for (const Tri& f : mesh.tri) {
    const Vec3 a = mesh.x.col(f[0]) - mean, b = mesh.x.col(f[1]) - mean,
               c = mesh.x.col(f[2]) - mean;
    const double v = a.dot(b.cross(c)) / 6;
    vol += v;
    moment += v * (a + b + c) / 4;
  }
  if (!(vol > 0)) return false;
  const Vec3 centre = mean + moment / vol;
  const bool has_v = mesh.v.cols() == mesh.x.cols();

  TriMesh out = icosphere(level);
  out.v = Eigen::Matrix3Xd::Zero(3, out.x.cols());
  for (int i = 0; i < out.numVertices(); ++i) {
    const Vec3 d = out.x.col(i).normalized();
    // Möller–Trumbore against every triangle; the outermost crossing wins.
    double best = -1;
    int tbest = -1;
    double ubest = 0, vbest = 0;
    for (int t = 0; t < nt; ++t) {
      const Tri& f = mesh.tri[t];
      const Vec3 a = mesh.x.col(f[0]), e1 = mesh.x.col(f[1]) - a, e2 = mesh.x.col(f[2]) - a;
      const Vec3 p = d.cross(e2);
      const double det = e1.dot(p);
      if (std::abs(det) < 1e-300) continue;
      const Vec3 s = centre - a;
      const double u = s.dot(p) / det;
      if (u < 0 || u > 1) continue;
      const Vec3 q = s.cross(e1);
      const double v = d.dot(q) / det;
      if (v < 0 || u + v > 1) continue;
      const double along = e2.dot(q) / det;
      if (along > best) {
        best = along;
        tbest = t;
        ubest = u;
        vbest = v;
      }
    }
    if (tbest < 0 || !(best > 0)) return false;
    out.x.col(i) = centre + best * d;
    if (has_v) {
      const Tri& f = mesh.tri[tbest];
      out.v.col(i) = (1 - ubest - vbest) * mesh.v.col(f[0]) + ubest * mesh.v.col(f[1]) +
                     vbest * mesh.v.col(f[2]);
    }
  }
  for (const Tri& f : out.tri) {
    const Vec3 a = out.x.col(f[0]), b = out.x.col(f[1]), c = out.x.col(f[2]);
    if (!((b - a).cross(c - a).dot((a + b + c) / 3 - centre) > 0)) return false;
  }
  const double scale = std::cbrt(meshVolume(mesh) / meshVolume(out));
  out.x = ((out.x.colwise() - centre) * scale).colwise() + centre;
  mesh = std::move(out);
  return true;
}

}  // namespace activefoam
