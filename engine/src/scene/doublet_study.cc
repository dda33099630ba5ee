#include "activefoam/doublet_study.h"

#include <algorithm>
#include <chrono>
#include <cmath>

#include "activefoam/observables.h"
#include "activefoam/simulation.h"
#include "activefoam/step_loop.h"

namespace activefoam {

SceneSpec doubletStudySpec(const NumericsParams& numerics, double pa_reduced, double k_factor) {
  SceneSpec s;
  s.scene = SceneKind::Doublet;
  s.cells.radius_gamma_k = 0;  // equal radii
  s.cells.p_a = pa_reduced * 2 * s.cells.gamma / s.cells.radius_mean_um;
  s.cells.k_contact *= k_factor;
  // The gap is left to its default, min(50 nm, 0.8 h0): h0 = √(w/k_AB) shrinks with stiffer
  // contacts (k_AB × 4 puts 50 nm outside it, and passive cells would never touch).
  s.numerics = numerics;
  return resolve(s);
}

DoubletEquilibrium measureDoubletEquilibrium(const SceneSpec& spec, double duration_s,
                                             double window_s) {
  Simulation sim(spec);
  DoubletEquilibrium o;
  const double dt = spec.numerics.dt_s;
  const auto t0 = std::chrono::steady_clock::now();
  const TimeStepper& clock = sim.stepper();  // in ticks: the adaptive schedule may halve steps
  const std::int64_t n = clock.ticksFor(duration_s);
  const std::int64_t window_from = clock.ticksFor(duration_s - window_s);
  double next_sample_t = 5;
  double sum = 0, iters = 0;
  int count = 0;
  const LoopResult loop = runSteps(sim, n, nullptr, [&](const StepReport& r) {
    if (!r.ok()) return false;
    iters += r.cg.iterations;
    for (int c = 0; c < sim.cells().numCells(); ++c)
      o.volume_error_max = std::max(o.volume_error_max, std::abs(sim.geometry().cell_volume[c] -
                                                                 sim.cells().target_volume[c]) /
                                                            sim.cells().target_volume[c]);
    if (sim.time() >= next_sample_t - 1e-9 * dt) {  // every 5 s (to within Δt)
      next_sample_t += 5;
      const double theta = doubletContactAngleDeg(sim.cells(), sim.contacts());
      o.theta_c_series_deg.push_back(theta);
      if (clock.ticks() >= window_from) {
        sum += theta;
        ++count;
      }
    }
    return true;
  });
  if (loop.end == LoopEnd::Failed) {
    o.failure = std::string(toString(loop.failed.failure));
    o.reason = loop.failed.reason;
  }
  o.wall_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  o.theta_c_deg = count ? sum / count : std::nan("");
  o.theta_c_end_deg = doubletContactAngleDeg(sim.cells(), sim.contacts());
  o.t_end_s = sim.time();
  o.steps = sim.steps();
  o.cg_iters_mean = sim.steps() ? iters / static_cast<double>(sim.steps()) : 0;
  return o;
}

}  // namespace activefoam
