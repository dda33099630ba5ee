// VTK XML PolyData / collection writers (see vtk.h).
#include "activefoam/vtk.h"

#include <charconv>
#include <cmath>
#include <stdexcept>

namespace activefoam {
namespace {

std::string xmlEscape(const std::string& s) {
  std::string out;
  out.reserve(s.size());
  for (char c : s) {
    switch (c) {
      case '&':
        out += "&amp;";
        break;
      case '<':
        out += "&lt;";
        break;
      case '>':
        out += "&gt;";
        break;
      case '"':
        out += "&quot;";
        break;
      case '\'':
        out += "&apos;";
        break;
      default:
        out += c;
    }
  }
  return out;
}

// Shortest round-trip form. VTK's ASCII reader does not take "nan"/"inf"; write 0 for them (a
// failed step's snapshot).
std::string num(double v) {
  if (!std::isfinite(v)) return "0";
  char buf[64];
  const auto res = std::to_chars(buf, buf + sizeof buf, v);
  return std::string(buf, res.ptr);
}

// n values of item(i), `per_line` to a line, indented to sit inside a DataArray.
template <class F>
void writeList(std::ostream& os, std::size_t n, std::size_t per_line, F item) {
  for (std::size_t i = 0; i < n; ++i) {
    os << (i % per_line ? " " : "          ") << item(i);
    if (i % per_line == per_line - 1 || i + 1 == n) os << '\n';
  }
}

}  // namespace

void writeVtp(std::ostream& os, const VtkMesh& snap) {
  if (snap.points.size() % 3 != 0)
    throw std::invalid_argument("writeVtp: " + std::to_string(snap.points.size()) +
                                " coordinates are not whole points");
  const std::size_t np = snap.points.size() / 3;
  const std::size_t nt = snap.tri.size();
  if (!snap.vertex_cell.empty() && snap.vertex_cell.size() != np)
    throw std::invalid_argument("writeVtp: vertex_cell has " +
                                std::to_string(snap.vertex_cell.size()) + " entries for " +
                                std::to_string(np) + " points");
  for (std::size_t t = 0; t < nt; ++t)
    for (int v : snap.tri[t])
      if (v < 0 || static_cast<std::size_t>(v) >= np)
        throw std::invalid_argument("writeVtp: triangle " + std::to_string(t) +
                                    " references vertex " + std::to_string(v) + " of " +
                                    std::to_string(np));

  auto vertexCell = [&](std::size_t i) {
    return snap.vertex_cell.empty() ? 0 : snap.vertex_cell[i];
  };
  auto triCell = [&](std::size_t t) {
    return vertexCell(static_cast<std::size_t>(snap.tri[t][0]));
  };
  auto perCell = [](const auto& values, int cell, auto fallback) {
    return cell >= 0 && static_cast<std::size_t>(cell) < values.size()
               ? values[static_cast<std::size_t>(cell)]
               : fallback;
  };

  os << "<?xml version=\"1.0\"?>\n"
     << "<VTKFile type=\"PolyData\" version=\"1.0\" byte_order=\"LittleEndian\" "
        "header_type=\"UInt64\">\n"
     << "  <PolyData>\n"
     << "    <FieldData>\n"
     << "      <DataArray type=\"Float64\" Name=\"TIME\" NumberOfTuples=\"1\" format=\"ascii\">"
     << num(snap.t_s) << "</DataArray>\n"
     << "      <DataArray type=\"Int64\" Name=\"STEP\" NumberOfTuples=\"1\" format=\"ascii\">"
     << snap.step << "</DataArray>\n"
     << "    </FieldData>\n"
     << "    <Piece NumberOfPoints=\"" << np << "\" NumberOfVerts=\"0\" NumberOfLines=\"0\" "
     << "NumberOfStrips=\"0\" NumberOfPolys=\"" << nt << "\">\n";

  os << "      <PointData Scalars=\"cell_id\">\n"
     << "        <DataArray type=\"Int32\" Name=\"cell_id\" format=\"ascii\">\n";
  writeList(os, np, 16, vertexCell);
  os << "        </DataArray>\n"
     << "      </PointData>\n";

  os << "      <CellData Scalars=\"cell_id\">\n"
     << "        <DataArray type=\"Int32\" Name=\"cell_id\" format=\"ascii\">\n";
  writeList(os, nt, 16, triCell);
  os << "        </DataArray>\n"
     << "        <DataArray type=\"Int32\" Name=\"spheroid\" format=\"ascii\">\n";
  writeList(os, nt, 16, [&](std::size_t t) { return perCell(snap.cell_label, triCell(t), 0); });
  os << "        </DataArray>\n"
     << "        <DataArray type=\"Float64\" Name=\"pressure\" format=\"ascii\">\n";
  writeList(os, nt, 8,
            [&](std::size_t t) { return num(perCell(snap.cell_pressure, triCell(t), 0.0)); });
  os << "        </DataArray>\n"
     << "      </CellData>\n";

  os << "      <Points>\n"
     << "        <DataArray type=\"Float64\" Name=\"Points\" NumberOfComponents=\"3\" "
        "format=\"ascii\">\n";
  for (std::size_t i = 0; i < np; ++i)
    os << "          " << num(snap.points[3 * i]) << ' ' << num(snap.points[3 * i + 1]) << ' '
       << num(snap.points[3 * i + 2]) << '\n';
  os << "        </DataArray>\n"
     << "      </Points>\n";

  os << "      <Polys>\n"
     << "        <DataArray type=\"Int64\" Name=\"connectivity\" format=\"ascii\">\n";
  for (const auto& t : snap.tri) os << "          " << t[0] << ' ' << t[1] << ' ' << t[2] << '\n';
  os << "        </DataArray>\n"
     << "        <DataArray type=\"Int64\" Name=\"offsets\" format=\"ascii\">\n";
  writeList(os, nt, 16, [](std::size_t t) { return 3 * (t + 1); });
  os << "        </DataArray>\n"
     << "      </Polys>\n"
     << "    </Piece>\n"
     << "  </PolyData>\n"
     << "</VTKFile>\n";
}

void writePvd(std::ostream& os, const std::vector<std::pair<double, std::string>>& time_and_file) {
  os << "<?xml version=\"1.0\"?>\n"
     << "<VTKFile type=\"Collection\" version=\"0.1\" byte_order=\"LittleEndian\">\n"
     << "  <Collection>\n";
  for (const auto& [t, file] : time_and_file)
    os << "    <DataSet timestep=\"" << num(t) << "\" group=\"\" part=\"0\" file=\""
       << xmlEscape(file) << "\"/>\n";
  os << "  </Collection>\n"
     << "</VTKFile>\n";
}

}  // namespace activefoam
