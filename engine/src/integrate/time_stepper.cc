#include "activefoam/time_stepper.h"

#include <algorithm>
#include <cmath>

namespace activefoam {

TimeStepper::TimeStepper(double dt_s, double dt_min_s, bool adaptive)
    : dt_(dt_s), adaptive_(adaptive) {
  // The deepest halving whose step is still ≥ dt_min (a tolerance of one part in 10⁹ so that
  // dt_min = Δt/64 written in decimal still allows the sixth halving). Non-adaptive runs never
  // halve, and their ticks are whole steps.
  if (adaptive_)
    while (max_level_ < 30 && std::ldexp(dt_, -(max_level_ + 1)) >= dt_min_s * (1 - 1e-9))
      ++max_level_;
  tick_s_ = std::ldexp(dt_, -max_level_);
  setLevel(0);
}

double TimeStepper::minDt() const {
  return std::ldexp(dt_, -max_level_);
}

std::int64_t TimeStepper::baseSteps(double seconds) const {
  return std::llround(seconds / dt_);
}

std::int64_t TimeStepper::ticksFor(double seconds) const {
  return baseSteps(seconds) * ticksPerBaseStep();
}

std::int64_t TimeStepper::periodTicks(double seconds) const {
  return std::max<std::int64_t>(1, baseSteps(seconds)) * ticksPerBaseStep();
}

void TimeStepper::setLevel(int level) {
  level_ = level;
  level_dt_ = std::ldexp(dt_, -level_);  // exact: a power of two
}

void TimeStepper::halve() {
  if (since_growth_ < std::max(4 * wait_, kRecent))  // grew too early
    wait_ = std::min(2 * wait_, kMaxWait);
  setLevel(level_ + 1);
  good_ = 0;
  calm_ = 0;
}

void TimeStepper::accept() {
  ticks_ += stepTicks();
  ++steps_;
  since_growth_ = std::min(since_growth_ + 1, kSaturated);
  if (++calm_ >= 2 * std::max(4 * wait_, kRecent)) {
    wait_ = std::max(wait_ / 2, kGrowAfter);
    calm_ = 0;
  }
  if (level_ > 0 && ++good_ >= wait_ && ticks_ % (2 * stepTicks()) == 0) {
    setLevel(level_ - 1);
    good_ = 0;
    since_growth_ = 0;
  }
}

void TimeStepper::setState(const State& s) {
  ticks_ = s.ticks;
  steps_ = s.steps;
  setLevel(std::clamp<int>(s.level, 0, max_level_));
  good_ = s.good;
  wait_ = std::clamp<int>(s.wait, kGrowAfter, kMaxWait);
  since_growth_ = std::clamp<int>(s.since_growth, 0, kSaturated);
  calm_ = std::max<int>(s.calm, 0);
}

}  // namespace activefoam
