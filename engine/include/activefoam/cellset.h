// The state of all cells, packed as structure of arrays (ARCHITECTURE.md).
#pragma once

#include <cstdint>
#include <vector>

#include <Eigen/Core>

#include "activefoam/mesh.h"

namespace activefoam {

struct CellSet {
  // Per vertex (all cells packed; cell c owns vertices [cell_vertex_begin[c], [c+1]) ).
  Eigen::Matrix3Xd x;  // positions, µm
  Eigen::Matrix3Xd v;  // velocities of the last step, µm/s (CG warm start)
  std::vector<int> vertex_cell;
  // Per triangle (global vertex indices; cell c owns triangles [cell_tri_begin[c], [c+1]) ).
  std::vector<Tri> tri;
  std::vector<int> tri_cell;
  std::vector<int> cell_vertex_begin{0};
  std::vector<int> cell_tri_begin{0};
  // Per cell.
  std::vector<double> radius;         // r_l, µm
  std::vector<double> target_volume;  // V*_l = 4/3 π r_l³
  std::vector<double> pi_integral;    // I_l = ∫ ε_l dt, s (PI volume controller)
  std::vector<Vec3> polarity;         // p̂_l
  std::vector<int> label;             // spheroid label
  // Bumped whenever vertices or triangles are added, removed or renumbered (remeshing).
  std::uint64_t topology_version = 0;

  int numCells() const { return static_cast<int>(radius.size()); }
  int numVertices() const { return static_cast<int>(x.cols()); }
  int numTriangles() const { return static_cast<int>(tri.size()); }

  // Appends one cell. `mesh` is in absolute coordinates (µm).
  void addCell(const TriMesh& mesh, double radius_um, int label = 0);
  // Cell c's surface with local vertex indices.
  TriMesh cellMesh(int c) const;
  // Replaces every cell's surface (same cell order; per-cell scalars kept). Bumps the version.
  void setCellMeshes(const std::vector<TriMesh>& meshes);
};

}  // namespace activefoam
