#include "activefoam/run.h"

#include <array>
#include <chrono>
#include <cmath>
#include <cstring>
#include <limits>
#include <memory>
#include <optional>
#include <stdexcept>

#include "../integrate/bytes.h"
#include "activefoam/fusion_outcome.h"
#include "activefoam/observables.h"
#include "activefoam/probe.h"
#include "activefoam/simulation.h"
#include "activefoam/spheroid.h"
#include "activefoam/step_loop.h"

namespace activefoam {
namespace {

const std::vector<std::string> kCommon = {
    "t_s", "steps", "wall_s", "cg_iters_mean", "volume_error_max", "dt_min_s", "steps_rejected"};

// A fusion run's own history, carried through checkpoints: the θ(t), a(t) series for the fits,
// the contact history and the MSRD samples, and what the preparation reported.
struct FusionState {
  std::vector<double> t, theta, neck;
  std::vector<double> area;  // contact area between the spheroids, µm²
  ContactHistory contacts;
  MsrdTracker msrd;
  std::array<double, 6> prep{};  // relaxed_s, compact, Rg µm: spheroid A, then B
  double R_um = 0;               // mean volume-equivalent radius of the two spheroids

  std::string save() const {
    bytes::Writer w;
    w.vec(t);
    w.vec(theta);
    w.vec(neck);
    w.str(contacts.save());
    w.str(msrd.save());
    w.pod(prep);
    w.pod(R_um);
    w.vec(area);
    return w.take();
  }
  void restore(const std::string& data) {
    bytes::Reader r(data, "checkpoint");
    t = r.vec<double>();
    theta = r.vec<double>();
    neck = r.vec<double>();
    contacts.restore(r.str());
    msrd.restore(r.str());
    prep = r.pod<std::array<double, 6>>();
    R_um = r.pod<double>();
    // Checkpoints written before the outcome existed end here: their contact areas are unknown
    // (NaN reads as no contact, so such a run's outcome is decided by the samples after it).
    area = r.done() ? std::vector<double>(t.size(), std::nan("")) : r.vec<double>();
    if (!r.done() || theta.size() != t.size() || neck.size() != t.size() || area.size() != t.size())
      throw std::invalid_argument("checkpoint: inconsistent fusion history");
  }
};

// Mean over the two spheroids of the radius of a ball of their cells' total volume.
double spheroidRadius(const CellSet& cells) {
  double v[2] = {0, 0};
  for (int c = 0; c < cells.numCells(); ++c) v[cells.label[c] == 1] += cells.target_volume[c];
  return 0.5 * (std::cbrt(3 * v[0] / (4 * M_PI)) + std::cbrt(3 * v[1] / (4 * M_PI)));
}

// The aggregate's surface contact angle and GSI = cos θ_c (spheroid and fusion samples).
void addSurfaceAngle(const Simulation& sim, std::vector<std::pair<std::string, double>>& out) {
  const SurfaceContactAngle sca = surfaceContactAngle(sim.cells(), sim.contacts());
  const double nan = std::numeric_limits<double>::quiet_NaN();
  out.emplace_back("surface_contact_angle_deg", sca.ok ? sca.theta_deg : nan);
  out.emplace_back("gsi", sca.ok ? sca.gsi : nan);
}

// The scene's observables, aligned with sampleColumns() after the common columns.
std::vector<std::pair<std::string, double>> sceneObservables(const Simulation& sim,
                                                             const FusionState* fusion) {
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
      out.emplace_back("radius_gyration_um",
                       radiusOfGyration(sim.cells(), g.cell_volume, g.cell_centroid));
      out.emplace_back("shape_index_mean", meanShapeIndex(g));
      out.emplace_back("contact_pairs", static_cast<double>(sim.contacts().pairs.size()));
      addSurfaceAngle(sim, out);
      break;
    }
    case SceneKind::Fusion: {
      const FusionAngle fa = fusionAngle(sim.cells(), sim.contacts());
      const double nan = std::numeric_limits<double>::quiet_NaN();
      out.emplace_back("theta_deg", fa.ok ? fa.theta_deg : nan);
      out.emplace_back("neck_radius_um", fa.ok ? fa.neck_radius_um : nan);
      out.emplace_back("length_um", fa.ok ? fa.length_um : nan);
      out.emplace_back("distance_um", fa.ok ? fa.distance_um : nan);
      out.emplace_back("shape_index_mean", meanShapeIndex(sim.geometry()));
      out.emplace_back("unique_contacts_norm", fusion ? fusion->contacts.normalized() : nan);
      addSurfaceAngle(sim, out);
      out.emplace_back("contact_pairs", static_cast<double>(sim.contacts().pairs.size()));
      out.emplace_back("contact_area_ab_um2", spheroidContactArea(sim.cells(), sim.contacts()));
      break;
    }
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

std::string fitResultName(std::string_view model, std::string_view parameter) {
  const bool shared = parameter == "theta_eq_deg" || parameter == "theta0_deg";
  return shared && model != "eq1" ? std::string(model) + "_" + std::string(parameter)
                                  : std::string(parameter);
}

std::vector<std::string> sampleColumns(const SceneSpec& spec) {
  std::vector<std::string> cols = kCommon;
  switch (spec.scene) {
    case SceneKind::Cell:
      cols.insert(cols.end(), {"aspect_ratio", "pressure_kpa", "laplace_pressure_kpa"});
      break;
    case SceneKind::Doublet:
      cols.insert(cols.end(),
                  {"contact_angle_deg", "contact_area_um2", "contact_pairs", "distance_um"});
      break;
    case SceneKind::Spheroid:
      cols.insert(cols.end(), {"radius_gyration_um", "shape_index_mean", "contact_pairs",
                               "surface_contact_angle_deg", "gsi"});
      break;
    case SceneKind::Fusion:
      cols.insert(cols.end(),
                  {"theta_deg", "neck_radius_um", "length_um", "distance_um", "shape_index_mean",
                   "unique_contacts_norm", "surface_contact_angle_deg", "gsi", "contact_pairs",
                   "contact_area_ab_um2"});
      break;
  }
  const std::vector<std::string> probes = probeColumns(spec);
  cols.insert(cols.end(), probes.begin(), probes.end());
  return cols;
}

RunSummary runScene(const SceneSpec& spec, const RunObserver& obs, const std::string* resume) {
  using Clock = std::chrono::steady_clock;
  const auto start = Clock::now();
  auto wall = [&] { return std::chrono::duration<double>(Clock::now() - start).count(); };

  RunSummary sum;
  const bool fusion = spec.scene == SceneKind::Fusion;
  FusionState fs;
  std::unique_ptr<Simulation> simp;
  if (fusion && !resume) {
    PrepObserver po;
    po.on_log = obs.on_log;
    po.cancel = obs.cancel;
    std::optional<SpheroidCache> cache;
    if (!obs.spheroid_cache_dir.empty()) cache.emplace(obs.spheroid_cache_dir);
    std::vector<PreparedSpheroid> info;
    try {
      CellSet cells = buildFusionCells(spec, cache ? &*cache : nullptr, po, &info);
      simp = std::make_unique<Simulation>(spec, std::move(cells));
    } catch (const PrepFailed& e) {
      sum.failure = e.cancelled ? FailureKind::Cancelled : FailureKind::PreparationFailed;
      sum.reason = e.what();
      sum.wall_s = wall();
      return sum;
    }
    for (int k = 0; k < 2; ++k) {
      fs.prep[3 * k] = info[k].relaxed_s;
      fs.prep[3 * k + 1] = info[k].compact ? 1 : 0;
      fs.prep[3 * k + 2] = info[k].radius_gyration_um;
    }
    fs.R_um = spheroidRadius(simp->cells());
  } else if (fusion) {
    simp = std::make_unique<Simulation>(spec, placeholderCells(spec));
  } else {
    simp = std::make_unique<Simulation>(spec);
  }
  Simulation& sim = *simp;
  const std::vector<std::unique_ptr<Probe>> probes = makeProbes(spec);
  const TimeStepper& clock = sim.stepper();
  const double dt = spec.numerics.dt_s;
  // Sample, snapshot and end times in ticks (whole steps of the spec's Δt): the adaptive schedule
  // never steps across one, so they fall on the same times whatever it did.
  const std::int64_t total = clock.ticksFor(spec.duration_s);
  const std::int64_t sample_every = clock.periodTicks(spec.sample_every_s);
  const std::int64_t snap_every =
      spec.snapshot_every_s > 0 ? clock.periodTicks(spec.snapshot_every_s) : 0;
  // The loop's own state, carried through checkpoints so that a resumed run emits exactly the
  // samples an uninterrupted one would (wall-clock columns aside).
  struct Accumulators {
    double window_iters = 0, window_vol = 0, all_iters = 0, wall_before = 0, last_checkpoint_t = 0;
    std::int64_t window_steps = 0;
    double window_dt_min = 0, run_dt_min = 0;  // smallest step taken (0: none yet)
    std::int64_t window_rejected = 0;
  } acc;
  double& window_iters = acc.window_iters;
  double& window_vol = acc.window_vol;
  double& all_iters = acc.all_iters;
  std::int64_t& window_steps = acc.window_steps;
  window_vol = maxVolumeError(sim);
  // Probes that read the velocity solve see the tries of the steps that end on a sample.
  bool reads_solve = false;
  for (const auto& p : probes) reads_solve = reads_solve || p->readsSolve();
  if (reads_solve)
    sim.onStartSolve([&](const StartSolve& solve) {
      if ((clock.ticks() + clock.stepTicks()) % sample_every != 0) return;
      for (const auto& p : probes)
        if (p->readsSolve()) p->solved(solve);
    });
  if (resume) {
    const std::string extra = sim.loadState(*resume);
    bytes::Reader r(extra, "checkpoint");  // holds a reference: `extra` must outlive it
    acc = r.pod<Accumulators>();
    const std::string history = r.str();
    for (const auto& p : probes) p->restore(r.str());
    if (!r.done())
      throw std::invalid_argument("checkpoint: not written by runScene of this engine version");
    if (fusion) fs.restore(history);
  }
  const double wall_before = acc.wall_before;
  auto checkpoint = [&] {
    if (!obs.on_checkpoint) return;
    acc.wall_before = wall_before + wall();
    acc.last_checkpoint_t = sim.time();
    bytes::Writer w;
    w.pod(acc);
    w.str(fusion ? fs.save() : std::string());
    for (const auto& p : probes) w.str(p->save());
    obs.on_checkpoint(sim.time(), sim.saveState(w.take()));
  };

  auto emitSample = [&] {
    std::vector<std::pair<std::string, double>> values;
    if (fusion) {
      fs.contacts.add(sim.cells(), sim.contacts());
      fs.msrd.addSample(sim.time(), sim.cells(), sim.geometry(), sim.contacts());
      values = sceneObservables(sim, &fs);
      // sampleColumns' order: θ first, the neck radius second, the contact area A–B last.
      fs.t.push_back(sim.time());
      fs.theta.push_back(values[0].second);
      fs.neck.push_back(values[1].second);
      fs.area.push_back(values.back().second);
    }
    // Every sample, watched or not: a probe may keep what it saw first (the aggregate at t = 0).
    std::vector<double> probed;
    for (const auto& p : probes) p->sample(sim, probed);
    if (obs.on_sample) {
      if (!fusion) values = sceneObservables(sim, nullptr);
      Sample s;
      // Wall time of the whole run, earlier processes of a resumed one included.
      s.values = {sim.time(),
                  static_cast<double>(sim.steps()),
                  wall_before + wall(),
                  window_steps ? window_iters / window_steps : 0.0,
                  window_vol,
                  window_steps ? acc.window_dt_min : dt,
                  static_cast<double>(acc.window_rejected)};
      for (const auto& [name, value] : values) s.values.push_back(value);
      s.values.insert(s.values.end(), probed.begin(), probed.end());
      obs.on_sample(s);
    }
    window_iters = 0;
    window_steps = 0;
    window_vol = maxVolumeError(sim);
    acc.window_dt_min = 0;
    acc.window_rejected = 0;
  };
  if (!resume) {
    emitSample();
    if (snap_every && obs.on_snapshot) obs.on_snapshot(makeSnapshot(sim));
  }

  double last_progress = 0;
  auto progress = [&] {
    if (obs.on_progress) obs.on_progress(sim.time(), sim.steps(), sim.stepsRejected());
  };
  HalvingEpisode halving(dt);
  const LoopResult loop = runSteps(sim, total, obs.cancel, [&](const StepReport& r) {
    halving.see(r, sim.time());
    if (r.rejected > 0 && acc.window_rejected == 0 && obs.on_log)  // one line per sample
      obs.on_log("step rejected: " + std::string(toString(r.rejected_kind)) + ": " +
                 r.rejected_reason + "; retried at dt = " + formatNumber(r.dt) + " s (" +
                 std::to_string(r.rejected) + " halvings)");
    acc.window_rejected += r.rejected;
    acc.run_dt_min = acc.run_dt_min > 0 ? std::min(acc.run_dt_min, r.dt) : r.dt;
    if (!r.ok()) return false;
    window_iters += r.cg.iterations;
    all_iters += r.cg.iterations;
    ++window_steps;
    acc.window_dt_min = acc.window_dt_min > 0 ? std::min(acc.window_dt_min, r.dt) : r.dt;
    window_vol = std::max(window_vol, maxVolumeError(sim));
    if (clock.ticks() % sample_every == 0) {
      emitSample();
      if (obs.checkpoint_every_s > 0 &&
          sim.time() - acc.last_checkpoint_t >= obs.checkpoint_every_s - 0.5 * dt)
        checkpoint();
    }
    if (snap_every && clock.ticks() % snap_every == 0 && obs.on_snapshot)
      obs.on_snapshot(makeSnapshot(sim));
    if (obs.on_progress && wall() - last_progress > 1.0) {
      last_progress = wall();
      progress();
    }
    return true;
  });
  if (loop.end == LoopEnd::Cancelled) {
    sum.failure = FailureKind::Cancelled;
    sum.reason = "cancelled at t=" + std::to_string(sim.time()) + " s";
    checkpoint();
  } else if (loop.end == LoopEnd::Failed) {
    sum.failure = loop.failed.failure;
    sum.reason = loop.failed.reason;
    sum.reason += halving.note();
  }
  sum.t_s = sim.time();
  sum.steps = sim.steps();
  sum.wall_s = wall_before + wall();
  sum.cg_iters_mean = sim.steps() ? all_iters / sim.steps() : 0;
  sum.remesh_ops = sim.remeshOps();
  sum.remesh_rescues = sim.remeshRescues();
  sum.remesh_rebuilds = sim.remeshRebuilds();
  sum.remesh_kept_out = sim.remeshKeptOut();
  sum.steps_rejected = sim.stepsRejected();
  sum.dt_min_s = acc.run_dt_min > 0 ? acc.run_dt_min : dt;
  sum.final_values = sceneObservables(sim, fusion ? &fs : nullptr);
  sum.final_values.emplace_back("volume_error_max", maxVolumeError(sim));
  if (fusion) {
    const FusionTrajectory traj{fs.t, fs.theta, fs.neck, fs.area};
    const FusionClassification outcome = classifyFusion(traj, spec.cells.radius_mean_um);
    sum.outcome = std::string(toString(outcome.outcome));
    sum.outcome_why = outcome.why;
    sum.fits = fusionFits(traj, outcome, fs.R_um);
    const MsrdTracker::Mixing mix = fs.msrd.mixingTime(spec.cells.radius_mean_um);
    sum.final_values.emplace_back("mixing_time_s", mix.time_s);
    sum.final_values.emplace_back("mixing_reached", mix.reached ? 1 : 0);
    // The same with the aggregate's rigid turn taken out (MsrdTracker::msrdLessRotation): near
    // the jam a turning doublet passes r² with no cell changing its neighbours.
    const MsrdTracker::Mixing mix_lr = fs.msrd.mixingTimeLessRotation(spec.cells.radius_mean_um);
    sum.final_values.emplace_back("mixing_time_less_rotation_s", mix_lr.time_s);
    sum.final_values.emplace_back("mixing_less_rotation_reached", mix_lr.reached ? 1 : 0);
    const int last = fs.msrd.numSamples() - 1;
    sum.final_values.emplace_back("msrd_end_less_rotation_um2", fs.msrd.msrdLessRotation(last));
    sum.final_values.emplace_back("turn_end_deg", fs.msrd.turnDeg(last));
    sum.final_values.emplace_back("spheroid_radius_um", fs.R_um);
    const char* ab[2] = {"a", "b"};
    for (int k = 0; k < 2; ++k) {
      sum.final_values.emplace_back(std::string("prep_relaxed_s_") + ab[k], fs.prep[3 * k]);
      sum.final_values.emplace_back(std::string("prep_compact_") + ab[k], fs.prep[3 * k + 1]);
      sum.final_values.emplace_back(std::string("prep_radius_gyration_um_") + ab[k],
                                    fs.prep[3 * k + 2]);
    }
    for (int k = 1; k < fs.msrd.numSamples(); ++k) {
      const double m = fs.msrd.msrd(k);
      if (std::isfinite(m)) sum.msrd.emplace_back(fs.msrd.lagTime(k), m);
    }
  }
  for (const auto& p : probes) p->finish(sum);
  const PhaseTimes& pt = sim.phaseTimes();
  sum.phase_wall_s = {{"geometry", pt.geometry}, {"contacts", pt.contacts}, {"forces", pt.forces},
                      {"matrix", pt.matrix},     {"solve", pt.solve},       {"remesh", pt.remesh}};
  progress();
  return sum;
}

}  // namespace activefoam
