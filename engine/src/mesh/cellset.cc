#include "activefoam/cellset.h"

#include <cmath>
#include <stdexcept>

namespace activefoam {

void CellSet::addCell(const TriMesh& mesh, double radius_um, int cell_label) {
  const int c = numCells();
  const int v0 = numVertices();
  const int nv = mesh.numVertices();
  x.conservativeResize(3, v0 + nv);
  v.conservativeResize(3, v0 + nv);
  x.middleCols(v0, nv) = mesh.x;
  v.middleCols(v0, nv) = mesh.v.cols() == nv ? mesh.v : Eigen::Matrix3Xd::Zero(3, nv);
  vertex_cell.insert(vertex_cell.end(), nv, c);
  for (const Tri& t : mesh.tri) tri.push_back({t[0] + v0, t[1] + v0, t[2] + v0});
  tri_cell.insert(tri_cell.end(), mesh.tri.size(), c);
  cell_vertex_begin.push_back(v0 + nv);
  cell_tri_begin.push_back(numTriangles());
  radius.push_back(radius_um);
  target_volume.push_back(4.0 / 3.0 * M_PI * radius_um * radius_um * radius_um);
  pi_integral.push_back(0.0);
  polarity.push_back(Vec3::UnitX());
  label.push_back(cell_label);
  ++topology_version;
}

TriMesh CellSet::cellMesh(int c) const {
  const int v0 = cell_vertex_begin[c], v1 = cell_vertex_begin[c + 1];
  TriMesh m;
  m.x = x.middleCols(v0, v1 - v0);
  m.v = v.middleCols(v0, v1 - v0);
  for (int t = cell_tri_begin[c]; t < cell_tri_begin[c + 1]; ++t)
    m.tri.push_back({tri[t][0] - v0, tri[t][1] - v0, tri[t][2] - v0});
  return m;
}

void CellSet::setCellMeshes(const std::vector<TriMesh>& meshes) {
  if (static_cast<int>(meshes.size()) != numCells())
    throw std::logic_error("setCellMeshes: one mesh per cell expected");
  int nv = 0, nt = 0;
  for (const auto& m : meshes) {
    nv += m.numVertices();
    nt += m.numTriangles();
  }
  x.resize(3, nv);
  v.resize(3, nv);
  vertex_cell.assign(nv, 0);
  tri.clear();
  tri.reserve(nt);
  tri_cell.clear();
  tri_cell.reserve(nt);
  cell_vertex_begin.assign(1, 0);
  cell_tri_begin.assign(1, 0);
  int v0 = 0;
  for (int c = 0; c < numCells(); ++c) {
    const TriMesh& m = meshes[c];
    const int n = m.numVertices();
    x.middleCols(v0, n) = m.x;
    v.middleCols(v0, n) = m.v;
    std::fill(vertex_cell.begin() + v0, vertex_cell.begin() + v0 + n, c);
    for (const Tri& t : m.tri) tri.push_back({t[0] + v0, t[1] + v0, t[2] + v0});
    tri_cell.insert(tri_cell.end(), m.tri.size(), c);
    v0 += n;
    cell_vertex_begin.push_back(v0);
    cell_tri_begin.push_back(static_cast<int>(tri.size()));
  }
  ++topology_version;
}

}  // namespace activefoam
