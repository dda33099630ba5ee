// A stored snapshot (a SnapshotData message, zlib-compressed or not) as a VtkMesh: what `foam
// export` writes from GetSnapshot's chunks and foamd's HTTP `.vtp` route writes from its store,
// decoded one way. It lives with the wire contract, not in common/ (which knows nothing of proto):
// users link activefoam_proto, activefoam_vtk and zlib.
#pragma once

#include <zlib.h>

#include <string>

#include "activefoam/v1/job.pb.h"
#include "activefoam/vtk.h"

namespace activefoam {

// Fills `mesh` from snapshot `info` (its `bytes` is the uncompressed size) stored as `data`
// with `compression` ("" or "zlib"). Returns an error text naming the snapshot, empty on success.
inline std::string decodeSnapshot(const v1::SnapshotInfo& info, const std::string& compression,
                                  std::string data, VtkMesh& mesh) {
  const std::string name = "snapshot " + std::to_string(info.index());
  if (compression == "zlib") {
    std::string raw(static_cast<std::size_t>(info.bytes()), '\0');
    uLongf n = static_cast<uLongf>(raw.size());
    if (uncompress(reinterpret_cast<Bytef*>(raw.data()), &n,
                   reinterpret_cast<const Bytef*>(data.data()),
                   static_cast<uLong>(data.size())) != Z_OK ||
        n != raw.size())
      return name + ": damaged (zlib)";
    data = std::move(raw);
  } else if (!compression.empty()) {
    return name + ": unknown compression " + compression;
  }
  v1::SnapshotData sd;
  if (!sd.ParseFromString(data)) return name + ": not a SnapshotData message";
  if (sd.x_size() % 3 != 0 || sd.tri_size() % 3 != 0) return name + ": malformed coordinates";
  mesh = VtkMesh{};
  mesh.t_s = sd.t_s();
  mesh.step = sd.step();
  mesh.points.assign(sd.x().begin(), sd.x().end());
  for (int k = 0; k + 2 < sd.tri_size(); k += 3)
    mesh.tri.push_back({sd.tri(k), sd.tri(k + 1), sd.tri(k + 2)});
  mesh.vertex_cell.assign(sd.vertex_cell().begin(), sd.vertex_cell().end());
  mesh.cell_pressure.assign(sd.cell_pressure().begin(), sd.cell_pressure().end());
  mesh.cell_label.assign(sd.cell_label().begin(), sd.cell_label().end());
  return "";
}

}  // namespace activefoam
