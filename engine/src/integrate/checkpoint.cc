// Checkpoints: a little-endian binary dump of the Simulation's dynamic state. Positions and
// velocities are stored bit-exactly, so a resumed run reproduces the uninterrupted one.
#include <cstring>
#include <sstream>
#include <stdexcept>
#include <type_traits>

#include "activefoam/checksum.h"
#include "activefoam/simulation.h"
#include "activefoam/spheroid.h"
#include "bytes.h"

namespace activefoam {
namespace {

using bytes::Reader;
using bytes::Writer;

constexpr char kMagic[8] = {'A', 'F', 'C', 'K', 'P', 'T', '0', '1'};
// 2: the adaptive step schedule; 3: polarity noise keyed by time; 4: sealed by a checksum, so
// that a damaged checkpoint is refused before anything of it is read.
constexpr std::uint32_t kFormat = 4;

// The cells, in the checkpoint's order (velocities right after positions when kept).
void writeCells(Writer& w, const CellSet& c, bool velocities) {
  w.mat(c.x);
  if (velocities) w.mat(c.v);
  w.vec(c.vertex_cell);
  w.vec(c.tri);
  w.vec(c.tri_cell);
  w.vec(c.cell_vertex_begin);
  w.vec(c.cell_tri_begin);
  w.vec(c.radius);
  w.vec(c.target_volume);
  w.vec(c.pi_integral);
  w.vec(c.polarity);
  w.vec(c.label);
}

// Throws std::invalid_argument("<what>: ...") when the arrays do not fit together.
CellSet readCells(Reader& r, bool velocities, const std::string& what) {
  CellSet c;
  c.x = r.mat();
  c.v = velocities ? r.mat() : Eigen::Matrix3Xd::Zero(3, c.x.cols());
  c.vertex_cell = r.vec<int>();
  c.tri = r.vec<Tri>();
  c.tri_cell = r.vec<int>();
  c.cell_vertex_begin = r.vec<int>();
  c.cell_tri_begin = r.vec<int>();
  c.radius = r.vec<double>();
  c.target_volume = r.vec<double>();
  c.pi_integral = r.vec<double>();
  c.polarity = r.vec<Vec3>();
  c.label = r.vec<int>();
  const auto nc = c.radius.size();
  const auto nv = static_cast<std::size_t>(c.x.cols());
  const bool consistent =
      c.v.cols() == c.x.cols() && c.vertex_cell.size() == nv && c.tri_cell.size() == c.tri.size() &&
      c.cell_vertex_begin.size() == nc + 1 && c.cell_tri_begin.size() == nc + 1 &&
      c.target_volume.size() == nc && c.pi_integral.size() == nc && c.polarity.size() == nc &&
      c.label.size() == nc && static_cast<std::size_t>(c.cell_vertex_begin.back()) == nv &&
      static_cast<std::size_t>(c.cell_tri_begin.back()) == c.tri.size();
  if (!consistent) throw std::invalid_argument(what + ": inconsistent cell data");
  for (const Tri& f : c.tri)
    for (int i : f)
      if (i < 0 || static_cast<std::size_t>(i) >= nv)
        throw std::invalid_argument(what + ": triangle index out of range");
  return c;
}

}  // namespace

std::string Simulation::saveState(const std::string& extra) const {
  Writer w;
  for (char c : kMagic) w.pod(c);
  w.pod(kFormat);
  w.str(specFingerprint(spec_));
  w.pod(stepper_.state());
  w.pod(remesh_ops_);
  // Only with the key (so that the checkpoints of runs without it are those of earlier versions;
  // the key is in the fingerprint, so the reader knows).
  if (spec_.numerics.remesh_repair != RemeshRepair::None) w.pod(remesh_rescues_);
  if (spec_.numerics.remesh_repair == RemeshRepair::RescueRebuild) w.pod(remesh_rebuilds_);
  if (spec_.numerics.remesh_keep_out_um > 0) w.pod(remesh_kept_out_);
  w.pod(steps_rejected_);
  std::vector<std::int64_t> counts;
  for (const auto& g : guards_) counts.push_back(g->count());
  w.vec(counts);
  writeCells(w, cells_, true);
  w.str(extra);
  return sealed(w.take());
}

std::string Simulation::loadState(const std::string& sealed_bytes) {
  if (sealed_bytes.compare(0, sizeof kMagic, kMagic, sizeof kMagic) != 0)
    throw std::invalid_argument("checkpoint: not an activefoam checkpoint");
  const auto body = unsealed(sealed_bytes);
  if (!body) {
    // An earlier format has no seal; anything else is damaged.
    Reader head(sealed_bytes);
    for (std::size_t i = 0; i < sizeof kMagic; ++i) head.pod<char>();
    if (sealed_bytes.size() >= sizeof kMagic + 4 && head.pod<std::uint32_t>() < kFormat)
      throw std::invalid_argument("checkpoint: format version not supported by this engine");
    throw std::invalid_argument("checkpoint: damaged (its checksum does not match its content)");
  }
  const std::string bytes(*body);
  Reader r(bytes);
  for (std::size_t i = 0; i < sizeof kMagic; ++i) r.pod<char>();
  if (r.pod<std::uint32_t>() != kFormat)
    throw std::invalid_argument("checkpoint: format version not supported by this engine");
  if (r.str() != specFingerprint(spec_))
    throw std::invalid_argument("checkpoint: written by a run of a different spec");
  const auto schedule = r.pod<TimeStepper::State>();
  const auto remesh_ops = r.pod<std::int64_t>();
  const auto rescues =
      spec_.numerics.remesh_repair != RemeshRepair::None ? r.pod<std::int64_t>() : 0;
  const auto rebuilds =
      spec_.numerics.remesh_repair == RemeshRepair::RescueRebuild ? r.pod<std::int64_t>() : 0;
  const auto kept_out = spec_.numerics.remesh_keep_out_um > 0 ? r.pod<std::int64_t>() : 0;
  const auto rejected = r.pod<std::int64_t>();
  const auto counts = r.vec<std::int64_t>();
  CellSet c = readCells(r, true, "checkpoint");
  std::string extra = r.str();
  if (!r.done() || c.numCells() != cells_.numCells() || counts.size() != guards_.size() ||
      schedule.level < 0 || schedule.level > stepper_.maxLevel() || schedule.ticks < 0)
    throw std::invalid_argument("checkpoint: inconsistent cell data");
  c.topology_version = cells_.topology_version + 1;
  cells_ = std::move(c);
  stepper_.setState(schedule);
  remesh_ops_ = remesh_ops;
  remesh_rescues_ = rescues;
  remesh_rebuilds_ = rebuilds;
  remesh_kept_out_ = kept_out;
  steps_rejected_ = rejected;
  for (std::size_t k = 0; k < counts.size(); ++k) guards_[k]->setCount(counts[k]);
  updateTopology(cells_, topo_);
  computeGeometry(cells_, geo_);
  detect();
  return extra;
}

std::string serializeCells(const CellSet& c) {
  Writer w;
  writeCells(w, c, false);
  return w.take();
}

CellSet deserializeCells(const std::string& bytes) {
  Reader r(bytes, "cells");
  CellSet c = readCells(r, false, "cells");
  if (!r.done()) throw std::invalid_argument("cells: trailing bytes");
  return c;
}

}  // namespace activefoam
