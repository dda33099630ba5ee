#include "activefoam/step_loop.h"

#include <cmath>

#include "activefoam/spec.h"

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

void HalvingEpisode::see(const StepReport& r, double t_after_s) {
  const double full = dt_full_ * (1 - 1e-12);
  if (r.rejected > 0 && t_ < 0 && r.dt * std::ldexp(1.0, r.rejected) >= full) {
    t_ = t_after_s - (r.ok() ? r.dt : 0);
    why_ = std::string(toString(r.rejected_kind)) + ": " + r.rejected_reason;
  }
  if (r.ok() && r.dt >= full) t_ = -1;
}

std::string HalvingEpisode::note() const {
  if (t_ < 0) return "";
  return "; the step was first halved from numerics.dt_s = " + formatNumber(dt_full_) +
         " s at t = " + formatNumber(t_) + " s by " + why_;
}

}  // namespace activefoam
