// VTK XML PolyData / collection writers (see vtk.h).
#include "activefoam/vtk.h"

#include <algorithm>
#include <cctype>
#include <charconv>
#include <cmath>
#include <optional>
#include <stdexcept>
#include <string_view>
#include <system_error>

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

namespace {

// The text between <DataArray ... Name="name" ...> and </DataArray>, or nullopt.
std::optional<std::string_view> dataArray(std::string_view text, std::string_view name) {
  const std::string key = "Name=\"" + std::string(name) + "\"";
  std::size_t at = 0;
  while ((at = text.find("<DataArray", at)) != std::string_view::npos) {
    const std::size_t close = text.find('>', at);
    if (close == std::string_view::npos) return std::nullopt;
    if (text.substr(at, close - at).find(key) != std::string_view::npos) {
      const std::size_t end = text.find("</DataArray>", close);
      if (end == std::string_view::npos) return std::nullopt;
      return text.substr(close + 1, end - close - 1);
    }
    at = close;
  }
  return std::nullopt;
}

template <class T>
std::vector<T> numbers(std::string_view text, std::string_view name) {
  const auto body = dataArray(text, name);
  if (!body) throw std::invalid_argument("readVtp: no DataArray '" + std::string(name) + "'");
  std::vector<T> out;
  const char* p = body->data();
  const char* end = p + body->size();
  while (p < end) {
    while (p < end && std::isspace(static_cast<unsigned char>(*p))) ++p;
    if (p == end) break;
    T v{};
    const auto res = std::from_chars(p, end, v);
    if (res.ec != std::errc())
      throw std::invalid_argument("readVtp: malformed number in '" + std::string(name) + "'");
    out.push_back(v);
    p = res.ptr;
  }
  return out;
}

}  // namespace

VtkMesh readVtp(const std::string& text) {
  VtkMesh m;
  const auto time = numbers<double>(text, "TIME");
  const auto step = numbers<std::int64_t>(text, "STEP");
  if (time.size() != 1 || step.size() != 1)
    throw std::invalid_argument("readVtp: TIME and STEP must hold one value each");
  m.t_s = time[0];
  m.step = step[0];
  // Point and cell arrays share the name cell_id: the first is PointData's, as written.
  const std::size_t cells_at = text.find("<CellData");
  if (cells_at == std::string::npos) throw std::invalid_argument("readVtp: no CellData");
  const std::string_view all(text);
  m.points = numbers<double>(all, "Points");
  if (m.points.size() % 3 != 0) throw std::invalid_argument("readVtp: points are not triples");
  m.vertex_cell = numbers<int>(all.substr(0, cells_at), "cell_id");
  const auto conn = numbers<std::int64_t>(all, "connectivity");
  if (conn.size() % 3 != 0) throw std::invalid_argument("readVtp: polygons are not triangles");
  const std::size_t np = m.points.size() / 3;
  if (m.vertex_cell.size() != np)
    throw std::invalid_argument("readVtp: cell_id has " + std::to_string(m.vertex_cell.size()) +
                                " entries for " + std::to_string(np) + " points");
  for (std::size_t t = 0; t < conn.size(); t += 3) {
    std::array<int, 3> tri{};
    for (int k = 0; k < 3; ++k) {
      const std::int64_t v = conn[t + static_cast<std::size_t>(k)];
      if (v < 0 || static_cast<std::size_t>(v) >= np)
        throw std::invalid_argument("readVtp: triangle references vertex " + std::to_string(v));
      tri[static_cast<std::size_t>(k)] = static_cast<int>(v);
    }
    m.tri.push_back(tri);
  }
  const auto tri_cell = numbers<int>(all.substr(cells_at), "cell_id");
  const auto label = numbers<int>(all, "spheroid");
  const auto pressure = numbers<double>(all, "pressure");
  if (tri_cell.size() != m.tri.size() || label.size() != m.tri.size() ||
      pressure.size() != m.tri.size())
    throw std::invalid_argument("readVtp: per-triangle arrays do not match the triangles");
  int cells = 0;
  for (int c : m.vertex_cell) cells = std::max(cells, c + 1);
  m.cell_pressure.assign(static_cast<std::size_t>(cells), 0.0);
  m.cell_label.assign(static_cast<std::size_t>(cells), 0);
  for (std::size_t t = 0; t < m.tri.size(); ++t) {
    const int c = tri_cell[t];
    if (c < 0 || c >= cells) throw std::invalid_argument("readVtp: triangle cell id out of range");
    m.cell_pressure[static_cast<std::size_t>(c)] = pressure[t];
    m.cell_label[static_cast<std::size_t>(c)] = label[t];
  }
  return m;
}

}  // namespace activefoam
