// How a step or a run failed. Below both the step (step_guards.h) and the scene driver
// (run.h's RunSummary), so that the integrator does not include the scene layer for it.
#pragma once

#include <string_view>

namespace activefoam {

enum class FailureKind {
  None,
  NonFinite,
  CgNotConverged,
  InvertedTriangle,
  VolumeDrift,
  Interpenetration,
  ContactOscillation,
  Cancelled,
  PreparationFailed,  // a spheroid's relaxation (fusion scene) failed
  StepError           // ros2's error estimate above numerics.max_step_error_um (rejections only)
};
std::string_view toString(FailureKind);

}  // namespace activefoam
