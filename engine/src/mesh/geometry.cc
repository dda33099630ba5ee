#include "activefoam/geometry.h"

#include <algorithm>
#include <tuple>

#include "activefoam/threads.h"

namespace activefoam {

void computeGeometry(const CellSet& cells, Geometry& geo) {
  const int nt = cells.numTriangles(), nv = cells.numVertices(), nc = cells.numCells();
  geo.tri_normal.resize(nt);
  geo.tri_area.resize(nt);
  geo.vertex_area.assign(nv, 0.0);
  geo.vertex_normal.assign(nv, Vec3::Zero());
  geo.cell_volume.assign(nc, 0.0);
  geo.cell_area.assign(nc, 0.0);
  geo.cell_centroid.assign(nc, Vec3::Zero());
  const auto& x = cells.x;
  // Threads own whole cells: a cell's triangles touch only its own vertices and slots.
#pragma omp parallel for schedule(static) if (nt > grain().min_items)
  for (int c = 0; c < nc; ++c) {
    // Volume and centroid relative to a point of the cell, for conditioning far from the origin.
    const Vec3 o = x.col(cells.cell_vertex_begin[c]);
    double vol = 0, area = 0;
    Vec3 moment = Vec3::Zero();
    for (int t = cells.cell_tri_begin[c]; t < cells.cell_tri_begin[c + 1]; ++t) {
      const Tri& f = cells.tri[t];
      const Vec3 a = x.col(f[0]) - o, b = x.col(f[1]) - o, d = x.col(f[2]) - o;
      const Vec3 n2 = (b - a).cross(d - a);  // 2 S_A n̂_A
      const double s = 0.5 * n2.norm();
      geo.tri_area[t] = s;
      geo.tri_normal[t] = s > 0 ? Vec3(n2 / (2 * s)) : Vec3::Zero();
      area += s;
      const double tv = a.dot(b.cross(d)) / 6.0;  // signed tetrahedron (o, a, b, d)
      vol += tv;
      moment += tv * (a + b + d) / 4.0;
      for (int k = 0; k < 3; ++k) {
        geo.vertex_area[f[k]] += s / 3.0;
        geo.vertex_normal[f[k]] += n2 / 6.0;  // S_A n̂_A / 3
      }
    }
    geo.cell_volume[c] = vol;
    geo.cell_area[c] = area;
    geo.cell_centroid[c] = o + (vol != 0 ? Vec3(moment / vol) : Vec3::Zero());
  }
#pragma omp parallel for schedule(static) if (nv > grain().min_items)
  for (int i = 0; i < nv; ++i) {
    const double n = geo.vertex_normal[i].norm();
    if (n > 0) geo.vertex_normal[i] /= n;
  }
}

bool updateTopology(const CellSet& cells, Topology& topo, const std::vector<char>* same_mesh) {
  if (topo.version == cells.topology_version) return false;
  // Each undirected edge appears as i→j in one triangle and j→i in the other. A cell's triangles
  // use only its own vertices, and cells hold increasing vertex ranges: sorting each cell's
  // half-edges on its own and joining the cells in order gives the globally sorted list (a
  // global sort of the 2 × 100-cell fusion's ~190 000 half-edges took ~11 ms after every remesh),
  // and the cells can be sorted in parallel.
  const int nc = cells.numCells();
  const bool reuse = same_mesh && static_cast<int>(same_mesh->size()) == nc &&
                     static_cast<int>(topo.cell_tri_begin.size()) == nc + 1;
  if (reuse) topo.previous.swap(topo.edges);
  const std::vector<Edge>& old = topo.previous;
  std::vector<std::size_t> edge_begin(static_cast<std::size_t>(nc) + 1, 0);
  for (int c = 0; c < nc; ++c)
    edge_begin[c + 1] =
        edge_begin[c] +
        3 * static_cast<std::size_t>(cells.cell_tri_begin[c + 1] - cells.cell_tri_begin[c]) / 2;
  topo.edges.resize(edge_begin[nc]);
#pragma omp parallel if (cells.numTriangles() > grain().min_items)
  {
    std::vector<std::tuple<int, int, int>> half;  // (min, max, triangle), triangle sign by side
#pragma omp for schedule(dynamic, 8)
    for (int c = 0; c < nc; ++c) {
      Edge* out = topo.edges.data() + edge_begin[c];
      const int vb = cells.cell_vertex_begin[c], t0 = cells.cell_tri_begin[c];
      if (reuse && (*same_mesh)[c] &&
          topo.cell_tri_begin[c + 1] - topo.cell_tri_begin[c] == cells.cell_tri_begin[c + 1] - t0 &&
          topo.cell_vertex_begin[c + 1] - topo.cell_vertex_begin[c] ==
              cells.cell_vertex_begin[c + 1] - vb) {
        // The same mesh at other offsets: the same edges in the same order, indices shifted.
        const int dv = vb - topo.cell_vertex_begin[c], dt = t0 - topo.cell_tri_begin[c];
        for (std::size_t e = topo.cell_edge_begin[c]; e < topo.cell_edge_begin[c + 1]; ++e) {
          const Edge& o = old[e];
          *out++ = {o.i + dv, o.j + dv, o.ta + dt, o.tb + dt};
        }
        continue;
      }
      half.clear();
      for (int t = t0; t < cells.cell_tri_begin[c + 1]; ++t) {
        const Tri& f = cells.tri[t];
        for (int k = 0; k < 3; ++k) {
          const int a = f[k], b = f[(k + 1) % 3];
          // Encode the side: the triangle with a < b along its orientation is "A" (left).
          half.emplace_back(std::min(a, b), std::max(a, b), a < b ? t : -t - 1);
        }
      }
      std::sort(half.begin(), half.end());
      for (size_t k = 0; k + 1 < half.size(); k += 2) {
        const auto& [i, j, s0] = half[k];
        const int s1 = std::get<2>(half[k + 1]);
        const int ta = s0 >= 0 ? s0 : s1;
        const int tb = s0 >= 0 ? -s1 - 1 : -s0 - 1;
        *out++ = {i, j, ta, tb};
      }
    }
  }
  topo.cell_edge_begin = std::move(edge_begin);
  topo.cell_vertex_begin = cells.cell_vertex_begin;
  topo.cell_tri_begin = cells.cell_tri_begin;
  topo.version = cells.topology_version;
  return true;
}

Eigen::Matrix3d cellCovariance(const CellSet& cells, int c) {
  const Vec3 o = cells.x.col(cells.cell_vertex_begin[c]);
  double vol = 0;
  Vec3 m1 = Vec3::Zero();
  Eigen::Matrix3d m2 = Eigen::Matrix3d::Zero();
  for (int t = cells.cell_tri_begin[c]; t < cells.cell_tri_begin[c + 1]; ++t) {
    const Tri& f = cells.tri[t];
    const Vec3 a = cells.x.col(f[0]) - o, b = cells.x.col(f[1]) - o, d = cells.x.col(f[2]) - o;
    const double tv = a.dot(b.cross(d)) / 6.0;
    const Vec3 s = a + b + d;
    vol += tv;
    m1 += tv * s / 4.0;
    // ∫ x xᵀ over the tetrahedron (0, a, b, d) = V/20 (aaᵀ + bbᵀ + ddᵀ + ssᵀ).
    m2 +=
        tv / 20.0 * (a * a.transpose() + b * b.transpose() + d * d.transpose() + s * s.transpose());
  }
  const Vec3 mean = m1 / vol;
  return m2 / vol - mean * mean.transpose();
}

}  // namespace activefoam
