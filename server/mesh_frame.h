// A snapshot's mesh in the compact binary form the dashboard's 3D view loads
// (GET /jobs/ID/snapshots/N.mesh): a VTK .vtp of a 2 × 100-cell frame is ~10 MB of text that a
// browser parses slowly; this is the same mesh as typed arrays it uses as they come.
//
// Layout (little-endian throughout):
//   bytes 0..3   "AFM1"
//   bytes 4..7   uint32 H: the length of the JSON header that follows (space-padded so that
//                8 + H is a multiple of 4, where the typed arrays start)
//   8 .. 8+H     JSON: {"format", "index", "t_s", "step", "vertices" V, "triangles" T, "cells" C,
//                "cell_id" [C], "spheroid" [C] (0 = A, 1 = B), "pressure_kPa" [C] (only where the
//                snapshot has pressures), "vertex_start" [C+1], "triangle_start" [C+1],
//                "bounds" [xmin, ymin, zmin, xmax, ymax, zmax], "positions_offset",
//                "triangles_offset"}
//   then         float32 positions [3 V] (µm), uint32 triangles [3 T] (vertex indices)
// Vertices and triangles are grouped by cell in the order of cell_id: cell k owns vertices
// [vertex_start[k], vertex_start[k+1]) and triangles [triangle_start[k], triangle_start[k+1]).
#pragma once

#include <string>

#include "activefoam/vtk.h"

namespace activefoam::server {

// Throws std::invalid_argument when a triangle or a vertex's cell is out of range.
std::string encodeMeshFrame(const VtkMesh& mesh, int index);

}  // namespace activefoam::server
