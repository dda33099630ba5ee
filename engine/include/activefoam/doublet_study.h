// The doublet as a measuring instrument: two passive cells from a small gap, run to
// equilibrium, their contact angle averaged over the last stretch. The speed/accuracy study
// and its quick version in the tests measure every numerical setting
// this way, so that both judge the same quantity.
#pragma once

#include <string>
#include <vector>

#include "activefoam/spec.h"

namespace activefoam {

struct DoubletEquilibrium {
  double theta_c_deg = 0;      // mean over the window (the end value jitters with remeshing)
  double theta_c_end_deg = 0;  // at the end
  // θ_c(t) every 5 s from t = 5 s (the approach to equilibrium: where settings differ most).
  std::vector<double> theta_c_series_deg;
  double volume_error_max = 0;  // largest |V − V*|/V* of any cell at any step
  double cg_iters_mean = 0;
  double wall_s = 0;
  double t_end_s = 0;
  long long steps = 0;
  std::string failure;  // empty, or the failure kind that stopped the run
  std::string reason;
};

// The doublet spec with the given numerics (equal radii; α and the rest at their defaults),
// resolved: passive cells unless pa_reduced = p_a r/2γ > 0, k_AB scaled by k_factor, the gap
// within the contact range h0 of that k_AB.
SceneSpec doubletStudySpec(const NumericsParams& numerics, double pa_reduced = 0,
                           double k_factor = 1);

// Runs `spec` (a doublet) for duration_s, records θ_c every 5 s and averages it over the last
// window_s.
// The defaults cover every setting of the study: with 80 triangles per cell the first contact
// (vertex to vertex across the gap) takes ~1000 s to open into the junction that 320 triangles
// reach in ~400 s (measured); both sit at their equilibrium from there on.
DoubletEquilibrium measureDoubletEquilibrium(const SceneSpec& spec, double duration_s = 1500,
                                             double window_s = 300);

}  // namespace activefoam
