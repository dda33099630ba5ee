#include "activefoam/mesh.h"

#include <algorithm>
#include <cmath>
#include <map>
#include <sstream>
#include <unordered_map>
#include <utility>

namespace activefoam {

TriMesh icosphere(int levels) {
  const double p = (1.0 + std::sqrt(5.0)) / 2.0;
  std::vector<Vec3> pts = {{-1, p, 0}, {1, p, 0}, {-1, -p, 0}, {1, -p, 0},
                           {0, -1, p}, {0, 1, p}, {0, -1, -p}, {0, 1, -p},
                           {p, 0, -1}, {p, 0, 1}, {-p, 0, -1}, {-p, 0, 1}};
  for (auto& q : pts) q.normalize();
  std::vector<Tri> tris = {{0, 11, 5}, {0, 5, 1},  {0, 1, 7},   {0, 7, 10}, {0, 10, 11},
                           {1, 5, 9},  {5, 11, 4}, {11, 10, 2}, {10, 7, 6}, {7, 1, 8},
                           {3, 9, 4},  {3, 4, 2},  {3, 2, 6},   {3, 6, 8},  {3, 8, 9},
                           {4, 9, 5},  {2, 4, 11}, {6, 2, 10},  {8, 6, 7},  {9, 8, 1}};
  for (int l = 0; l < levels; ++l) {
    std::map<std::pair<int, int>, int> mid;
    auto midpoint = [&](int a, int b) {
      auto key = std::minmax(a, b);
      auto it = mid.find(key);
      if (it != mid.end()) return it->second;
      pts.push_back((pts[a] + pts[b]).normalized());
      const int id = static_cast<int>(pts.size()) - 1;
      mid.emplace(key, id);
      return id;
    };
    std::vector<Tri> next;
    next.reserve(tris.size() * 4);
    for (const Tri& t : tris) {
      const int a = midpoint(t[0], t[1]), b = midpoint(t[1], t[2]), c = midpoint(t[2], t[0]);
      next.push_back({t[0], a, c});
      next.push_back({t[1], b, a});
      next.push_back({t[2], c, b});
      next.push_back({a, b, c});
    }
    tris.swap(next);
  }
  TriMesh m;
  m.x.resize(3, static_cast<Eigen::Index>(pts.size()));
  for (size_t i = 0; i < pts.size(); ++i) m.x.col(static_cast<Eigen::Index>(i)) = pts[i];
  m.v = Eigen::Matrix3Xd::Zero(3, m.x.cols());
  m.tri = std::move(tris);
  return m;
}

int icosphereLevelForTriangles(int triangles) {
  switch (triangles) {
    case 80:
      return 1;
    case 320:
      return 2;
    case 1280:
      return 3;
    default:
      return -1;
  }
}

double meshVolume(const TriMesh& m) {
  double v = 0;
  for (const Tri& t : m.tri) v += m.x.col(t[0]).dot(m.x.col(t[1]).cross(m.x.col(t[2])));
  return v / 6.0;
}

double triangleArea(const TriMesh& m, int t) {
  const Tri& f = m.tri[t];
  return 0.5 * (m.x.col(f[1]) - m.x.col(f[0])).cross(m.x.col(f[2]) - m.x.col(f[0])).norm();
}

Vec3 closestOnTriangle(const Vec3& p, const Vec3& a, const Vec3& b, const Vec3& c) {
  const Vec3 ab = b - a, ac = c - a, ap = p - a;
  const double d1 = ab.dot(ap), d2 = ac.dot(ap);
  if (d1 <= 0 && d2 <= 0) return a;
  const Vec3 bp = p - b;
  const double d3 = ab.dot(bp), d4 = ac.dot(bp);
  if (d3 >= 0 && d4 <= d3) return b;
  const double vc = d1 * d4 - d3 * d2;
  if (vc <= 0 && d1 >= 0 && d3 <= 0) return a + d1 / (d1 - d3) * ab;
  const Vec3 cp = p - c;
  const double d5 = ab.dot(cp), d6 = ac.dot(cp);
  if (d6 >= 0 && d5 <= d6) return c;
  const double vb = d5 * d2 - d1 * d6;
  if (vb <= 0 && d2 >= 0 && d6 <= 0) return a + d2 / (d2 - d6) * ac;
  const double va = d3 * d6 - d5 * d4;
  if (va <= 0 && d4 - d3 >= 0 && d5 - d6 >= 0)
    return b + (d4 - d3) / ((d4 - d3) + (d5 - d6)) * (c - b);
  const double denom = 1 / (va + vb + vc);
  return a + ab * (vb * denom) + ac * (vc * denom);
}

double solidAngle(const Vec3& p, const Vec3& a, const Vec3& b, const Vec3& c) {
  const Vec3 u = a - p, v = b - p, w = c - p;
  const double lu = u.norm(), lv = v.norm(), lw = w.norm();
  const double det = u.dot(v.cross(w));
  const double den = lu * lv * lw + u.dot(v) * lw + v.dot(w) * lu + w.dot(u) * lv;
  return 2 * std::atan2(det, den);
}

double windingNumber(const TriMesh& m, const Vec3& p) {
  double omega = 0;
  for (const Tri& t : m.tri) omega += solidAngle(p, m.x.col(t[0]), m.x.col(t[1]), m.x.col(t[2]));
  return omega / (4 * M_PI);
}

double meshArea(const TriMesh& m) {
  double a = 0;
  for (int t = 0; t < m.numTriangles(); ++t) a += triangleArea(m, t);
  return a;
}

std::string checkClosedManifold(const TriMesh& m) {
  const int nv = m.numVertices();
  std::ostringstream err;
  // Directed edge counts: a closed oriented manifold has each directed edge exactly once and
  // its reverse exactly once.
  std::unordered_map<long long, int> directed;
  auto key = [nv](int a, int b) { return static_cast<long long>(a) * nv + b; };
  std::vector<int> used(nv, 0);
  for (int t = 0; t < m.numTriangles(); ++t) {
    const Tri& f = m.tri[t];
    for (int k = 0; k < 3; ++k) {
      if (f[k] < 0 || f[k] >= nv) {
        err << "triangle " << t << " has out-of-range vertex " << f[k];
        return err.str();
      }
      used[f[k]]++;
    }
    if (f[0] == f[1] || f[1] == f[2] || f[2] == f[0]) {
      err << "triangle " << t << " repeats a vertex";
      return err.str();
    }
    for (int k = 0; k < 3; ++k) {
      if (++directed[key(f[k], f[(k + 1) % 3])] > 1) {
        err << "directed edge " << f[k] << "->" << f[(k + 1) % 3]
            << " appears twice (inconsistent orientation or non-manifold edge)";
        return err.str();
      }
    }
  }
  for (const auto& [k, c] : directed) {
    const int a = static_cast<int>(k / nv), b = static_cast<int>(k % nv);
    if (!directed.count(key(b, a))) {
      err << "edge " << a << "-" << b << " is a boundary edge (mesh not closed)";
      return err.str();
    }
  }
  for (int i = 0; i < nv; ++i) {
    if (!used[i]) {
      err << "vertex " << i << " is unused";
      return err.str();
    }
  }
  // Vertex links must be one cycle: follow next-edges around each vertex.
  std::vector<std::vector<std::pair<int, int>>> link(nv);  // for vertex i: (j, k) of tri (i,j,k)
  for (const Tri& f : m.tri)
    for (int k = 0; k < 3; ++k) link[f[k]].push_back({f[(k + 1) % 3], f[(k + 2) % 3]});
  for (int i = 0; i < nv; ++i) {
    const auto& l = link[i];
    std::unordered_map<int, int> next;
    for (const auto& [a, b] : l) next[a] = b;
    int start = l[0].first, cur = start, steps = 0;
    do {
      cur = next[cur];
      ++steps;
    } while (cur != start && steps <= static_cast<int>(l.size()));
    if (steps != static_cast<int>(l.size())) {
      err << "vertex " << i << " is non-manifold (its link is not a single cycle)";
      return err.str();
    }
  }
  const int euler = nv - static_cast<int>(directed.size()) / 2 + m.numTriangles();
  if (euler != 2) {
    err << "Euler characteristic " << euler << " != 2 (not a sphere)";
    return err.str();
  }
  if (meshVolume(m) <= 0) return "non-positive enclosed volume (inward orientation)";
  return {};
}

}  // namespace activefoam
