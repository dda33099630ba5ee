// Brakke-style remeshing of one closed cell surface (DESIGN.md §5).
#pragma once

#include "activefoam/mesh.h"

namespace activefoam {

struct RemeshParams {
  double min_area = 0;  // A_m: collapse the shortest edge of triangles smaller than this
  double max_area = 0;  // A_M: split the longest edge of triangles larger than this
  int max_passes = 8;   // bound on split/collapse/flip sweeps per call
};

struct RemeshStats {
  int splits = 0;
  int collapses = 0;
  int flips = 0;
  int refused_collapses = 0;  // candidates rejected by the manifold/orientation/valence guards
  double volume_before = 0;
  double volume_after = 0;
  int operations() const { return splits + collapses + flips; }
};

// Splits, collapses and Delaunay flips in place. Keeps the mesh closed, 2-manifold, oriented,
// with vertex valence ≥ 4; keeps the enclosed volume (collapsed vertices are placed to preserve
// it). Velocities are carried along (averaged on split/collapse) for the CG warm start.
RemeshStats remesh(TriMesh& mesh, const RemeshParams& params);

}  // namespace activefoam
