// Per-step geometry of the packed meshes, and the edge topology of each cell.
#pragma once

#include <cstdint>
#include <vector>

#include "activefoam/cellset.h"

namespace activefoam {

struct Geometry {
  std::vector<Vec3> tri_normal;     // n̂_A, unit, outward
  std::vector<double> tri_area;     // S_A
  std::vector<double> vertex_area;  // S_i = Σ_{A∋i} S_A / 3
  std::vector<Vec3> vertex_normal;  // area-weighted unit normal n̂_i
  std::vector<double> cell_volume;  // V_l
  std::vector<double> cell_area;    // S_l
  std::vector<Vec3> cell_centroid;  // volume centroid x_c,l
};

void computeGeometry(const CellSet& cells, Geometry& geo);

// Mesh edges with their two adjacent triangles (A on the left of i→j, B on the right).
struct Edge {
  int i, j;    // global vertex indices
  int ta, tb;  // triangles sharing the edge
};

struct Topology {
  std::vector<Edge> edges;
  std::uint64_t version = ~std::uint64_t{0};  // CellSet::topology_version it was built for
};

// Rebuilds the edge list when cells.topology_version changed; returns true if it rebuilt.
bool updateTopology(const CellSet& cells, Topology& topo);

// Volume covariance (second central moment / V) of cell c: principal axes of an ellipsoid with
// semi-axes a_k have eigenvalues a_k²/5.
Eigen::Matrix3d cellCovariance(const CellSet& cells, int c);

}  // namespace activefoam
