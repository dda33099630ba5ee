// Running a scene to its end: the engine's batch interface (used by foam-run and foamd).
#pragma once

#include <atomic>
#include <cstdint>
#include <functional>
#include <string>
#include <utility>
#include <vector>

#include <Eigen/Core>

#include "activefoam/failure_kind.h"
#include "activefoam/fits.h"
#include "activefoam/mesh.h"
#include "activefoam/spec.h"

namespace activefoam {

// One row of samples.csv. `values` is aligned with sampleColumns(spec).
struct Sample {
  std::vector<double> values;
};

// Column names of a run's samples, in order. The first seven are common to every scene:
// t_s, steps, wall_s, cg_iters_mean, volume_error_max, and of the adaptive time step dt_min_s
// (the shortest step taken since the last sample) and steps_rejected (tries undone and retried
// since the last sample); then the scene's observables; then the columns of the probes the
// spec's [observe] table asks for (probe.h).
std::vector<std::string> sampleColumns(const SceneSpec& spec);

// Every cell's surface at one time, packed (global vertex indices).
struct Snapshot {
  double t_s = 0;
  std::int64_t step = 0;
  Eigen::Matrix3Xd x;
  std::vector<Tri> tri;
  std::vector<int> vertex_cell;       // cell id of each vertex
  std::vector<double> cell_pressure;  // P_l, kPa
  std::vector<int> cell_label;        // spheroid label (0/1), 0 for single-spheroid scenes
};

struct RunSummary {
  FailureKind failure = FailureKind::None;  // None: ran to duration_s
  std::string reason;                       // one line, empty on success
  double t_s = 0;                           // simulated time reached
  std::int64_t steps = 0;
  double wall_s = 0;
  double cg_iters_mean = 0;
  std::int64_t remesh_ops = 0;  // splits + collapses + flips over the run
  // Cell remeshes that ran the rescue (numerics.remesh_repair): 0 means the bits of the run
  // without the key.
  std::int64_t remesh_rescues = 0;
  // Cell meshes rebuilt (numerics.remesh_repair = rescue-rebuild): 0 means the bits of the run
  // without the key.
  std::int64_t remesh_rebuilds = 0;
  // Collapses and rebuilds refused for entering a neighbour (numerics.remesh_keep_out_um): 0
  // means the bits of the run without the key.
  std::int64_t remesh_kept_out = 0;
  // Adaptive time step: tries undone and retried over the run, and the shortest step taken (on
  // failure: the shortest tried).
  std::int64_t steps_rejected = 0;
  double dt_min_s = 0;
  // Scene observables at the end, as (name, value) in a stable order, e.g. aspect_ratio.
  std::vector<std::pair<std::string, double>> final_values;
  // Wall time split by phase over the run, seconds: geometry, forces, matrix, solve, remesh.
  std::vector<std::pair<std::string, double>> phase_wall_s;
  // Fusion: how it ended (fused | arrested | separated | no-contact, see fusion_outcome.h) and
  // the numbers that decided it; the fits of θ(t) and a(t) over the samples ("eq1", "eq2",
  // "s1"; see fits.h: not ok, with the reason, unless fused or arrested); the MSRD curve (lag s,
  // µm²). Other scenes leave the outcome empty.
  std::string outcome;
  std::string outcome_why;
  std::vector<std::pair<std::string, FitResult>> fits;
  std::vector<std::pair<double, double>> msrd;
  // More curves the run ends with, by name, in a stable order: those of the probes the spec's
  // [observe] table asks for (probe.h), e.g. msrd_surface. Their final values are in
  // final_values.
  struct Curve {
    std::string name;
    std::vector<double> x, y;  // aligned
  };
  std::vector<Curve> curves;
  bool ok() const { return failure == FailureKind::None; }
};

struct RunObserver {
  std::function<void(const Sample&)> on_sample;
  std::function<void(const Snapshot&)> on_snapshot;
  // At most every ~1 s of wall time: time, accepted steps, steps rejected so far.
  std::function<void(double t_s, std::int64_t step, std::int64_t rejected)> on_progress;
  const std::atomic<bool>* cancel = nullptr;  // polled every step
  // Checkpoints: the complete run state as an opaque, versioned byte string, emitted right after
  // a sample at least every checkpoint_every_s of simulated time (0 = never) and when the run is
  // cancelled. Resuming from it (runScene's `resume`) continues bit-identically: the samples
  // after the checkpoint equal those of an uninterrupted run (the wall-clock column aside).
  double checkpoint_every_s = 0;
  std::function<void(double t_s, const std::string& state)> on_checkpoint;  // t_s: state's time
  // Fusion: where prepared spheroids are cached (empty: prepared for this run only), and one
  // line per preparation stage (prepared, loaded from the cache, compact after ... s).
  std::string spheroid_cache_dir;
  std::function<void(const std::string&)> on_log;
};

// The flat name of a fit parameter in results tables (foam-run's summary.json top level, the
// server's results): the parameter's own name, prefixed with the model where two models share
// it (eq2's theta_eq_deg and theta0_deg → eq2_theta_eq_deg, eq2_theta0_deg; Eq. 1 keeps them).
std::string fitResultName(std::string_view model, std::string_view parameter);

// Runs a resolved, valid spec (see resolve/validate in spec.h) to duration_s or to its first
// failure. Samples are emitted at t = 0 and every sample_every_s; snapshots likewise. With
// `resume` (a checkpoint of the same spec) the run continues from it and emits only what comes
// after; throws std::invalid_argument if the checkpoint is malformed or of another spec.
RunSummary runScene(const SceneSpec& spec, const RunObserver& observer,
                    const std::string* resume = nullptr);

}  // namespace activefoam
