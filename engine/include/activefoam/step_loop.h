// The one loop that advances a Simulation over a stretch of time, shared by the scene drivers
// (runScene, prepareSpheroid, measureDoubletEquilibrium): step until a tick count, stopping early
// when cancelled, when a step fails, or when the caller has seen enough.
#pragma once

#include <atomic>
#include <cstdint>
#include <functional>
#include <string>

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

// The try that first halved the step from numerics.dt_s, kept until the schedule is back at
// dt_s: a run that fails at the floor names it, for its last step may have started at the floor
// (earlier steps halved it), and that step's own tries then say nothing of what started it
// (fig9's first failure: "after 0 halvings", the deciding try six steps earlier).
class HalvingEpisode {
 public:
  explicit HalvingEpisode(double dt_full_s) : dt_full_(dt_full_s) {}
  // Each step's report, and the clock after it (at the step's start when it failed).
  void see(const StepReport& r, double t_after_s);
  // Empty, or "; the step was first halved from numerics.dt_s = D s at t = T s by KIND: WHY".
  std::string note() const;

 private:
  double dt_full_;
  double t_ = -1;  // the step's start, s; < 0: the schedule is at dt_s
  std::string why_;
};

}  // namespace activefoam
