#include "activefoam/step_loop.h"

namespace activefoam {

LoopResult runSteps(Simulation& sim, std::int64_t end_ticks, const std::atomic<bool>* cancel,
                    const std::function<bool(const StepReport&)>& on_step) {
  LoopResult out;
  while (sim.stepper().ticks() < end_ticks) {
    if (cancel && cancel->load(std::memory_order_relaxed)) {
      out.end = LoopEnd::Cancelled;
      return out;
    }
    StepReport r = sim.step();
    const bool go_on = on_step(r);
    if (!r.ok()) {
      out.end = LoopEnd::Failed;
      out.failed = std::move(r);
      return out;
    }
    if (!go_on) {
      out.end = LoopEnd::Stopped;
      return out;
    }
  }
  return out;
}

}  // namespace activefoam
