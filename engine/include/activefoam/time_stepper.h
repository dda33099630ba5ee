// Who owns Δt: the step length, the adaptive schedule and the simulated time in integer ticks.
#pragma once

#include <cstdint>

namespace activefoam {

// The step length and simulated time. Time is counted in ticks of Δt/2^K, the smallest step the
// schedule may take (K: the halvings from numerics.dt_s down to numerics.dt_min_s), so that half
// steps add up exactly and samples fall on the same times as in a run that never halved:
// t = ticks · Δt/2^K is bit-identical to steps · Δt while no step was halved.
//
// Adaptive schedule: a step that fails is retried at half the length (level + 1), recursively, as
// long as the level stays ≤ K; after `wait` accepted steps at a level (4 at first), the next step
// is doubled again, but only where the time is a multiple of the doubled length, so a step never
// straddles a step of the spec's Δt (sample and remesh times stay where they were). Growth that
// fails again soon (within max(4 × wait, kRecent) steps) doubles the wait, up to kMaxWait: a Δt
// that keeps failing is tried geometrically less often, so little time is spent at it. kRecent
// covers the guards that need many steps to see a failure: the semi-implicit doublet at
// Δt = 0.1 s trips the oscillation guard ~20 steps after each growth, and without the window it
// spent 90 % of its steps at that unstable Δt. Twice that window without a failure halves the
// wait again.
class TimeStepper {
 public:
  static constexpr int kGrowAfter = 4;
  static constexpr int kMaxWait = 4096;
  static constexpr int kRecent = 64;
  static constexpr int kSaturated = 4 * kMaxWait;
  TimeStepper(double dt_s, double dt_min_s, bool adaptive);

  double dt() const { return level_dt_; }  // length of the next step, s
  double baseDt() const { return dt_; }    // numerics.dt_s
  double minDt() const;                    // the floor Δt/2^K
  int level() const { return level_; }
  int maxLevel() const { return max_level_; }
  bool adaptive() const { return adaptive_; }
  std::int64_t ticks() const { return ticks_; }
  std::int64_t ticksPerBaseStep() const { return std::int64_t{1} << max_level_; }
  std::int64_t stepTicks() const { return ticksPerBaseStep() >> level_; }
  // Ticks of a duration given in seconds, rounded to whole steps of the spec's Δt.
  std::int64_t ticksFor(double seconds) const;
  // Ticks of a period (sampling, snapshots, remeshing, a preparation's window): as ticksFor,
  // but at least one step of the spec's Δt. The adaptive schedule never steps across one, so
  // what happens every period happens at the same times whatever the schedule did.
  std::int64_t periodTicks(double seconds) const;
  double time() const { return timeAt(ticks_); }
  double timeAt(std::int64_t ticks) const { return static_cast<double>(ticks) * tick_s_; }
  std::int64_t steps() const { return steps_; }  // accepted steps

  bool canHalve() const { return adaptive_ && level_ < max_level_; }
  // The step just tried failed and was undone: the next one is half as long.
  void halve();
  // The step of length dt() was taken.
  void accept();

  // Everything that a checkpoint must carry to continue the same schedule.
  struct State {
    std::int64_t ticks = 0, steps = 0;
    std::int32_t level = 0, good = 0, wait = kGrowAfter, since_growth = kSaturated, calm = 0;
    std::int32_t unused = 0;  // no padding bytes in checkpoints
  };
  State state() const { return {ticks_, steps_, level_, good_, wait_, since_growth_, calm_, 0}; }
  int growthWait() const { return wait_; }
  void setState(const State& s);

 private:
  void setLevel(int level);
  std::int64_t baseSteps(double seconds) const;  // seconds in whole steps of Δt, rounded
  double dt_, tick_s_, level_dt_;
  int max_level_ = 0;
  bool adaptive_;
  std::int64_t ticks_ = 0, steps_ = 0;
  int level_ = 0, good_ = 0;
  int wait_ = kGrowAfter;          // good steps before the next growth
  int since_growth_ = kSaturated;  // accepted steps since the last growth (saturating)
  int calm_ = 0;                   // accepted steps since the last failure or relaxation
};

}  // namespace activefoam
