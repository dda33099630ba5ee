// The one loop that advances a Simulation over a stretch of time, shared by the scene drivers
// (runScene, prepareSpheroid, measureDoubletEquilibrium): step until a tick count, stopping early
// when cancelled, when a step fails, or when the caller has seen enough.
#pragma once

#include <atomic>
#include <cstdint>
#include <functional>

#include "activefoam/simulation.h"

namespace activefoam {

enum class LoopEnd {
  Reached,    // the simulation's clock reached the end
  Cancelled,  // `cancel` was set (polled before every step); the last step is complete
  Failed,     // a step failed: LoopResult::failed says how, the state is as it failed
  Stopped     // on_step returned false
};

struct LoopResult {
  LoopEnd end = LoopEnd::Reached;
  StepReport failed;  // the failed step's report (LoopEnd::Failed)
};

// Steps `sim` until its clock reaches `end_ticks` (TimeStepper ticks). `on_step` sees every
// step's report, failed ones included, before the loop acts on it; returning false after an
// accepted step stops the loop.
LoopResult runSteps(Simulation& sim, std::int64_t end_ticks, const std::atomic<bool>* cancel,
                    const std::function<bool(const StepReport&)>& on_step);

}  // namespace activefoam
