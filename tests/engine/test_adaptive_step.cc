// The adaptive time step: rejected tries retried at half the step, rollback of the whole state,
// failures at the floor, and resuming a run whose step is halved.
#include <algorithm>
#include <cstring>
#include <functional>
#include <iostream>

#include <gtest/gtest.h>

#include "activefoam/step_guards.h"
#include "activefoam/step_loop.h"
#include "step_scenes.h"
#include "test_support.h"

using namespace activefoam;
using activefoam::testing::cellSpec;
using activefoam::testing::motileDoublet;
using activefoam::testing::physicsColumns;
using activefoam::testing::stretchedPair;

namespace {

// A guard that tests use to force failures: rejects a try when `when(t, dt)` says so, at the end
// of the step (after the move, the remesh and the detection: rollback must undo all of that).
class ForcedFailure : public StepGuard {
 public:
  using When = std::function<bool(double t, double dt)>;
  ForcedFailure(When when, Phase phase = Phase::Detected) : when_(std::move(when)), phase_(phase) {}
  std::string_view name() const override { return "forced"; }
  Phase phase() const override { return phase_; }
  std::optional<StepFailure> check(const GuardView& g) override {
    ++calls;
    if (!when_(g.t, g.dt)) return std::nullopt;
    ++failures;
    return StepFailure{FailureKind::InvertedTriangle, "forced by the test"};
  }
  int calls = 0, failures = 0;

 private:
  When when_;
  Phase phase_;
};

bool sameBits(const Eigen::Matrix3Xd& a, const Eigen::Matrix3Xd& b) {
  return a.size() == b.size() && std::memcmp(a.data(), b.data(), sizeof(double) * a.size()) == 0;
}

template <class T>
bool sameBits(const std::vector<T>& a, const std::vector<T>& b) {
  return a.size() == b.size() && std::memcmp(a.data(), b.data(), sizeof(T) * a.size()) == 0;
}

// Every piece of the cells' state, bit for bit.
void expectSameCells(const CellSet& a, const CellSet& b) {
  EXPECT_TRUE(sameBits(a.x, b.x)) << "positions";
  EXPECT_TRUE(sameBits(a.v, b.v)) << "velocities";
  EXPECT_TRUE(sameBits(a.tri, b.tri)) << "triangles";
  EXPECT_TRUE(sameBits(a.pi_integral, b.pi_integral)) << "PI integrals";
  EXPECT_TRUE(sameBits(a.polarity, b.polarity)) << "polarities";
}

}  // namespace

// Every try longer than 0.1 s is rejected: a run at Δt = 0.2 s then takes exactly the steps of a
// run at Δt = 0.1 s (growing back is tried every few steps and rejected again), and must end
// bit-identical to it: same positions, velocities, meshes (remeshing every 10 s happens inside
// rejected tries too), PI integrals and polarities (their random streams are keyed by accepted
// steps).
TEST(AdaptiveStep, RejectedStepsRetriedAsHalvesEqualARunAtTheSmallerStep) {
  SceneSpec coarse = motileDoublet(0.2), fine = motileDoublet(0.1);
  coarse.numerics.remesh_every_s = fine.numerics.remesh_every_s = 2;
  Simulation halved(coarse, stretchedPair(coarse));
  auto guard = std::make_unique<ForcedFailure>([](double, double dt) { return dt > 0.1; });
  ForcedFailure* forced = guard.get();
  halved.addGuard(std::move(guard));
  Simulation direct(fine, stretchedPair(fine));
  // The same guard list (the forced guard never fires here) keeps the two runs' work alike.
  direct.addGuard(std::make_unique<ForcedFailure>([](double, double) { return false; }));
  std::int64_t rejected = 0;
  while (halved.time() < 20 - 1e-9) {
    const StepReport r = halved.step();
    ASSERT_TRUE(r.ok()) << r.reason;
    EXPECT_EQ(r.dt, 0.1);
    rejected += r.rejected;
  }
  while (direct.time() < 20 - 1e-9) ASSERT_TRUE(direct.step().ok());
  EXPECT_EQ(halved.time(), direct.time());
  EXPECT_EQ(halved.steps(), direct.steps());
  EXPECT_EQ(halved.steps(), 200);
  EXPECT_EQ(rejected, halved.stepsRejected());
  EXPECT_EQ(rejected, forced->failures);
  // The first step, then regrowths after 4, 8, 16, 32, 64 steps at 0.1 s (each failing at once
  // doubles the wait).
  EXPECT_EQ(rejected, 6);
  EXPECT_GT(halved.remeshOps(), 0) << "the test must cover remeshing inside a rejected try";
  EXPECT_EQ(halved.remeshOps(), direct.remeshOps());
  expectSameCells(halved.cells(), direct.cells());
}

// Rollback restores the whole state: compared at the start of the retry (its first guard) with
// the state before the step, on a step whose rejected try remeshed every cell.
TEST(AdaptiveStep, RollbackRestoresEveryPieceOfState) {
  SceneSpec s = motileDoublet(0.2);
  s.numerics.remesh_every_s = 0.2;  // the first step ends with a remesh of the stretched cells
  Simulation sim(s, stretchedPair(s));
  const CellSet before = sim.cells();
  const Geometry geo_before = sim.geometry();
  const ContactList contacts_before = sim.contacts();
  const double t_before = sim.time();
  const std::int64_t steps_before = sim.steps(), remesh_before = sim.remeshOps();

  std::uint64_t tried_topology = 0;
  bool compared = false;
  // Phase Solved: called on every try before anything moves. On the retry (dt 0.1) the state
  // must be the one before the step.
  sim.addGuard(std::make_unique<ForcedFailure>(
      [&](double t, double dt) {
        if (dt < 0.2) {
          EXPECT_EQ(t, t_before);
          EXPECT_EQ(sim.time(), t_before);
          EXPECT_EQ(sim.steps(), steps_before);
          EXPECT_EQ(sim.remeshOps(), remesh_before);
          expectSameCells(sim.cells(), before);
          EXPECT_TRUE(sameBits(sim.geometry().tri_normal, geo_before.tri_normal));
          EXPECT_TRUE(sameBits(sim.geometry().cell_volume, geo_before.cell_volume));
          EXPECT_EQ(sim.contacts().pairs.size(), contacts_before.pairs.size());
          bool same_pairs = sim.contacts().pairs.size() == contacts_before.pairs.size();
          for (std::size_t k = 0; same_pairs && k < contacts_before.pairs.size(); ++k) {
            const ContactPair &a = sim.contacts().pairs[k], &b = contacts_before.pairs[k];
            same_pairs =
                a.ta == b.ta && a.tb == b.tb && a.c.area == b.c.area && a.c.normal == b.c.normal;
          }
          EXPECT_TRUE(same_pairs) << "contacts";
          EXPECT_TRUE(
              sameBits(sim.contacts().vertex_contact_area, contacts_before.vertex_contact_area));
          compared = true;
        }
        return false;
      },
      StepGuard::Phase::Solved));
  // Phase Detected: the first try (dt 0.2) is rejected after it moved, remeshed and detected.
  sim.addGuard(std::make_unique<ForcedFailure>([&](double, double dt) {
    if (dt < 0.2) return false;
    tried_topology = sim.cells().topology_version;
    EXPECT_GT(sim.remeshOps(), remesh_before);
    return true;
  }));
  const StepReport r = sim.step();
  ASSERT_TRUE(r.ok()) << r.reason;
  EXPECT_EQ(r.rejected, 1);
  EXPECT_EQ(r.dt, 0.1);
  EXPECT_TRUE(compared);
  EXPECT_NE(tried_topology, before.topology_version) << "the rejected try did not remesh";
}

TEST(AdaptiveStep, AFailurePersistingToTheFloorEndsTheStepWithItsKind) {
  SceneSpec s = motileDoublet(0.1);
  s.numerics.dt_min_s = 0.1 / 8;
  Simulation sim(s);
  ASSERT_TRUE(sim.step().ok());
  sim.addGuard(std::make_unique<ForcedFailure>([](double, double) { return true; }));
  const StepReport r = sim.step();
  EXPECT_EQ(r.failure, FailureKind::InvertedTriangle);
  EXPECT_EQ(r.rejected, 3);  // 0.1 → 0.05 → 0.025 → 0.0125, which fails too
  EXPECT_EQ(r.dt, 0.0125);
  EXPECT_EQ(r.rejected_kind, FailureKind::InvertedTriangle);
  EXPECT_EQ(r.rejected_reason, "forced by the test");
  EXPECT_EQ(sim.stepsRejected(), 3);
  EXPECT_NE(r.reason.find("forced by the test"), std::string::npos) << r.reason;
  EXPECT_NE(r.reason.find("numerics.dt_min_s"), std::string::npos) << r.reason;
  EXPECT_NE(r.reason.find("numerics.dt_s halved 3 times, 3 of them in this step"),
            std::string::npos)
      << r.reason;

  // Not adaptive: the first failure ends the step, nothing is retried.
  s.numerics.adaptive = false;
  Simulation fixed(s);
  fixed.addGuard(std::make_unique<ForcedFailure>([](double, double) { return true; }));
  const StepReport f = fixed.step();
  EXPECT_EQ(f.failure, FailureKind::InvertedTriangle);
  EXPECT_EQ(f.rejected, 0);
  EXPECT_EQ(f.dt, 0.1);
  EXPECT_EQ(f.reason, "forced by the test");
}

// A step that starts at the floor (an earlier step halved the schedule there) and fails: its
// message counts the schedule's halvings, not only its own (none), and the run's episode names
// the try that first halved the step from dt_s, which the failing step's tries never saw.
TEST(AdaptiveStep, AFailureAtTheFloorNamesTheTryThatFirstHalvedTheStep) {
  SceneSpec s = motileDoublet(0.1);
  s.numerics.dt_min_s = 0.1 / 8;
  Simulation sim(s);
  HalvingEpisode episode(0.1);
  StepReport r = sim.step();
  ASSERT_TRUE(r.ok());
  episode.see(r, sim.time());
  EXPECT_EQ(episode.note(), "");
  bool all = false;
  sim.addGuard(
      std::make_unique<ForcedFailure>([&](double, double dt) { return all || dt > 0.0125; }));
  const double t1 = sim.time();
  r = sim.step();  // 0.1 → 0.05 → 0.025 → 0.0125, accepted there
  ASSERT_TRUE(r.ok()) << r.reason;
  EXPECT_EQ(r.rejected, 3);
  episode.see(r, sim.time());
  all = true;
  r = sim.step();  // starts at the floor, fails there
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.rejected, 0);
  EXPECT_EQ(r.dt, 0.0125);
  EXPECT_NE(r.reason.find("numerics.dt_s halved 3 times, 0 of them in this step"),
            std::string::npos)
      << r.reason;
  episode.see(r, sim.time());
  EXPECT_EQ(episode.note(), "; the step was first halved from numerics.dt_s = 0.1 s at t = " +
                                formatNumber(t1) + " s by inverted-triangle: forced by the test");

  // Back at dt_s, the episode is over.
  StepReport back;
  back.dt = 0.1;
  episode.see(back, 1.0);
  EXPECT_EQ(episode.note(), "");
}

// A checkpoint taken while the schedule runs at a halved step (after a rejection, before Δt
// has grown back) resumes bit-identically.
TEST(AdaptiveStep, ResumeBetweenARejectionAndTheRegrowthIsBitIdentical) {
  // ros2 with the incomplete-Cholesky factor too: its factor, reused by the second stage, is
  // rebuilt by every try and every step, so no checkpoint needs it.
  struct Case {
    IntegratorKind kind;
    PreconditionerKind pre;
  };
  for (const Case c : {Case{IntegratorKind::ContactImplicit, PreconditionerKind::Jacobi},
                       Case{IntegratorKind::Ros2, PreconditionerKind::Jacobi},
                       Case{IntegratorKind::Ros2, PreconditionerKind::IncompleteCholesky}}) {
    SCOPED_TRACE(std::string(toString(c.kind)) + " " + std::string(toString(c.pre)));
    SceneSpec s = motileDoublet(0.2);
    s.numerics.integrator = c.kind;
    s.numerics.preconditioner = c.pre;
    // Rejects every try longer than 0.05 s between t = 3 and 6 s.
    auto when = [](double t, double dt) { return t >= 3 && t < 6 && dt > 0.05; };
    Simulation a(s);
    a.addGuard(std::make_unique<ForcedFailure>(when));
    std::string state;
    while (a.time() < 12 - 1e-9) {
      ASSERT_TRUE(a.step().ok());
      if (state.empty() && a.time() > 6 && a.stepper().level() > 0) state = a.saveState();
    }
    ASSERT_FALSE(state.empty());
    EXPECT_EQ(a.stepper().level(), 0) << "Δt grows back after the hard stretch";
    Simulation b(s);
    b.addGuard(std::make_unique<ForcedFailure>(when));
    b.loadState(state);
    EXPECT_GT(b.stepper().level(), 0);
    while (b.time() < 12 - 1e-9) ASSERT_TRUE(b.step().ok());
    EXPECT_EQ(a.time(), b.time());
    EXPECT_EQ(a.steps(), b.steps());
    EXPECT_EQ(a.stepsRejected(), b.stepsRejected());
    expectSameCells(a.cells(), b.cells());
  }
}

// A real instability: the semi-implicit scheme at the supplement's Δt = 0.1 s oscillates in the
// contact springs (Doublet.SemiImplicitIsUnstable...). With the adaptive step the run survives
// at a shorter step, samples report the rejections and the shortest step, and a resumed run
// repeats every sample.
TEST(AdaptiveStep, SemiImplicitDoubletSurvivesAndSamplesSayHow) {
  SceneSpec s = cellSpec(1.0, 320);  // oscillates from t ≈ 28 s without the adaptive step
  s.scene = SceneKind::Doublet;
  s.numerics.integrator = IntegratorKind::SemiImplicit;
  s.duration_s = 40;
  s.sample_every_s = 5;
  s.snapshot_every_s = 0;
  const auto cols = sampleColumns(s);
  const auto dt_min_col = std::find(cols.begin(), cols.end(), "dt_min_s") - cols.begin();
  const auto rejected_col = std::find(cols.begin(), cols.end(), "steps_rejected") - cols.begin();
  ASSERT_LT(rejected_col, static_cast<long>(cols.size()));

  std::vector<Sample> straight;
  std::vector<std::pair<double, std::string>> checkpoints;
  RunObserver obs;
  obs.on_sample = [&](const Sample& x) { straight.push_back(x); };
  obs.checkpoint_every_s = 5;
  obs.on_checkpoint = [&](double t, const std::string& st) { checkpoints.emplace_back(t, st); };
  const RunSummary a = runScene(s, obs);
  ASSERT_TRUE(a.ok()) << a.reason;
  EXPECT_GT(a.steps_rejected, 0);
  EXPECT_LT(a.dt_min_s, 0.1);
  double rejected = 0, dt_min = 1;
  for (const Sample& x : straight) {
    rejected += x.values[rejected_col];
    dt_min = std::min(dt_min, x.values[dt_min_col]);
  }
  EXPECT_EQ(rejected, static_cast<double>(a.steps_rejected));
  EXPECT_EQ(dt_min, a.dt_min_s);
  EXPECT_EQ(straight.front().values[dt_min_col], 0.1);  // t = 0: no step yet
  std::cout << "[ adaptive ] semi-implicit doublet at Δt = 0.1 s: " << a.steps_rejected
            << " rejected tries, shortest step " << a.dt_min_s << " s, " << a.steps
            << " steps in 40 s\n";

  // Resume from the checkpoint at t = 20 s.
  ASSERT_GE(checkpoints.size(), 4u);
  const auto& [t_ck, state] = checkpoints[3];
  ASSERT_EQ(t_ck, 20);
  std::vector<Sample> resumed;
  RunObserver obs2;
  obs2.on_sample = [&](const Sample& x) { resumed.push_back(x); };
  const RunSummary b = runScene(s, obs2, &state);
  ASSERT_TRUE(b.ok()) << b.reason;
  EXPECT_EQ(b.steps_rejected, a.steps_rejected);
  EXPECT_EQ(b.dt_min_s, a.dt_min_s);
  const std::vector<Sample> tail(straight.end() - static_cast<long>(resumed.size()),
                                 straight.end());
  EXPECT_EQ(physicsColumns(resumed), physicsColumns(tail));

  // Without the adaptive step the same run fails.
  s.numerics.adaptive = false;
  const RunSummary fixed = runScene(s, RunObserver{});
  EXPECT_EQ(fixed.failure, FailureKind::ContactOscillation) << fixed.reason;
  EXPECT_EQ(fixed.steps_rejected, 0);
}
