#include "activefoam/run.h"

#include <chrono>
#include <cmath>
#include <cstring>
#include <stdexcept>

#include "activefoam/observables.h"
#include "activefoam/simulation.h"

namespace activefoam {
namespace {

const std::vector<std::string> kCommon = {"t_s", "steps", "wall_s", "cg_iters_mean",
                                          "volume_error_max"};

// The scene's observables, aligned with sampleColumns() after the common five.
std::vector<std::pair<std::string, double>> sceneObservables(const Simulation& sim) {
  std::vector<std::pair<std::string, double>> out;
  switch (sim.spec().scene) {
    case SceneKind::Cell:
      out.emplace_back("aspect_ratio", aspectRatio(sim.cells(), 0));
      out.emplace_back("pressure_kpa", sim.pressure(0));
      out.emplace_back("laplace_pressure_kpa", 2 * sim.spec().cells.gamma / sim.cells().radius[0]);
      break;
    case SceneKind::Doublet: {
      out.emplace_back("contact_angle_deg", doubletContactAngleDeg(sim.cells(), sim.contacts()));
      double area = 0;
      for (const ContactPair& p : sim.contacts().pairs) area += p.c.area;
      out.emplace_back("contact_area_um2", area);
      out.emplace_back("contact_pairs", static_cast<double>(sim.contacts().pairs.size()));
      out.emplace_back("distance_um",
                       (sim.geometry().cell_centroid[1] - sim.geometry().cell_centroid[0]).norm());
      break;
    }
    case SceneKind::Spheroid: {
      const Geometry& g = sim.geometry();
      const int n = sim.cells().numCells();
      double vol = 0;
      Vec3 centre = Vec3::Zero();
      for (int c = 0; c < n; ++c) {
        vol += g.cell_volume[c];
        centre += g.cell_volume[c] * g.cell_centroid[c];
      }
      centre /= vol;
      double rg2 = 0;
      for (int c = 0; c < n; ++c)
        rg2 += g.cell_volume[c] * (g.cell_centroid[c] - centre).squaredNorm();
      out.emplace_back("radius_gyration_um", std::sqrt(rg2 / vol));
      out.emplace_back("shape_index_mean", meanShapeIndex(g));
      out.emplace_back("contact_pairs", static_cast<double>(sim.contacts().pairs.size()));
      break;
    }
    default:
      break;
  }
  return out;
}

Snapshot makeSnapshot(const Simulation& sim) {
  Snapshot s;
  s.t_s = sim.time();
  s.step = sim.steps();
  s.x = sim.cells().x;
  s.tri = sim.cells().tri;
  s.vertex_cell = sim.cells().vertex_cell;
  s.cell_label = sim.cells().label;
  for (int c = 0; c < sim.cells().numCells(); ++c) s.cell_pressure.push_back(sim.pressure(c));
  return s;
}

double maxVolumeError(const Simulation& sim) {
  double m = 0;
  const auto& cells = sim.cells();
  for (int c = 0; c < cells.numCells(); ++c)
    m = std::max(m, std::abs(sim.geometry().cell_volume[c] - cells.target_volume[c]) /
                        cells.target_volume[c]);
  return m;
}

}  // namespace

std::string_view toString(FailureKind k) {
  switch (k) {
    case FailureKind::None:
      return "none";
    case FailureKind::NonFinite:
      return "non-finite";
    case FailureKind::CgNotConverged:
      return "cg-not-converged";
    case FailureKind::InvertedTriangle:
      return "inverted-triangle";
    case FailureKind::VolumeDrift:
      return "volume-drift";
    case FailureKind::Interpenetration:
      return "interpenetration";
    case FailureKind::ContactOscillation:
      return "contact-oscillation";
    case FailureKind::Cancelled:
      return "cancelled";
  }
  return "unknown";
}

std::vector<std::string> sampleColumns(SceneKind scene) {
  std::vector<std::string> cols = kCommon;
  switch (scene) {
    case SceneKind::Cell:
      cols.insert(cols.end(), {"aspect_ratio", "pressure_kpa", "laplace_pressure_kpa"});
      break;
    case SceneKind::Doublet:
      cols.insert(cols.end(),
                  {"contact_angle_deg", "contact_area_um2", "contact_pairs", "distance_um"});
      break;
    case SceneKind::Spheroid:
      cols.insert(cols.end(), {"radius_gyration_um", "shape_index_mean", "contact_pairs"});
      break;
    default:
      break;
  }
  return cols;
}

RunSummary runScene(const SceneSpec& spec, const RunObserver& obs, const std::string* resume) {
  using Clock = std::chrono::steady_clock;
  const auto start = Clock::now();
  auto wall = [&] { return std::chrono::duration<double>(Clock::now() - start).count(); };

  Simulation sim(spec);
  RunSummary sum;
  const double dt = spec.numerics.dt_s;
  const std::int64_t total = std::llround(spec.duration_s / dt);
  const std::int64_t sample_every =
      std::max<std::int64_t>(1, std::llround(spec.sample_every_s / dt));
  const std::int64_t snap_every =
      spec.snapshot_every_s > 0
          ? std::max<std::int64_t>(1, std::llround(spec.snapshot_every_s / dt))
          : 0;
  // The loop's own state, carried through checkpoints so that a resumed run emits exactly the
  // samples an uninterrupted one would (wall-clock columns aside).
  struct Accumulators {
    double window_iters = 0, window_vol = 0, all_iters = 0, wall_before = 0, last_checkpoint_t = 0;
    std::int64_t window_steps = 0;
  } acc;
  double& window_iters = acc.window_iters;
  double& window_vol = acc.window_vol;
  double& all_iters = acc.all_iters;
  std::int64_t& window_steps = acc.window_steps;
  window_vol = maxVolumeError(sim);
  if (resume) {
    const std::string extra = sim.loadState(*resume);
    if (extra.size() != sizeof acc)
      throw std::invalid_argument("checkpoint: not written by runScene of this engine version");
    std::memcpy(&acc, extra.data(), sizeof acc);
  }
  const double wall_before = acc.wall_before;
  auto checkpoint = [&] {
    if (!obs.on_checkpoint) return;
    acc.wall_before = wall_before + wall();
    acc.last_checkpoint_t = sim.time();
    obs.on_checkpoint(sim.time(),
                      sim.saveState(std::string(reinterpret_cast<const char*>(&acc), sizeof acc)));
  };

  auto emitSample = [&] {
    if (!obs.on_sample) return;
    Sample s;
    s.values = {sim.time(), static_cast<double>(sim.steps()), wall(),
                window_steps ? window_iters / window_steps : 0.0, window_vol};
    for (const auto& [name, value] : sceneObservables(sim)) s.values.push_back(value);
    obs.on_sample(s);
    window_iters = 0;
    window_steps = 0;
    window_vol = maxVolumeError(sim);
  };
  if (!resume) {
    emitSample();
    if (snap_every && obs.on_snapshot) obs.on_snapshot(makeSnapshot(sim));
  }

  double last_progress = 0;
  while (sim.steps() < total) {
    if (obs.cancel && obs.cancel->load(std::memory_order_relaxed)) {
      sum.failure = FailureKind::Cancelled;
      sum.reason = "cancelled at t=" + std::to_string(sim.time()) + " s";
      checkpoint();
      break;
    }
    const StepReport r = sim.step();
    if (!r.ok()) {
      sum.failure = r.failure;
      sum.reason = r.reason;
      break;
    }
    window_iters += r.cg.iterations;
    all_iters += r.cg.iterations;
    ++window_steps;
    window_vol = std::max(window_vol, maxVolumeError(sim));
    if (sim.steps() % sample_every == 0) {
      emitSample();
      if (obs.checkpoint_every_s > 0 &&
          sim.time() - acc.last_checkpoint_t >= obs.checkpoint_every_s - 0.5 * dt)
        checkpoint();
    }
    if (snap_every && sim.steps() % snap_every == 0 && obs.on_snapshot)
      obs.on_snapshot(makeSnapshot(sim));
    if (obs.on_progress && wall() - last_progress > 1.0) {
      last_progress = wall();
      obs.on_progress(sim.time(), sim.steps());
    }
  }
  sum.t_s = sim.time();
  sum.steps = sim.steps();
  sum.wall_s = wall_before + wall();
  sum.cg_iters_mean = sim.steps() ? all_iters / sim.steps() : 0;
  sum.remesh_ops = sim.remeshOps();
  sum.final_values = sceneObservables(sim);
  sum.final_values.emplace_back("volume_error_max", maxVolumeError(sim));
  const PhaseTimes& pt = sim.phaseTimes();
  sum.phase_wall_s = {{"geometry", pt.geometry}, {"contacts", pt.contacts}, {"forces", pt.forces},
                      {"matrix", pt.matrix},     {"solve", pt.solve},       {"remesh", pt.remesh}};
  if (obs.on_progress) obs.on_progress(sim.time(), sim.steps());
  return sum;
}

}  // namespace activefoam
