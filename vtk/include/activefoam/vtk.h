// VTK XML output of cell meshes (ParaView opens them): PolyData (.vtp) and a time series index
// (.pvd). Plain data in, text out: no libvtk, no engine, no Eigen, so that foam-run (from the
// engine's snapshots) and the foam client (from the server's snapshot messages, without linking
// the engine) write the same files.
#pragma once

#include <array>
#include <cstdint>
#include <ostream>
#include <string>
#include <utility>
#include <vector>

namespace activefoam {

struct VtkMesh {
  double t_s = 0;
  std::int64_t step = 0;
  std::vector<double> points;  // x0 y0 z0 x1 y1 z1 ... (µm)
  std::vector<std::array<int, 3>> tri;
  std::vector<int> vertex_cell;       // cell id of each vertex (may be empty: all 0)
  std::vector<double> cell_pressure;  // P_l, kPa, per cell (may be short: 0)
  std::vector<int> cell_label;        // spheroid label per cell (may be short: 0)
};

// One mesh as VTK XML PolyData: Points, Polys (connectivity/offsets), PointData `cell_id`,
// CellData (per triangle) `cell_id`, `spheroid` (the cell's label) and `pressure` (the cell's
// P_l, kPa), and FieldData TIME/STEP. Missing per-cell labels or pressures are written as 0.
// Throws std::invalid_argument when points is not a multiple of 3, vertex_cell is neither empty
// nor one entry per point, or a triangle references a vertex out of range.
void writeVtp(std::ostream& os, const VtkMesh& mesh);

// Reads back what writeVtp wrote (ASCII PolyData with the arrays above): points, triangles,
// per-vertex cell ids, and per cell the pressure and spheroid label (from the triangles' values).
// Values are exact (writeVtp prints shortest round-trip decimals). Throws std::invalid_argument
// naming what is missing or malformed.
VtkMesh readVtp(const std::string& text);

// A ParaView collection: one DataSet per (time, file) in the given order; file names are
// written as given (relative to the .pvd) and XML-escaped.
void writePvd(std::ostream& os, const std::vector<std::pair<double, std::string>>& time_and_file);

}  // namespace activefoam
