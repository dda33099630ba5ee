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
  std::vector<Edge> edges;                    // cell by cell; within a cell sorted by (i, j)
  std::uint64_t version = ~std::uint64_t{0};  // CellSet::topology_version it was built for
  // The layout it was built for: where each cell's edges, vertices and triangles begin.
  std::vector<std::size_t> cell_edge_begin;
  std::vector<int> cell_vertex_begin, cell_tri_begin;
  std::vector<Edge> previous;  // updateTopology's buffer for the list it shifts from (kept: the
                               // list is ~3 MB on the 2 × 100 fusion, rebuilt after each remesh)
};

// Rebuilds the edge list when cells.topology_version changed; returns true if it rebuilt.
// `same_mesh` (optional, one flag per cell): cells whose mesh is the one `topo` was built for,
// only moved in the packed arrays (a remesh of other cells); their edges are shifted instead of
// sorted again. The result is the same as a full rebuild.
bool updateTopology(const CellSet& cells, Topology& topo,
                    const std::vector<char>* same_mesh = nullptr);

// Volume covariance (second central moment / V) of cell c: principal axes of an ellipsoid with
// semi-axes a_k have eigenvalues a_k²/5.
Eigen::Matrix3d cellCovariance(const CellSet& cells, int c);

}  // namespace activefoam
