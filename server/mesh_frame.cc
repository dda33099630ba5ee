// The .mesh route's encoding (see mesh_frame.h).
#include "mesh_frame.h"

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <map>
#include <stdexcept>
#include <vector>

#include <nlohmann/json.hpp>

namespace activefoam::server {

// The arrays are copied as they lie in memory; a big-endian host would need byte swaps.
static_assert(std::endian::native == std::endian::little, "the .mesh route writes host order");

std::string encodeMeshFrame(const VtkMesh& mesh, int index) {
  if (mesh.points.size() % 3 != 0) throw std::invalid_argument("mesh: points not a multiple of 3");
  const std::size_t nv = mesh.points.size() / 3;
  const std::size_t nt = mesh.tri.size();
  if (!mesh.vertex_cell.empty() && mesh.vertex_cell.size() != nv)
    throw std::invalid_argument("mesh: vertex_cell has " + std::to_string(mesh.vertex_cell.size()) +
                                " entries for " + std::to_string(nv) + " vertices");
  auto cellOf = [&](std::size_t v) { return mesh.vertex_cell.empty() ? 0 : mesh.vertex_cell[v]; };

  // Cell ids need not be dense or sorted in the snapshot: rank them.
  std::map<int, std::size_t> rank;
  for (std::size_t v = 0; v < nv; ++v) {
    if (cellOf(v) < 0) throw std::invalid_argument("mesh: a negative cell id");
    rank.emplace(cellOf(v), 0);
  }
  std::vector<int> ids;
  for (auto& [id, r] : rank) {
    r = ids.size();
    ids.push_back(id);
  }
  const std::size_t nc = ids.size();

  // A counting sort by cell keeps each cell's own vertex and triangle order.
  std::vector<std::uint32_t> vstart(nc + 1, 0), tstart(nc + 1, 0);
  std::vector<std::size_t> vrank(nv);
  for (std::size_t v = 0; v < nv; ++v) ++vstart[(vrank[v] = rank[cellOf(v)]) + 1];
  std::vector<std::size_t> trank(nt);
  for (std::size_t t = 0; t < nt; ++t) {
    for (int k : mesh.tri[t])
      if (k < 0 || static_cast<std::size_t>(k) >= nv)
        throw std::invalid_argument("mesh: triangle " + std::to_string(t) + " has vertex " +
                                    std::to_string(k) + " of " + std::to_string(nv));
    ++tstart[(trank[t] = vrank[static_cast<std::size_t>(mesh.tri[t][0])]) + 1];
  }
  for (std::size_t c = 0; c < nc; ++c) {
    vstart[c + 1] += vstart[c];
    tstart[c + 1] += tstart[c];
  }
  std::vector<float> pos(3 * nv);
  std::vector<std::uint32_t> newv(nv);
  {
    std::vector<std::uint32_t> next(vstart.begin(), vstart.end() - 1);
    for (std::size_t v = 0; v < nv; ++v) {
      const std::uint32_t to = next[vrank[v]]++;
      newv[v] = to;
      for (int d = 0; d < 3; ++d) pos[3 * to + d] = static_cast<float>(mesh.points[3 * v + d]);
    }
  }
  std::vector<std::uint32_t> tri(3 * nt);
  {
    std::vector<std::uint32_t> next(tstart.begin(), tstart.end() - 1);
    for (std::size_t t = 0; t < nt; ++t) {
      const std::uint32_t to = next[trank[t]]++;
      for (int d = 0; d < 3; ++d)
        tri[3 * to + d] = newv[static_cast<std::size_t>(mesh.tri[t][static_cast<std::size_t>(d)])];
    }
  }

  double lo[3], hi[3];
  for (int d = 0; d < 3; ++d) {
    lo[d] = nv ? std::numeric_limits<double>::infinity() : 0;
    hi[d] = nv ? -std::numeric_limits<double>::infinity() : 0;
  }
  for (std::size_t v = 0; v < nv; ++v)
    for (int d = 0; d < 3; ++d) {
      lo[d] = std::min(lo[d], mesh.points[3 * v + d]);
      hi[d] = std::max(hi[d], mesh.points[3 * v + d]);
    }

  nlohmann::json h = {{"format", "activefoam-mesh/1"},
                      {"index", index},
                      {"t_s", mesh.t_s},
                      {"step", mesh.step},
                      {"vertices", nv},
                      {"triangles", nt},
                      {"cells", nc},
                      {"cell_id", ids},
                      {"vertex_start", vstart},
                      {"triangle_start", tstart},
                      {"bounds", {lo[0], lo[1], lo[2], hi[0], hi[1], hi[2]}}};
  std::vector<int> label(nc, 0);
  for (std::size_t c = 0; c < nc; ++c)
    if (static_cast<std::size_t>(ids[c]) < mesh.cell_label.size())
      label[c] = mesh.cell_label[static_cast<std::size_t>(ids[c])];
  h["spheroid"] = label;
  if (!mesh.cell_pressure.empty()) {
    nlohmann::json p = nlohmann::json::array();
    for (int id : ids) {
      const auto i = static_cast<std::size_t>(id);
      const double x = i < mesh.cell_pressure.size() ? mesh.cell_pressure[i] : 0.0;
      p.push_back(std::isfinite(x) ? nlohmann::json(x) : nlohmann::json(nullptr));
    }
    h["pressure_kPa"] = std::move(p);
  }
  // The offsets depend on the header's length, which depends on the offsets' digits: fix them
  // for a header long enough to hold any two offsets of its own size.
  h["positions_offset"] = 0;
  h["triangles_offset"] = 0;
  std::size_t header_len = h.dump().size() + 2 * 20;
  header_len += (4 - (8 + header_len) % 4) % 4;
  const std::size_t pos_off = 8 + header_len;
  const std::size_t tri_off = pos_off + 4 * pos.size();
  h["positions_offset"] = pos_off;
  h["triangles_offset"] = tri_off;
  std::string header = h.dump();
  header.resize(header_len, ' ');

  std::string out;
  out.reserve(tri_off + 4 * tri.size());
  out += "AFM1";
  const auto len = static_cast<std::uint32_t>(header_len);
  out.append(reinterpret_cast<const char*>(&len), 4);
  out += header;
  out.append(reinterpret_cast<const char*>(pos.data()), 4 * pos.size());
  out.append(reinterpret_cast<const char*>(tri.data()), 4 * tri.size());
  return out;
}

}  // namespace activefoam::server
