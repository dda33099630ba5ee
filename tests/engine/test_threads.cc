// The engine's promise that a run is bit-identical for any thread count: whole runs (fusion,
// motile doublet) and single kernels at 1, 2 and 3 threads compared byte by byte. The scenes are
// small, so the tests shrink the work grain (setGrain) until every parallel path runs with
// many chunks; one test keeps the production grain on a scene large enough to split.
#include <cmath>
#include <cstring>
#include <thread>
#include <tuple>

#include <gtest/gtest.h>

#include "activefoam/contacts.h"
#include "activefoam/rng.h"
#include "activefoam/run.h"
#include "activefoam/spheroid.h"
#include "activefoam/step_guards.h"
#include "activefoam/threads.h"
#include "test_support.h"

using namespace activefoam;
using activefoam::testing::cellSpec;
using activefoam::testing::curveBits;
using activefoam::testing::jiggle;
using activefoam::testing::physicsColumns;
using activefoam::testing::studiesStep;

namespace {

// Threads and grain for one scope, restored after it.
struct Parallel {
  int saved_threads = threads();
  Grain saved_grain = grain();
  Parallel(int n, Grain g) {
    setThreads(n);
    setGrain(g);
  }
  ~Parallel() {
    setThreads(saved_threads);
    setGrain(saved_grain);
  }
};

constexpr Grain kFine{64, 0};  // every kernel parallel, reductions in 64-entry chunks

template <class M>
bool sameBits(const M& a, const M& b) {
  return a.size() == b.size() &&
         std::memcmp(a.data(), b.data(), sizeof(double) * static_cast<size_t>(a.size())) == 0;
}

bool sameBits(const std::vector<std::vector<double>>& a,
              const std::vector<std::vector<double>>& b) {
  if (a.size() != b.size()) return false;
  for (size_t i = 0; i < a.size(); ++i)
    if (a[i].size() != b[i].size() ||
        std::memcmp(a[i].data(), b[i].data(), sizeof(double) * a[i].size()) != 0)
      return false;
  return true;
}

SceneSpec fusion2x4() {
  return activefoam::testing::smallFusionSpec(/*seed=*/11, 4, 4, /*duration_s=*/20,
                                              /*sample_every_s=*/2);
}

SceneSpec motileDoublet() {
  SceneSpec s = cellSpec(1.0, 80);
  s.scene = SceneKind::Doublet;
  s.cells.p_a = 0.1;
  s.cells.radius_gamma_k = 37;
  s.duration_s = 20;
  s.sample_every_s = 2;
  s.snapshot_every_s = 0;
  EXPECT_TRUE(validate(s).empty());
  return resolve(s);
}

struct Run {
  std::vector<std::vector<double>> samples;
  RunSummary summary;
};

Run run(const SceneSpec& spec, int n, Grain g) {
  Parallel p(n, g);
  Run r;
  RunObserver obs;
  std::vector<Sample> samples;
  obs.on_sample = [&](const Sample& s) { samples.push_back(s); };
  r.summary = runScene(spec, obs);
  r.samples = physicsColumns(samples);
  return r;
}

void expectSameRuns(const SceneSpec& spec, Grain g) {
  const Run one = run(spec, 1, g);
  ASSERT_TRUE(one.summary.ok()) << one.summary.reason;
  ASSERT_GT(one.samples.size(), 5u);
  for (int n : {2, 3}) {
    const Run other = run(spec, n, g);
    ASSERT_TRUE(other.summary.ok()) << other.summary.reason;
    EXPECT_TRUE(sameBits(one.samples, other.samples)) << n << " threads";
    ASSERT_EQ(one.summary.final_values.size(), other.summary.final_values.size());
    for (size_t i = 0; i < one.summary.final_values.size(); ++i)
      EXPECT_EQ(std::memcmp(&one.summary.final_values[i].second,
                            &other.summary.final_values[i].second, sizeof(double)),
                0)
          << one.summary.final_values[i].first << ", " << n << " threads";
    EXPECT_EQ(curveBits(one.summary), curveBits(other.summary)) << n << " threads";
  }
}

// One application of each parallel kernel on the same state.
struct Kernels {
  Eigen::Matrix3Xd forces;
  double energy = 0;
  Eigen::VectorXd product;  // Γ v for a fixed v
  std::vector<double> contact_areas;
  std::vector<double> tri_contact_area, cell_contact_area;
  std::vector<std::array<double, 3>> pair_list;         // ta, tb, area of each pair, in list order
  std::vector<std::array<double, 11>> friction_blocks;  // i, j, and the block, lower triangle
  Eigen::Matrix3Xd after_step;  // positions after one step (CG solve included)
  int pairs = 0;
};

Kernels kernels(const SceneSpec& spec, const CellSet& cells, int n, Grain g) {
  Parallel p(n, g);
  Simulation sim(spec, cells);
  Kernels k;
  k.energy = sim.computeForces(k.forces);
  sim.prepareFriction();
  const Eigen::Index m = 3 * static_cast<Eigen::Index>(sim.cells().numVertices());
  Eigen::VectorXd v(m);
  for (Eigen::Index i = 0; i < m; ++i) v[i] = std::sin(0.37 * static_cast<double>(i));
  k.product.resize(m);
  sim.applyFriction(v.data(), k.product.data());
  k.contact_areas = sim.contacts().vertex_contact_area;
  k.tri_contact_area = sim.contacts().tri_contact_area;
  k.cell_contact_area = sim.contacts().cell_contact_area;
  for (const ContactPair& p : sim.contacts().pairs)
    k.pair_list.push_back({double(p.ta), double(p.tb), p.c.area});
  sim.forEachFrictionBlock([&](int i, int j, const Eigen::Matrix3d& b) {
    std::array<double, 11> e{double(i), double(j)};
    for (int q = 0; q < 9; ++q) e[2 + q] = b(q);
    k.friction_blocks.push_back(e);
  });
  k.pairs = static_cast<int>(sim.contacts().pairs.size());
  EXPECT_TRUE(sim.step().ok());
  k.after_step = sim.cells().x;
  return k;
}

void expectSameKernels(const SceneSpec& spec, const CellSet& cells, Grain g) {
  const Kernels a = kernels(spec, cells, 1, g), b = kernels(spec, cells, 3, g);
  EXPECT_GT(a.pairs, 0);
  EXPECT_EQ(a.pairs, b.pairs);
  EXPECT_TRUE(sameBits(a.forces, b.forces));
  EXPECT_EQ(std::memcmp(&a.energy, &b.energy, sizeof(double)), 0);
  EXPECT_TRUE(sameBits(a.product, b.product));
  EXPECT_TRUE(a.contact_areas == b.contact_areas);
  EXPECT_TRUE(a.tri_contact_area == b.tri_contact_area);
  EXPECT_TRUE(a.cell_contact_area == b.cell_contact_area);
  EXPECT_TRUE(a.pair_list == b.pair_list);  // the detection's list, in the same order
  EXPECT_GT(a.friction_blocks.size(), 0u);
  EXPECT_TRUE(a.friction_blocks == b.friction_blocks);  // pattern (rebuilt threaded) and values
  EXPECT_TRUE(sameBits(a.after_step, b.after_step));
}

}  // namespace

TEST(Threads, SetThreadsIsPerCallingThread) {
  const int before = threads();
  setThreads(3);
  EXPECT_EQ(threads(), 3);
  int other = 0;
  std::thread t([&] {
    setThreads(2);
    other = threads();
  });
  t.join();
  EXPECT_EQ(other, 2);
  EXPECT_EQ(threads(), 3);  // the worker's choice did not leak into this thread
  setThreads(0);
  EXPECT_EQ(threads(), 1);
  setThreads(before);
}

TEST(Threads, KernelsGiveTheSameBitsOnAFusionState) {
  const SceneSpec s = fusion2x4();
  CellSet cells;
  {
    Parallel p(1, kFine);
    cells = buildFusionCells(s, nullptr, {});
  }
  jiggle(cells, 0.05, 3);  // generic, with contacts
  expectSameKernels(s, cells, kFine);
}

TEST(Threads, KernelsGiveTheSameBitsAtTheProductionGrain) {
  // 64 cells of 320 triangles pressed into each other: 20 480 triangles and ~31 000 CG entries
  // (eight 4096-entry chunks), so CG and the per-cell force kernels run threaded.
  SceneSpec s = cellSpec(1.0, 320);
  s.scene = SceneKind::Doublet;  // contacts on
  // Neighbours start 2.6 µm into each other along x: vertices over 1 µm inside, which the
  // interpenetration guard rightly stops at its default 1 µm.
  s.numerics.max_penetration_um = 5;
  CellSet cells;
  const double r = 8.88;
  for (int k = 0; k < 64; ++k)
    cells.addCell(ellipsoidCell(r, 1.1, 320,
                                Vec3(1.9 * r * (k % 4), 1.9 * r * (k / 4 % 4), 1.9 * r * (k / 16))),
                  r);
  expectSameKernels(s, cells, Grain{});
}

// The remesh of cells in parallel, with the rescue and the rebuild at work on one of them (the
// cell the rescue cannot repair, tests/engine/data/locked-cell-rescue-refused.obj, among three
// plain cells): the same meshes for any thread count.
TEST(Threads, RemeshWithTheRescueAndTheRebuildIsBitIdenticalForAnyThreadCount) {
  const auto locked = activefoam::testing::readObjCell(std::string(ENGINE_TEST_DATA) +
                                                       "/locked-cell-rescue-refused.obj");
  SceneSpec s = cellSpec(1.0, 320);
  s.numerics.remesh_repair = RemeshRepair::RescueRebuild;
  s = resolve(s);
  CellSet cells;
  const double r = 8.88;
  for (int k = 0; k < 3; ++k) {
    TriMesh m = ellipsoidCell(r, 1.2, 320, Vec3(60.0 + 2.5 * r * k, 0, 0));
    m.v = Eigen::Matrix3Xd::Zero(3, m.x.cols());
    cells.addCell(m, r);
    if (k == 1) cells.addCell(locked.mesh, locked.radius);
  }
  std::vector<Eigen::Matrix3Xd> xs;
  for (const int n : {1, 2, 3}) {
    Parallel p(n, kFine);
    Simulation sim(s, cells);
    sim.remeshAll();
    EXPECT_EQ(sim.remeshRebuilds(), 1) << n;
    xs.push_back(sim.cells().x);
  }
  EXPECT_TRUE(sameBits(xs[0], xs[1]));
  EXPECT_TRUE(sameBits(xs[0], xs[2]));
}

// A cell pressed against its neighbour (tests/engine/data/pressed-pair-*.obj, a fig9 run's state
// before the remesh that failed it), with two plain cells: the simulation's remesh without
// numerics.remesh_keep_out_um puts a vertex past the interpenetration guard, with it no pair is
// beyond the guard and a collapse was refused; the same meshes for any thread count.
TEST(Threads, RemeshWithKeepOutKeepsThePressedCellOutAndIsBitIdenticalForAnyThreadCount) {
  const std::string data = ENGINE_TEST_DATA;
  const auto a = activefoam::testing::readObjCell(data + "/pressed-pair-A.obj");
  const auto b = activefoam::testing::readObjCell(data + "/pressed-pair-B.obj");
  SceneSpec s = fusion2x4();
  s.numerics.triangles_per_cell = 320;  // the run's (A_m and A_M scale with it)
  s.numerics.remesh_repair = RemeshRepair::RescueRebuild;
  CellSet cells;
  cells.addCell(a.mesh, a.radius);
  cells.addCell(b.mesh, b.radius);
  const double r = 8.88;
  for (int k = 0; k < 2; ++k) {
    TriMesh m = ellipsoidCell(r, 1.2, 320, Vec3(120.0 + 2.5 * r * k, 0, 0));
    m.v = Eigen::Matrix3Xd::Zero(3, m.x.cols());
    cells.addCell(m, r);
  }
  const double limit = s.numerics.max_penetration_um;
  PenetrationScratch scratch;
  {
    Simulation sim(s, cells);
    ASSERT_EQ(interpenetration(sim.cells(), sim.contacts(), limit, 0, scratch), "");
    sim.remeshAll();
    EXPECT_NE(interpenetration(sim.cells(), sim.contacts(), limit, 0, scratch), "")
        << "the remesh without keep_out pushes a vertex past the guard";
  }
  s.numerics.remesh_keep_out_um = s.numerics.max_penetration_um / 4;
  std::vector<Eigen::Matrix3Xd> xs;
  for (const int n : {1, 2, 3}) {
    Parallel p(n, kFine);
    Simulation sim(s, cells);
    sim.remeshAll();
    EXPECT_GE(sim.remeshKeptOut(), 1) << n;
    EXPECT_EQ(interpenetration(sim.cells(), sim.contacts(), limit, 0, scratch), "") << n;
    xs.push_back(sim.cells().x);
  }
  EXPECT_TRUE(sameBits(xs[0], xs[1]));
  EXPECT_TRUE(sameBits(xs[0], xs[2]));
}

TEST(Threads, FusionRunIsBitIdenticalForAnyThreadCount) {
  expectSameRuns(fusion2x4(), kFine);
}

// The incomplete-Cholesky factor is built and applied in one fixed order whatever the threads.
TEST(Threads, IncompleteCholeskyFusionRunIsBitIdenticalForAnyThreadCount) {
  SceneSpec s = fusion2x4();
  s.numerics.preconditioner = PreconditionerKind::IncompleteCholesky;
  expectSameRuns(s, kFine);
}

TEST(Threads, MotileDoubletRunIsBitIdenticalForAnyThreadCount) {
  expectSameRuns(motileDoublet(), kFine);
}

// ros2: two solves, contacts at the predicted state, the consistent stiffness' product.
TEST(Threads, Ros2MotileDoubletRunIsBitIdenticalForAnyThreadCount) {
  SceneSpec s = motileDoublet();
  s.numerics.integrator = IntegratorKind::Ros2;
  expectSameRuns(s, kFine);
}

// With the probes on: their columns too (the dissipation's products run the parallel kernels),
// and the MSRD by depth's curves and final values.
TEST(Threads, StudiesStepFusionRunIsBitIdenticalForAnyThreadCount) {
  SceneSpec s = studiesStep(fusion2x4());
  s.observe.rigid_motion = true;
  s.observe.dissipation = true;
  s.observe.msrd_by_depth = true;
  s.observe.shape = true;
  s.observe.torque = true;
  expectSameRuns(s, kFine);
}

// Every preset as it ships (its repairs, guard and polarities the defaults'), on the fusion.
TEST(Threads, EveryPresetsFusionRunIsBitIdenticalForAnyThreadCount) {
  for (const PresetInfo& p : fidelityPresets()) {
    SCOPED_TRACE(std::string(toString(p.preset)));
    SceneSpec s = fusion2x4();
    const SceneSpec plain;
    s.numerics = plain.numerics;
    s.numerics.triangles_per_cell = 80;  // small cells: fast enough for the sanitizer passes
    s.scene_params.polarity_from_preparation = plain.scene_params.polarity_from_preparation;
    applyPreset(s.numerics, p.preset);
    s.numerics.triangles_per_cell = 80;
    s.numerics.remesh_every_s.reset();
    s.numerics.dt_min_s.reset();
    s.duration_s = 12;
    ASSERT_TRUE(validate(s).empty()) << validate(s)[0].str();
    expectSameRuns(resolve(s), kFine);
  }
}

TEST(Threads, StudiesStepMotileDoubletRunIsBitIdenticalForAnyThreadCount) {
  expectSameRuns(studiesStep(motileDoublet()), kFine);
}

// The tension's stiffness in Γ (numerics.tension_implicit): its edge coupling, cell by cell.
TEST(Threads, ImplicitTensionMotileDoubletRunIsBitIdenticalForAnyThreadCount) {
  SceneSpec s = studiesStep(motileDoublet());
  s.numerics.tension_implicit = true;
  s.numerics.dt_s = 2;
  expectSameRuns(s, kFine);
}

// The adaptive time step at work (rejected tries, rollback, halved and regrown steps): the
// semi-implicit doublet at Δt = 0.1 s oscillates from t ≈ 28 s and is retried at 0.05 s.
TEST(Threads, AdaptiveRunWithRejectedStepsIsBitIdenticalForAnyThreadCount) {
  SceneSpec s = cellSpec(1.0, 320);
  s.scene = SceneKind::Doublet;
  s.numerics.integrator = IntegratorKind::SemiImplicit;
  s.duration_s = 36;
  s.sample_every_s = 2;
  s.snapshot_every_s = 0;
  s = resolve(s);
  const ::Run one = run(s, 1, kFine);
  ASSERT_GT(one.summary.steps_rejected, 0);
  EXPECT_LT(one.summary.dt_min_s, 0.1);
  expectSameRuns(s, kFine);
}

// The contact kernels split the pairs among parts that own whole cells: every side of every pair
// (its three vertices in one cell) is written by exactly one part, each part walks its pairs in
// pair order — so every vertex gets its pairs' shares in the order one thread would add them —
// and the parts carry about equal numbers of pair sides.
TEST(Threads, ContactPartitionOwnsEveryPairSideOnceInPairOrder) {
  const int cells = 12, tris_per_cell = 5;
  std::vector<int> tri_cell(cells * tris_per_cell);
  for (std::size_t t = 0; t < tri_cell.size(); ++t) tri_cell[t] = static_cast<int>(t) / 5;
  Rng rng(3, 1);
  std::vector<ContactPair> pairs;
  for (int q = 0; q < 400; ++q) {
    const int ta = static_cast<int>(rng.uniform() * 60), tb = static_cast<int>(rng.uniform() * 60);
    if (tri_cell[ta] != tri_cell[tb]) pairs.push_back({std::min(ta, tb), std::max(ta, tb), {}});
  }
  ASSERT_GT(pairs.size(), 300u);
  for (int parts : {1, 2, 3, 5, 12, 20}) {
    ContactPartition part;
    part.build(pairs, tri_cell, cells, parts);
    EXPECT_EQ(part.parts, parts);
    EXPECT_EQ(part.num_pairs, pairs.size());
    if (parts == 1) {
      EXPECT_TRUE(part.item.empty());  // one part walks every pair, both sides
      continue;
    }
    std::vector<int> owner_a(pairs.size(), -1), owner_b(pairs.size(), -1);
    std::vector<int> cell_owner(cells, -1);
    std::vector<std::int64_t> sides(parts, 0);
    for (int k = 0; k < parts; ++k) {
      std::int64_t last = -1;
      for (std::int64_t e = part.begin[k]; e < part.begin[k + 1]; ++e) {
        const auto q = static_cast<std::int64_t>(part.item[e] >> 2);
        const bool own_a = part.item[e] & 1, own_b = part.item[e] & 2;
        EXPECT_GT(q, last) << "part " << k << " is not in pair order";
        last = q;
        EXPECT_TRUE(own_a || own_b);
        for (auto [own, owner, t] :
             {std::tuple{own_a, &owner_a, pairs[q].ta}, std::tuple{own_b, &owner_b, pairs[q].tb}}) {
          if (!own) continue;
          EXPECT_EQ((*owner)[q], -1) << "pair " << q << " side written twice";
          (*owner)[q] = k;
          ++sides[k];
          int& co = cell_owner[tri_cell[t]];
          EXPECT_TRUE(co == -1 || co == k) << "cell " << tri_cell[t] << " in two parts";
          co = k;
        }
      }
    }
    for (std::size_t q = 0; q < pairs.size(); ++q)
      EXPECT_TRUE(owner_a[q] >= 0 && owner_b[q] >= 0) << "pair " << q << " has an unowned side";
    if (parts <= 3) {  // 12 cells of ~67 sides each can be split about evenly in up to 3 parts
      const double mean = 2.0 * pairs.size() / parts;
      for (int k = 0; k < parts; ++k)
        EXPECT_LT(std::abs(sides[k] - mean), 0.3 * mean) << parts << " parts, part " << k;
    }
  }
}
