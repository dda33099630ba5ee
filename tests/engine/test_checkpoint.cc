// Checkpoint and resume: a resumed run continues bit-identically.
#include <cstdint>
#include <cstring>

#include <gtest/gtest.h>

#include "test_support.h"

using namespace activefoam;
using activefoam::testing::bits;
using activefoam::testing::physicsColumns;

namespace {

SceneSpec doublet() {
  return activefoam::testing::doubletSpec(60, 5);
}

}  // namespace

TEST(Checkpoint, SimulationStateRoundTripsBitExactly) {
  const SceneSpec s = doublet();
  Simulation a(s);
  for (int k = 0; k < 200; ++k) ASSERT_TRUE(a.step().ok());
  const std::string state = a.saveState("extra");
  Simulation b(s);
  EXPECT_EQ(b.loadState(state), "extra");
  EXPECT_EQ(b.steps(), a.steps());
  for (int k = 0; k < 300; ++k) {
    ASSERT_TRUE(a.step().ok());
    ASSERT_TRUE(b.step().ok());
  }
  ASSERT_EQ(a.cells().x.size(), b.cells().x.size());
  EXPECT_EQ(
      std::memcmp(a.cells().x.data(), b.cells().x.data(), sizeof(double) * a.cells().x.size()), 0);
}

// With numerics.remesh_repair = rescue the checkpoint carries the count of rescued remeshes (the
// summary's proof that a run without any has the bits of a run without the key), and the resumed
// run goes on bit for bit; a state saved without the key is another spec's. (A doublet needs no
// rescue: the count is 0 here; the rescue itself is Remesh.ALockedCellIsRepairedByTheRescue's.)
// Likewise numerics.remesh_keep_out_um and its count of refused collapses (Remesh.KeepOutRefuses…).
namespace {

template <class T>
void expectCountRoundTrips(T NumericsParams::*key, T on,
                           std::int64_t (Simulation::*count)() const) {
  SceneSpec s = doublet();
  s.numerics.*key = on;
  Simulation a(s);
  for (int k = 0; k < 200; ++k) ASSERT_TRUE(a.step().ok());
  const std::string state = a.saveState();
  {
    SceneSpec plain = s;
    plain.numerics.*key = T{};
    Simulation p(plain);
    for (int k = 0; k < 200; ++k) ASSERT_TRUE(p.step().ok());
    EXPECT_EQ(p.saveState().size() + sizeof(std::int64_t),
              state.size() - (specFingerprint(s).size() - specFingerprint(plain).size()))
        << "the key adds its count, and nothing else, to the checkpoint";
    ASSERT_EQ((a.*count)(), 0);
    EXPECT_EQ(
        std::memcmp(a.cells().x.data(), p.cells().x.data(), sizeof(double) * a.cells().x.size()), 0)
        << "the key did nothing: the same bits as without it";
  }
  Simulation b(s);
  b.loadState(state);
  EXPECT_EQ((b.*count)(), (a.*count)());
  for (int k = 0; k < 100; ++k) {
    ASSERT_TRUE(a.step().ok());
    ASSERT_TRUE(b.step().ok());
  }
  EXPECT_EQ((b.*count)(), (a.*count)());
  ASSERT_EQ(a.cells().x.size(), b.cells().x.size());
  EXPECT_EQ(
      std::memcmp(a.cells().x.data(), b.cells().x.data(), sizeof(double) * a.cells().x.size()), 0);
  SceneSpec without = s;
  without.numerics.*key = T{};
  Simulation c(without);
  EXPECT_THROW(c.loadState(state), std::invalid_argument);
  EXPECT_THROW(b.loadState(c.saveState()), std::invalid_argument);
}

}  // namespace

TEST(Checkpoint, TheRemeshRescuesCountRoundTrips) {
  expectCountRoundTrips(&NumericsParams::remesh_repair, RemeshRepair::Rescue,
                        &Simulation::remeshRescues);
}

TEST(Checkpoint, TheRemeshKeptOutCountRoundTrips) {
  expectCountRoundTrips(&NumericsParams::remesh_keep_out_um, 0.75, &Simulation::remeshKeptOut);
}

TEST(Checkpoint, RejectsForeignOrDamagedState) {
  const SceneSpec s = doublet();
  Simulation a(s);
  const std::string state = a.saveState();
  SceneSpec other = s;
  other.cells.alpha = 0.5;
  Simulation b(other);
  EXPECT_THROW(b.loadState(state), std::invalid_argument);  // another spec
  Simulation c(s);
  EXPECT_THROW(c.loadState(state.substr(0, state.size() / 2)), std::invalid_argument);
  EXPECT_THROW(c.loadState("not a checkpoint"), std::invalid_argument);
  std::string flipped = state;
  flipped[3] ^= 1;
  EXPECT_THROW(c.loadState(flipped), std::invalid_argument);
}

// The figure studies' step (the consistent stiffness at Δt 1 s, ε_CG 1e-2, the overlap within
// prisms) on a motile fusion: cut mid-run and resumed, the same samples as straight through —
// the probes' columns included (the rigid motion's reference at t = 0 rides in the checkpoint) —
// and the same curves and final values (the MSRD by depth's samples ride in it too).
TEST(Checkpoint, StudiesStepFusionResumesWithTheSameSamples) {
  SceneSpec s = activefoam::testing::studiesStep(activefoam::testing::smallFusionSpec(
      /*seed=*/11, 4, 4, /*duration_s=*/30, /*sample_every_s=*/2));
  s.observe.rigid_motion = true;
  s.observe.dissipation = true;
  s.observe.msrd_by_depth = true;
  s.observe.shape = true;
  s.observe.torque = true;
  ASSERT_EQ(sampleColumns(s).back(), "torque_share_springs");

  std::vector<Sample> straight, first, second;
  RunObserver o1;
  o1.on_sample = [&](const Sample& x) { straight.push_back(x); };
  const RunSummary whole = runScene(s, o1);
  ASSERT_TRUE(whole.ok()) << whole.reason;

  std::string checkpoint;
  std::atomic<bool> cancel{false};
  RunObserver o2;
  o2.cancel = &cancel;
  o2.checkpoint_every_s = 1e9;  // only the one written on cancel
  o2.on_checkpoint = [&](double, const std::string& c) { checkpoint = c; };
  o2.on_sample = [&](const Sample& x) {
    first.push_back(x);
    if (x.values[0] >= 13) cancel = true;
  };
  ASSERT_EQ(runScene(s, o2).failure, FailureKind::Cancelled);
  ASSERT_FALSE(checkpoint.empty());

  RunObserver o3;
  o3.on_sample = [&](const Sample& x) { second.push_back(x); };
  const RunSummary rest = runScene(s, o3, &checkpoint);
  ASSERT_TRUE(rest.ok()) << rest.reason;
  first.insert(first.end(), second.begin(), second.end());
  EXPECT_EQ(bits(physicsColumns(first)), bits(physicsColumns(straight)));
  EXPECT_EQ(rest.steps, whole.steps);
  EXPECT_EQ(activefoam::testing::curveBits(rest), activefoam::testing::curveBits(whole));
  ASSERT_EQ(rest.curves.size(), 6u);
  EXPECT_FALSE(rest.curves[0].y.empty());  // msrd_surface
  ASSERT_EQ(rest.final_values.size(), whole.final_values.size());
  for (std::size_t i = 0; i < whole.final_values.size(); ++i) {
    if (whole.final_values[i].first.rfind("mixing_", 0) != 0) continue;
    EXPECT_EQ(
        std::memcmp(&rest.final_values[i].second, &whole.final_values[i].second, sizeof(double)), 0)
        << whole.final_values[i].first;
  }
  // The aggregate turned and moved, and the probes measured it after the resume as well.
  const std::size_t turn = sampleColumns(s).size() - 32;
  EXPECT_GT(straight.back().values[turn], 0);
  EXPECT_GT(second.back().values[turn + 1], 0);
}

TEST(Checkpoint, ResumedRunEmitsTheSameSamples) {
  const SceneSpec s = doublet();
  std::vector<Sample> straight;
  RunObserver o1;
  o1.on_sample = [&](const Sample& x) { straight.push_back(x); };
  ASSERT_TRUE(runScene(s, o1).ok());

  // Interrupted: cancel after the sample at t = 25 s, keeping every checkpoint (every 10 s and
  // the one written on cancel, mid-window).
  std::vector<Sample> first, second;
  std::vector<std::string> checkpoints;
  std::atomic<bool> cancel{false};
  RunObserver o2;
  o2.cancel = &cancel;
  o2.checkpoint_every_s = 10;
  o2.on_checkpoint = [&](double, const std::string& c) { checkpoints.push_back(c); };
  o2.on_sample = [&](const Sample& x) {
    first.push_back(x);
    if (x.values[0] >= 25) cancel = true;
  };
  const RunSummary cut = runScene(s, o2);
  ASSERT_EQ(cut.failure, FailureKind::Cancelled);
  ASSERT_GE(checkpoints.size(), 3u);  // t = 10, 20 and on cancel

  RunObserver o3;
  o3.on_sample = [&](const Sample& x) { second.push_back(x); };
  const RunSummary rest = runScene(s, o3, &checkpoints.back());
  ASSERT_TRUE(rest.ok()) << rest.reason;
  first.insert(first.end(), second.begin(), second.end());
  EXPECT_EQ(physicsColumns(first), physicsColumns(straight));
  EXPECT_EQ(rest.steps, 600);

  // Resuming from an earlier periodic checkpoint repeats the samples after it, identically.
  std::vector<Sample> from10;
  RunObserver o4;
  o4.on_sample = [&](const Sample& x) { from10.push_back(x); };
  ASSERT_TRUE(runScene(s, o4, &checkpoints.front()).ok());
  const auto tail = physicsColumns(straight);
  EXPECT_EQ(physicsColumns(from10),
            std::vector<std::vector<double>>(tail.end() - from10.size(), tail.end()));
  EXPECT_EQ(from10.front().values[0], 15.0);
}

// Every preset as it ships resumes bit for bit: a small fusion cancelled mid-run and resumed
// from its last checkpoint emits the uninterrupted run's samples.
TEST(Checkpoint, EveryPresetResumesBitForBit) {
  for (const PresetInfo& p : fidelityPresets()) {
    SCOPED_TRACE(std::string(toString(p.preset)));
    SceneSpec s = activefoam::testing::smallFusionSpec(5, 3, 4, 12, 2);
    const SceneSpec plain;
    s.numerics = plain.numerics;
    s.scene_params.polarity_from_preparation = plain.scene_params.polarity_from_preparation;
    applyPreset(s.numerics, p.preset);
    s.numerics.triangles_per_cell = 80;
    ASSERT_TRUE(validate(s).empty()) << validate(s)[0].str();
    s = resolve(s);
    std::vector<Sample> straight, first, second;
    RunObserver o1;
    o1.on_sample = [&](const Sample& x) { straight.push_back(x); };
    ASSERT_TRUE(runScene(s, o1).ok());
    std::vector<std::string> checkpoints;
    std::atomic<bool> cancel{false};
    RunObserver o2;
    o2.cancel = &cancel;
    o2.checkpoint_every_s = 4;
    o2.on_checkpoint = [&](double, const std::string& c) { checkpoints.push_back(c); };
    o2.on_sample = [&](const Sample& x) {
      first.push_back(x);
      if (x.values[0] >= 6) cancel = true;
    };
    ASSERT_EQ(runScene(s, o2).failure, FailureKind::Cancelled);
    ASSERT_FALSE(checkpoints.empty());
    RunObserver o3;
    o3.on_sample = [&](const Sample& x) { second.push_back(x); };
    ASSERT_TRUE(runScene(s, o3, &checkpoints.back()).ok());
    first.insert(first.end(), second.begin(), second.end());
    EXPECT_EQ(physicsColumns(first), physicsColumns(straight));
  }
}

// A checkpoint is sealed by a checksum: any flipped bit — in its header (magic, format, spec
// fingerprint, counters) or anywhere in its cells — is refused as damaged before anything of it
// is read, so no damaged state ever reaches the engine; a cut one likewise.
TEST(Checkpoint, EveryFlippedBitIsRefused) {
  const SceneSpec s = doublet();
  Simulation a(s);
  for (int k = 0; k < 20; ++k) ASSERT_TRUE(a.step().ok());
  const std::string state = a.saveState("extra");
  Simulation b(s);
  ASSERT_NO_THROW(b.loadState(state));
  const std::size_t header_bits = 8 * 256;  // magic, format, the fingerprint's start
  const std::size_t bits = 8 * state.size();
  std::size_t tried = 0;
  for (std::size_t bit = 0; bit < bits; bit += bit < header_bits ? 1 : 97) {
    std::string damaged = state;
    damaged[bit / 8] = static_cast<char>(damaged[bit / 8] ^ (1 << (bit % 8)));
    Simulation c(s);
    EXPECT_THROW(c.loadState(damaged), std::invalid_argument) << "bit " << bit;
    ++tried;
  }
  for (std::size_t bit = bits - 64; bit < bits; ++bit) {  // the seal itself
    std::string damaged = state;
    damaged[bit / 8] = static_cast<char>(damaged[bit / 8] ^ (1 << (bit % 8)));
    Simulation c(s);
    EXPECT_THROW(c.loadState(damaged), std::invalid_argument) << "bit " << bit;
  }
  EXPECT_GT(tried, header_bits);
  Simulation c(s);
  EXPECT_THROW(c.loadState(state.substr(0, state.size() - 1)), std::invalid_argument);
  try {
    std::string damaged = state;
    damaged[state.size() / 2] ^= 4;
    Simulation d(s);
    d.loadState(damaged);
    ADD_FAILURE() << "a damaged checkpoint was read";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("damaged"), std::string::npos) << e.what();
  }
}
