// VTK XML output of snapshots (ParaView opens them): PolyData (.vtp) and a time series index
// (.pvd). Pure C++, ASCII encoding, no libvtk.
#pragma once

#include <ostream>
#include <string>
#include <utility>
#include <vector>

#include "activefoam/run.h"

namespace activefoam {

// One snapshot as VTK XML PolyData: Points, Polys (connectivity/offsets), PointData `cell_id`,
// CellData (per triangle) `cell_id`, `spheroid` (the cell's label) and `pressure` (the cell's
// P_l, kPa), and FieldData TIME/STEP. Missing per-cell labels or pressures are written as 0.
// Throws std::invalid_argument when vertex_cell is neither empty nor one entry per point, or a
// triangle references a vertex out of range.
void writeVtp(std::ostream& os, const Snapshot& snap);

// A ParaView collection: one DataSet per (time, file) in the given order; file names are
// written as given (relative to the .pvd) and XML-escaped.
void writePvd(std::ostream& os, const std::vector<std::pair<double, std::string>>& time_and_file);

}  // namespace activefoam
