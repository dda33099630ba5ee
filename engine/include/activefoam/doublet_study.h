// The doublet as a measuring instrument (issue 6): two passive cells from a small gap, run to
// equilibrium, their contact angle averaged over the last stretch. The speed/accuracy study
// (bench/study_accuracy) and its quick version in the tests measure every numerical setting
// this way, so that both judge the same quantity.
#pragma once

#include <string>

#include "activefoam/spec.h"

namespace activefoam {

struct DoubletEquilibrium {
  double theta_c_deg = 0;       // mean over the window (the end value jitters with remeshing)
  double theta_c_end_deg = 0;   // at the end
  double volume_error_max = 0;  // largest |V − V*|/V* of any cell at any step
  double cg_iters_mean = 0;
  double wall_s = 0;
  double t_end_s = 0;
  long long steps = 0;
  std::string failure;  // empty, or the failure kind that stopped the run
  std::string reason;
};

// The doublet spec with the given numerics (cells passive, equal radii; α and the rest at their
// defaults), resolved.
SceneSpec doubletStudySpec(const NumericsParams& numerics);

// Runs `spec` (a doublet) for duration_s and averages θ_c every 5 s over the last window_s.
DoubletEquilibrium measureDoubletEquilibrium(const SceneSpec& spec, double duration_s = 500,
                                             double window_s = 100);

}  // namespace activefoam
