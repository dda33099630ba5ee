// Probes ([observe]): the aggregate's rigid motion, the dissipation by term and the MSRD by depth,
// on states with known answers; a run's other columns keep their bits with probes on.
#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstring>
#include <limits>

#include <gtest/gtest.h>
#include <Eigen/Geometry>
#include <Eigen/SparseCholesky>

#include "activefoam/observables.h"
#include "activefoam/probe.h"
#include "activefoam/spheroid.h"
#include "activefoam/terms.h"
#include "test_support.h"

using namespace activefoam;
using activefoam::testing::bits;
using activefoam::testing::cellSpec;
using activefoam::testing::physicsColumns;
using activefoam::testing::smallFusionSpec;

namespace {

// Points carried as a body: turned by `deg` about `axis` through `pivot`, then moved by `shift`.
std::vector<Vec3> carried(const std::vector<Vec3>& p, double deg, const Vec3& axis,
                          const Vec3& pivot, const Vec3& shift) {
  const Eigen::Matrix3d r =
      Eigen::AngleAxisd(deg * M_PI / 180, axis.normalized()).toRotationMatrix();
  std::vector<Vec3> q;
  for (const Vec3& x : p) q.push_back(pivot + r * (x - pivot) + shift);
  return q;
}

Vec3 mean(const std::vector<Vec3>& p) {
  Vec3 m = Vec3::Zero();
  for (const Vec3& x : p) m += x;
  return m / static_cast<double>(p.size());
}

SceneSpec doublet() {
  return activefoam::testing::doubletSpec(6, 1);
}

struct Column {
  std::vector<std::string> names;
  std::vector<Sample> rows;
  double at(std::size_t row, const std::string& name) const {
    const auto it = std::find(names.begin(), names.end(), name);
    EXPECT_NE(it, names.end()) << name;
    return it == names.end() ? std::nan("") : rows.at(row).values.at(it - names.begin());
  }
};

Column runProbed(const SceneSpec& spec) {
  Column c;
  c.names = sampleColumns(spec);
  RunObserver obs;
  obs.on_sample = [&](const Sample& s) {
    EXPECT_EQ(s.values.size(), c.names.size());
    c.rows.push_back(s);
  };
  const RunSummary sum = runScene(spec, obs);
  EXPECT_TRUE(sum.ok()) << sum.reason;
  return c;
}

double total(const Dissipation& d) {
  return d.medium + d.cortex + d.friction_t + d.friction_n + d.springs;
}

}  // namespace

// Kabsch on a known answer: a cloud turned by 37° about a tilted axis through an arbitrary point
// and moved gives back the rotation, its angle and the distance its mean moved.
TEST(Probes, BestRotationRecoversAKnownTurnAboutAnyAxis) {
  Rng rng(7, 1);
  std::vector<Vec3> p(9);
  for (Vec3& x : p) x = 6 * Vec3(rng.normal(), rng.normal(), rng.normal());
  const Vec3 axis(0.3, -0.5, 0.81), pivot(4, -2, 7), shift(1.5, -2, 0.7);
  for (double deg : {0.0, 0.5, 37.0, 150.0}) {
    const std::vector<Vec3> q = carried(p, deg, axis, pivot, shift);
    const Eigen::Matrix3d want =
        Eigen::AngleAxisd(deg * M_PI / 180, axis.normalized()).toRotationMatrix();
    EXPECT_LT((bestRotation(p, q) - want).norm(), 1e-12) << deg;
    const RigidMotion m = rigidMotion(p, q);
    EXPECT_NEAR(m.turn_deg, deg, deg < 1 ? 1e-5 : 1e-9) << deg;
    EXPECT_NEAR(m.drift_um, (mean(q) - mean(p)).norm(), 1e-12) << deg;
  }
  // Turned about its own mean, the cloud's mean moves by the shift alone.
  EXPECT_NEAR(rigidMotion(p, carried(p, 37, axis, mean(p), shift)).drift_um, shift.norm(), 1e-12);
  EXPECT_THROW(bestRotation(p, std::vector<Vec3>(3, Vec3::Zero())), std::invalid_argument);
  EXPECT_THROW(rigidMotion({}, {}), std::invalid_argument);
}

// Two cells (a 2 × 1 doublet): no two points show a turn about their own line, so the answer is
// the smallest rotation that turns the line as it turned — its angle, not 180° about the line.
TEST(Probes, BestRotationOfTwoPointsIsTheLinesOwnTurn) {
  const std::vector<Vec3> p = {Vec3(1, 2, 3), Vec3(9, -1, 4)};
  const Vec3 across = (p[1] - p[0]).cross(Vec3(0.2, 0.9, -0.4)).normalized();
  for (double deg : {0.0, 0.3, 1.2, 37.0, 150.0}) {
    const Eigen::Matrix3d turn = Eigen::AngleAxisd(deg * M_PI / 180, across).toRotationMatrix();
    std::vector<Vec3> q;
    for (const Vec3& x : p) q.push_back(turn * (x - mean(p)) + Vec3(0.5, 0, -2));
    const Eigen::Matrix3d r = bestRotation(p, q);
    EXPECT_LT((r - turn).norm(), 1e-9) << deg;
    EXPECT_NEAR(rigidMotion(p, q).turn_deg, deg, 1e-6) << deg;
  }
  EXPECT_LT((bestRotation(p, p) - Eigen::Matrix3d::Identity()).norm(), 1e-12);
}

// The probe on a spheroid's cells, turned and moved as a body after its first sample: the angle
// and the distance of the cells' volume centroids; its reference survives a checkpoint.
TEST(Probes, RigidMotionOfASpheroidTurnedAndMovedAsABody) {
  SceneSpec s = cellSpec(1.0, 80);
  s.scene = SceneKind::Spheroid;
  s.scene_params.n_cells = 5;
  s.observe.rigid_motion = true;
  s = resolve(s);
  Simulation sim(s);
  auto probes = makeProbes(s);
  ASSERT_EQ(probes.size(), 1u);
  ASSERT_EQ(probes[0]->columns(), (std::vector<std::string>{"rigid_turn_deg", "rigid_drift_um"}));
  std::vector<double> out;
  probes[0]->sample(sim, out);
  EXPECT_EQ(out, (std::vector<double>{0.0, 0.0}));

  const std::vector<Vec3> before = sim.geometry().cell_centroid;
  const Vec3 axis(-0.6, 0.2, 0.77), pivot(3, -1, 2), shift(0.4, 1.1, -0.3);
  const Eigen::Matrix3d r =
      Eigen::AngleAxisd(23 * M_PI / 180, axis.normalized()).toRotationMatrix();
  Eigen::Matrix3Xd x = sim.cells().x;
  for (Eigen::Index i = 0; i < x.cols(); ++i)
    x.col(i) = pivot + r * (Vec3(x.col(i)) - pivot) + shift;
  sim.setPositions(x);
  const Vec3 moved = pivot + r * (mean(before) - pivot) + shift;
  out.clear();
  probes[0]->sample(sim, out);
  ASSERT_EQ(out.size(), 2u);
  EXPECT_NEAR(out[0], 23.0, 1e-8);
  EXPECT_NEAR(out[1], (moved - mean(before)).norm(), 1e-9);

  auto restored = makeProbes(s);
  restored[0]->restore(probes[0]->save());
  std::vector<double> again;
  restored[0]->sample(sim, again);
  EXPECT_EQ(again, out);
  EXPECT_THROW(restored[0]->restore("xx"), std::invalid_argument);
}

// Where medium drag is the only friction, Γ v = F solved exactly: its dissipation is the power of
// the forces, and no other term reports any.
TEST(Probes, MediumDragAloneDissipatesThePowerOfTheForces) {
  SceneSpec s = resolve(cellSpec(1.3, 320));
  Simulation sim(s);
  Eigen::Matrix3Xd f;
  sim.computeForces(f);
  Topology topo;
  updateTopology(sim.cells(), topo);
  const StepContext ctx{sim.cells(), sim.geometry(), topo, 0.1, 0.0, nullptr, 0.0};
  ForceTerms terms;
  terms.push_back(std::make_unique<MediumDrag>(s.cells));
  FrictionOperator op;
  op.reset(sim.cells().numVertices(), sim.cells().topology_version);
  terms[0]->addFriction(ctx, op);
  const SpMat gamma = op.assembled();
  const Eigen::Map<const Eigen::VectorXd> b(f.data(), f.size());
  const Eigen::VectorXd v = Eigen::SimplicialLDLT<SpMat>(gamma).solve(b);
  ASSERT_LT((gamma * v - b).norm(), 1e-12 * b.norm());
  const Dissipation d = dissipation({ctx, f, v, terms, op});
  ASSERT_GT(d.forces, 0);
  EXPECT_NEAR(d.medium, d.forces, 1e-12 * d.forces);
  EXPECT_EQ(d.cortex, 0);
  EXPECT_EQ(d.friction_t + d.friction_n + d.springs + d.active, 0);
}

// A cell relaxing from an ellipsoid: medium drag and the cortex viscosity take the forces'
// power between them (to the CG tolerance), no contact term reports any, and t = 0 has no step.
TEST(Probes, RelaxingCellDissipatesThroughMediumAndCortex) {
  SceneSpec s = cellSpec(1.3, 320);
  s.duration_s = 4;
  s.sample_every_s = 1;
  s.snapshot_every_s = 0;
  s.numerics.cg_tol = 1e-10;
  s.observe.dissipation = true;
  const Column c = runProbed(resolve(s));
  ASSERT_EQ(c.rows.size(), 5u);
  EXPECT_TRUE(std::isnan(c.at(0, "diss_medium_nw")));
  EXPECT_TRUE(std::isnan(c.at(0, "power_forces_nw")));
  for (std::size_t k = 1; k < c.rows.size(); ++k) {
    const double medium = c.at(k, "diss_medium_nw"), cortex = c.at(k, "diss_cortex_nw");
    const double forces = c.at(k, "power_forces_nw");
    EXPECT_GT(medium, 0);
    EXPECT_GT(cortex, 0);
    EXPECT_NEAR(medium + cortex, forces, 1e-6 * forces) << k;
    for (const char* none :
         {"diss_friction_t_nw", "diss_friction_n_nw", "diss_springs_nw", "power_active_nw"})
      EXPECT_EQ(c.at(k, none), 0) << none;
  }
  // It relaxes: less power at the end than after the first second.
  EXPECT_LT(c.at(4, "power_forces_nw"), c.at(1, "power_forces_nw"));
}

// Every integrator's solve, as a doublet's step shows it: the parts sum to vᵀΓv of the Γ the
// solver used (the split is exact), which is vᵀF to the CG tolerance; the springs' part is there
// where Γ carries them.
TEST(Probes, DissipationSplitsTheSolversOwnGamma) {
  for (IntegratorKind integrator :
       {IntegratorKind::SemiImplicit, IntegratorKind::ContactImplicit,
        IntegratorKind::ContactImplicitConsistent, IntegratorKind::Ros2}) {
    SCOPED_TRACE(std::string(toString(integrator)));
    SceneSpec s = doublet();
    s.numerics.integrator = integrator;
    s.numerics.dt_s = integrator == IntegratorKind::SemiImplicit ? 0.005 : 0.1;
    s.cells.p_a = 0.1;  // motile: active forces
    s = resolve(s);
    Simulation sim(s);
    int seen = 0;
    sim.onStartSolve([&](const StartSolve& solve) {
      const Dissipation d = dissipation(solve);
      Eigen::VectorXd y(solve.v.size());
      solve.friction.apply(solve.v.data(), y.data());
      const double vgv = solve.v.dot(y);
      EXPECT_NEAR(total(d), vgv, 1e-10 * vgv);
      const Eigen::Map<const Eigen::VectorXd> b(solve.f.data(), solve.f.size());
      // |vᵀ(Γv − F)| ≤ |v| |Γv − F|, the residual within ε_CG |F| (twice: CG's recurrence)
      EXPECT_LE(std::abs(vgv - d.forces), 2 * s.numerics.cg_tol * solve.v.norm() * b.norm());
      EXPECT_GT(d.medium, 0);
      EXPECT_GT(d.cortex, 0);
      if (!solve.ctx.contacts->pairs.empty()) {
        EXPECT_GT(d.friction_t, 0);
        EXPECT_GT(d.friction_n, 0);
      }
      if (integrator == IntegratorKind::SemiImplicit) {
        EXPECT_EQ(d.springs, 0);
      } else if (!solve.ctx.contacts->pairs.empty()) {
        EXPECT_GT(d.springs, 0);
      }
      EXPECT_NE(d.active, 0);
      ++seen;
    });
    for (int k = 0; k < 20; ++k) ASSERT_TRUE(sim.step().ok());
    EXPECT_GE(seen, 20);
  }
}

// A motile fusion at a tight tolerance: at every sample the terms sum to the forces' power,
// with the tension's stiffness in Γ too (numerics.tension_implicit: counted with the springs').
TEST(Probes, SmallFusionTermsSumToThePowerOfTheForces) {
  for (bool tension_implicit : {false, true}) {
    SCOPED_TRACE(tension_implicit ? "tension implicit" : "tension explicit");
    SceneSpec s = smallFusionSpec(5, 3, 4, 3, 1);
    s.numerics.cg_tol = 1e-10;
    s.numerics.tension_implicit = tension_implicit;
    s.observe.dissipation = true;
    const Column c = runProbed(s);
    ASSERT_EQ(c.rows.size(), 4u);
    for (std::size_t k = 1; k < c.rows.size(); ++k) {
      double sum = 0;
      for (const char* t : {"diss_medium_nw", "diss_cortex_nw", "diss_friction_t_nw",
                            "diss_friction_n_nw", "diss_springs_nw"}) {
        EXPECT_GT(c.at(k, t), 0) << t;
        sum += c.at(k, t);
      }
      EXPECT_NEAR(sum, c.at(k, "power_forces_nw"), 1e-6 * sum) << k;
      EXPECT_NE(c.at(k, "power_active_nw"), 0);
    }
  }
}

// Probes read and never write: a fusion with all of them has every other column's bits and the same
// summary; the probes' columns come last, in the key table's order.
TEST(Probes, ChangeNoBitOfTheRun) {
  const SceneSpec plain = smallFusionSpec(11, 3, 4, 6, 1);
  SceneSpec probed = plain;
  probed.observe.rigid_motion = true;
  probed.observe.dissipation = true;
  probed.observe.msrd_by_depth = true;
  probed.observe.shape = true;
  probed.observe.torque = true;
  std::vector<Sample> a, b;
  RunObserver oa, ob;
  oa.on_sample = [&](const Sample& x) { a.push_back(x); };
  ob.on_sample = [&](const Sample& x) { b.push_back(x); };
  const RunSummary sa = runScene(plain, oa), sb = runScene(probed, ob);
  ASSERT_TRUE(sa.ok() && sb.ok());
  const std::vector<std::string> cols = sampleColumns(plain), more = sampleColumns(probed);
  ASSERT_EQ(more.size(), cols.size() + 32);
  EXPECT_TRUE(std::equal(cols.begin(), cols.end(), more.begin()));
  EXPECT_EQ(more[cols.size()], "rigid_turn_deg");
  EXPECT_EQ(more[cols.size() + 2], "diss_medium_nw");
  EXPECT_EQ(more[cols.size() + 9], "diss_medium_affine_nw");
  EXPECT_EQ(more[cols.size() + 16], "cells_surface");
  EXPECT_EQ(more[cols.size() + 18], "shape_index_smoothed_mean");
  EXPECT_EQ(more[cols.size() + 24], "net_force_nn");
  ASSERT_EQ(a.size(), b.size());
  for (Sample& x : b) x.values.resize(cols.size());
  EXPECT_EQ(bits(physicsColumns(a)), bits(physicsColumns(b)));
  EXPECT_EQ(sa.steps, sb.steps);
  // The probes' final values and curves come after the run's own.
  ASSERT_EQ(sa.final_values.size() + 6, sb.final_values.size());
  EXPECT_TRUE(sa.curves.empty());
  EXPECT_EQ(sb.curves.size(), 6u);
  EXPECT_EQ(sa.msrd, sb.msrd);
  for (std::size_t i = 0; i < sa.final_values.size(); ++i)
    EXPECT_EQ(std::memcmp(&sa.final_values[i].second, &sb.final_values[i].second, sizeof(double)),
              0)
        << sa.final_values[i].first;
}

// A probe where its scene gives it no meaning is not built (the front ends refuse the key).
TEST(Probes, OnlyWhereTheSceneReadsThem) {
  SceneSpec s = cellSpec(1.0, 80);
  s.observe.rigid_motion = true;
  s.observe.dissipation = true;
  s.observe.msrd_by_depth = true;
  s.observe.shape = true;
  s.observe.torque = true;
  EXPECT_EQ(probeColumns(s).size(), 14u);  // the dissipation's alone
  EXPECT_FALSE(findField("observe.rigid_motion")->readBy(SceneKind::Cell));
  EXPECT_FALSE(findField("observe.rigid_motion")->readBy(SceneKind::Doublet));
  EXPECT_TRUE(findField("observe.rigid_motion")->readBy(SceneKind::Fusion));
  for (SceneKind k : {SceneKind::Cell, SceneKind::Doublet, SceneKind::Spheroid})
    EXPECT_FALSE(findField("observe.msrd_by_depth")->readBy(k));  // the MSRD is a fusion's
  EXPECT_TRUE(findField("observe.msrd_by_depth")->readBy(SceneKind::Fusion));
  for (SceneKind k : {SceneKind::Cell, SceneKind::Doublet}) {
    EXPECT_FALSE(findField("observe.shape")->readBy(k));  // an aggregate's cells
    EXPECT_FALSE(findField("observe.torque")->readBy(k));
  }
  EXPECT_TRUE(findField("observe.shape")->readBy(SceneKind::Spheroid));
  EXPECT_FALSE(findField("observe.torque")->readBy(SceneKind::Spheroid));
  EXPECT_TRUE(findField("observe.torque")->readBy(SceneKind::Fusion));
  s.scene = SceneKind::Spheroid;
  EXPECT_EQ(probeColumns(s).size(), 22u);
  s.scene = SceneKind::Fusion;
  EXPECT_EQ(probeColumns(s).size(), 32u);
}

// The keys change neither the preparation nor, while off, the fingerprint; on, they are in it:
// a checkpoint without a probe's state is refused by a run that asks for the probe, and back.
TEST(Probes, KeysLeaveThePreparationAloneAndSeparateCheckpoints) {
  const SceneSpec plain = smallFusionSpec();
  SceneSpec probed = plain;
  probed.observe.rigid_motion = true;
  probed.observe.dissipation = true;
  probed.observe.msrd_by_depth = true;
  probed.observe.shape = true;
  probed.observe.torque = true;
  EXPECT_EQ(spheroidPrepSpec(probed, 3, 11), spheroidPrepSpec(plain, 3, 11));
  EXPECT_EQ(specFingerprint(plain).find("observe"), std::string::npos);
  EXPECT_NE(specFingerprint(probed).find("observe.rigid_motion=1"), std::string::npos);
  EXPECT_NE(specFingerprint(probed).find("observe.msrd_by_depth=1"), std::string::npos);
  EXPECT_NE(specFingerprint(probed).find("observe.shape=1"), std::string::npos);
  EXPECT_NE(specFingerprint(probed).find("observe.torque=1"), std::string::npos);

  SceneSpec d = resolve(doublet());
  std::string checkpoint;
  std::atomic<bool> cancel{false};
  RunObserver o;
  o.cancel = &cancel;
  o.on_checkpoint = [&](double, const std::string& c) { checkpoint = c; };
  o.on_sample = [&](const Sample& x) { cancel = x.values[0] >= 2; };
  ASSERT_EQ(runScene(d, o).failure, FailureKind::Cancelled);
  ASSERT_FALSE(checkpoint.empty());
  SceneSpec with = d;
  with.observe.dissipation = true;
  EXPECT_THROW(runScene(with, RunObserver{}, &checkpoint), std::invalid_argument);
  cancel = false;
  checkpoint.clear();
  ASSERT_EQ(runScene(with, o).failure, FailureKind::Cancelled);
  EXPECT_THROW(runScene(d, RunObserver{}, &checkpoint), std::invalid_argument);
  EXPECT_TRUE(runScene(with, RunObserver{}, &checkpoint).ok());
}

// ---- observe.msrd_by_depth

// Depth in the contact graph: a surface cell 0, then buried cells by their fewest contacts to it
// (cell 3 through 7 rather than along the chain 1–2), a buried island with no way to the surface
// (the deepest found + 1), an isolated surface cell; 0.05 itself is on the surface; with no
// surface cell at all every cell is at 0.
TEST(Probes, ContactDepthsCountContactsFromTheSurface) {
  const std::vector<double> free = {0.3, 0.01, 0, 0.049, 0, 0.02, 1, 0};
  const std::vector<std::pair<int, int>> pairs = {{0, 1}, {1, 2}, {2, 3}, {4, 5}, {0, 7}, {3, 7}};
  EXPECT_EQ(contactDepths(free, pairs), (std::vector<int>{0, 1, 2, 2, 3, 3, 0, 1}));
  EXPECT_EQ(contactDepths({0.05, 0.0}, {{0, 1}}), (std::vector<int>{0, 1}));
  EXPECT_EQ(contactDepths({0.0, 0.01}, {{0, 1}}), (std::vector<int>{0, 0}));
  // At 0.5 the one surface cell touches no other: every buried cell has no way out, at 0 + 1.
  EXPECT_EQ(contactDepths(free, pairs, 0.5), (std::vector<int>{1, 1, 1, 1, 1, 1, 0, 1}));
  EXPECT_THROW(contactDepths({1.0}, {{0, 1}}), std::invalid_argument);
}

// The free fraction is the engine's own contact area against the cell's.
TEST(Probes, FreeFractionIsTheShareOfTheSurfaceInNoContact) {
  Geometry geo;
  geo.cell_area = {10, 20, 8};
  ContactList con;
  EXPECT_EQ(freeFractions(geo, con), (std::vector<double>{1, 1, 1}));  // none detected
  con.cell_contact_area = {2.5, 20, 0};
  EXPECT_EQ(freeFractions(geo, con), (std::vector<double>{0.75, 0, 1}));
}

namespace {

// MsrdTracker::Pooled's mean and count.
void expectPooled(const MsrdTracker::Pooled& p, double mean, long pairs, const char* what) {
  EXPECT_EQ(p.pairs, pairs) << what;
  if (pairs == 0)
    EXPECT_TRUE(std::isnan(p.mean())) << what;
  else
    EXPECT_DOUBLE_EQ(p.mean(), mean) << what;
}

}  // namespace

// Cells 0–2 on the surface, 3–5 buried at depths 1, 2, 3. Cell 0 moves by d between samples, no
// other cell moves: its pairs' relative vectors change by lag × d, all others' by nothing. Pairs
// (0,1), (0,2) on the surface, (0,3), (2,3) mixed, (3,4), (4,5) buried; by the shallower cell's
// depth the first four are layer 0, (3,4) layer 1, (4,5) layer 2+.
TEST(Probes, MsrdByDepthSplitsAKnownMotion) {
  const double d = 0.5;
  const std::vector<double> free = {0.4, 0.2, 0.06, 0.04, 0, 0.01};
  const std::vector<std::pair<int, int>> pairs = {{0, 1}, {0, 2}, {0, 3}, {2, 3}, {3, 4}, {4, 5}};
  std::vector<Vec3> x0;
  for (int c = 0; c < 6; ++c) x0.emplace_back(3.0 * c, 0.5 * c * c, -1.0 * c);
  MsrdByDepth split;
  const int n = 4;
  for (int k = 0; k < n; ++k) {
    std::vector<Vec3> x = x0;
    x[0] += Vec3(k * d, 0, 0);
    split.addSample(30.0 * k, x, pairs, free);
  }
  for (int lag = 1; lag < n; ++lag) {
    SCOPED_TRACE(lag);
    const double l2 = (lag * d) * (lag * d);
    const long origins = n - lag;
    const MsrdByDepth::Split s = split.pooled(lag);
    expectPooled(s.burial[MsrdByDepth::kSurface], l2, 2 * origins, "surface");
    expectPooled(s.burial[MsrdByDepth::kMixed], l2 / 2, 2 * origins, "mixed");
    expectPooled(s.burial[MsrdByDepth::kBuried], 0, 2 * origins, "buried");
    expectPooled(s.layer[MsrdByDepth::kLayer0], 3 * l2 / 4, 4 * origins, "layer 0");
    expectPooled(s.layer[MsrdByDepth::kLayer1], 0, origins, "layer 1");
    expectPooled(s.layer[MsrdByDepth::kLayer2Plus], 0, origins, "layer 2+");
    EXPECT_DOUBLE_EQ(split.tracker().msrd(lag), l2 / 2);
  }
  // Its samples survive a checkpoint; malformed bytes, and a tracker without depths, do not.
  MsrdByDepth restored;
  restored.restore(split.save());
  EXPECT_EQ(restored.pooled(2).layer[0].sum, split.pooled(2).layer[0].sum);
  EXPECT_THROW(restored.restore("xx"), std::invalid_argument);
  EXPECT_THROW(restored.restore(split.save() + "x"), std::invalid_argument);
  MsrdTracker plain;
  plain.addSample(0, x0, pairs);
  EXPECT_THROW(restored.restore(plain.save()), std::invalid_argument);
  EXPECT_THROW(plain.pooledByClass(0, 1, [](int, int) { return 0; }), std::invalid_argument);
  EXPECT_THROW(split.addSample(200, x0, pairs, {0.5}), std::invalid_argument);
}

// A pair's class is its cells' at the origin: buried at the first sample only, cell 1's pair
// with surface cell 0 is mixed from that origin and on the surface from the later ones.
TEST(Probes, MsrdByDepthClassesAPairAtItsOrigin) {
  const double d = 0.25;
  MsrdByDepth split;
  for (int k = 0; k < 3; ++k)
    split.addSample(k, {Vec3::Zero(), Vec3(2 + k * d, 0, 0)}, {{0, 1}}, {0.5, k == 0 ? 0.01 : 0.5});
  expectPooled(split.pooled(1).burial[MsrdByDepth::kMixed], d * d, 1, "mixed, lag 1");
  expectPooled(split.pooled(1).burial[MsrdByDepth::kSurface], d * d, 1, "surface, lag 1");
  expectPooled(split.pooled(2).burial[MsrdByDepth::kMixed], 4 * d * d, 1, "mixed, lag 2");
  expectPooled(split.pooled(2).burial[MsrdByDepth::kSurface], 0, 0, "surface, lag 2");
  // The classes' mixing times by the tracker's rule: r² = 2d² is crossed between lags 1 and 2.
  std::vector<double> mixed(3);
  for (int k = 0; k < 3; ++k) mixed[k] = split.pooled(k).burial[MsrdByDepth::kMixed].mean();
  const MsrdTracker::Mixing m = split.tracker().mixingTime(std::sqrt(2) * d, mixed);
  EXPECT_TRUE(m.reached);
  EXPECT_DOUBLE_EQ(m.time_s, 1 + 1.0 / 3);
}

// A real fusion, sampled every step: every origin–pair of the MSRD falls in one class of each
// split, so at every lag the classes hold the MSRD's pairs and it is their pair-weighted mean —
// at the probe's threshold and at the median free fraction of t = 0, where so small an
// aggregate has cells of every class.
TEST(Probes, MsrdByDepthSplitsTheRunsOwnMsrd) {
  const SceneSpec s = smallFusionSpec(5, 3, 4, 10, 1);
  Simulation sim(s, buildFusionCells(s, nullptr));
  std::vector<double> free0 = freeFractions(sim.geometry(), sim.contacts());
  std::sort(free0.begin(), free0.end());
  const double median = free0[free0.size() / 2];
  ASSERT_LT(free0.front(), 1);  // in contact
  MsrdTracker all;
  std::vector<MsrdByDepth> splits{MsrdByDepth(), MsrdByDepth(median)};
  auto sample = [&] {
    const std::vector<double> free = freeFractions(sim.geometry(), sim.contacts());
    for (double f : free) EXPECT_TRUE(f >= 0 && f <= 1) << f;
    const auto pairs = contactingCellPairs(sim.cells(), sim.contacts());
    all.addSample(sim.time(), sim.geometry().cell_centroid, pairs);
    for (MsrdByDepth& sp : splits)
      sp.addSample(sim.time(), sim.geometry().cell_centroid, pairs, free);
  };
  sample();
  for (int k = 0; k < 16; ++k) {
    ASSERT_TRUE(sim.step().ok());
    sample();
  }
  std::array<long, 3> populated{};
  for (std::size_t which = 0; which < splits.size(); ++which)
    for (int lag = 1; lag < all.numSamples(); ++lag) {
      SCOPED_TRACE(::testing::Message() << "split " << which << ", lag " << lag);
      const MsrdTracker::Pooled every =
          splits[which].tracker().pooledByClass(lag, 1, [](int, int) { return 0; })[0];
      ASSERT_GT(every.pairs, 0);
      EXPECT_EQ(every.mean(), all.msrd(lag));  // the same samples, the same sum
      const MsrdByDepth::Split sp = splits[which].pooled(lag);
      for (const auto* classes : {&sp.burial, &sp.layer}) {
        double sum = 0;
        long pairs = 0;
        for (const MsrdTracker::Pooled& p : *classes) {
          sum += p.pairs ? p.mean() * p.pairs : 0;
          pairs += p.pairs;
        }
        EXPECT_EQ(pairs, every.pairs);
        EXPECT_NEAR(sum / pairs, all.msrd(lag), 1e-12 * all.msrd(lag));
      }
      if (which == 1)
        for (int c = 0; c < 3; ++c) populated[c] += sp.burial[c].pairs;
    }
  for (int c = 0; c < 3; ++c) EXPECT_GT(populated[c], 0) << "class " << c;
}

// Through runScene: the columns count the cells at every sample, and the run ends with the six
// curves and the classes' mixing times. No cell of so small an aggregate is buried: the surface
// pairs are all the pairs, and layer 0 too.
// observe.msrd_by_depth_after_s: the probe's curves count only the origins from that time on —
// those of a tracker given only the samples from then — while its columns keep every sample.
TEST(Probes, MsrdByDepthAfterCountsOnlyTheLaterOrigins) {
  SceneSpec s = smallFusionSpec(5, 3, 4, 10, 1);
  s.observe.msrd_by_depth = true;
  s.observe.msrd_by_depth_after_s = 4;
  Simulation sim(s, buildFusionCells(s, nullptr));
  auto probes = makeProbes(s);
  ASSERT_EQ(probes.size(), 1u);
  MsrdTracker later;
  int samples = 0;
  auto sample = [&] {
    std::vector<double> out;
    probes[0]->sample(sim, out);
    ASSERT_EQ(out.size(), 2u);
    ++samples;
    if (sim.time() >= 4 - 1e-9)
      later.addSample(sim.time(), sim.geometry().cell_centroid,
                      contactingCellPairs(sim.cells(), sim.contacts()));
  };
  sample();
  for (int k = 0; k < 16; ++k) {  // 8 s at Δt 0.5 s, a sample a second
    ASSERT_TRUE(sim.step().ok());
    if (k % 2 == 1) sample();
  }
  ASSERT_EQ(samples, 9);
  ASSERT_EQ(later.numSamples(), 5);
  RunSummary sum;
  probes[0]->finish(sum);
  const RunSummary::Curve& surface = sum.curves[0];
  ASSERT_EQ(surface.name, "msrd_surface");
  ASSERT_EQ(surface.x.size(), 4u);  // lags 1–4 s of the five later samples
  for (int lag = 1; lag <= 4; ++lag) {
    EXPECT_DOUBLE_EQ(surface.x[lag - 1], later.lagTime(lag));
    EXPECT_NEAR(surface.y[lag - 1], later.msrd(lag), 1e-12 * later.msrd(lag));
  }
}

TEST(Probes, MsrdByDepthEndsAFusionWithItsCurves) {
  SceneSpec s = smallFusionSpec(5, 3, 4, 10, 1);
  s.observe.msrd_by_depth = true;
  Column c;
  c.names = sampleColumns(s);
  RunObserver obs;
  obs.on_sample = [&](const Sample& x) { c.rows.push_back(x); };
  const RunSummary sum = runScene(s, obs);
  ASSERT_TRUE(sum.ok()) << sum.reason;
  ASSERT_EQ(c.rows.size(), 11u);
  for (std::size_t k = 0; k < c.rows.size(); ++k) {
    EXPECT_EQ(c.at(k, "cells_surface"), 7);
    EXPECT_EQ(c.at(k, "cells_buried"), 0);
  }
  std::vector<std::string> names;
  for (const RunSummary::Curve& curve : sum.curves) names.push_back(curve.name);
  ASSERT_EQ(names, (std::vector<std::string>{"msrd_surface", "msrd_mixed", "msrd_buried",
                                             "msrd_layer0", "msrd_layer1", "msrd_layer2plus"}));
  ASSERT_EQ(sum.msrd.size(), 10u);
  for (int k : {0, 3}) {
    const RunSummary::Curve& curve = sum.curves[k];
    ASSERT_EQ(curve.x.size(), sum.msrd.size()) << curve.name;
    for (std::size_t i = 0; i < sum.msrd.size(); ++i) {
      EXPECT_EQ(curve.x[i], sum.msrd[i].first);
      EXPECT_NEAR(curve.y[i], sum.msrd[i].second, 1e-12 * sum.msrd[i].second);
    }
  }
  for (int k : {1, 2, 4, 5}) EXPECT_TRUE(sum.curves[k].x.empty()) << sum.curves[k].name;
  auto value = [&](const std::string& name) {
    for (const auto& [n, v] : sum.final_values)
      if (n == name) return v;
    ADD_FAILURE() << name;
    return std::nan("");
  };
  EXPECT_EQ(value("mixing_time_surface_s"), value("mixing_time_s"));
  EXPECT_EQ(value("mixing_surface_reached"), value("mixing_reached"));
  for (const char* none : {"mixing_time_mixed_s", "mixing_time_buried_s"})
    EXPECT_TRUE(std::isnan(value(none))) << none;
  EXPECT_EQ(value("mixing_buried_reached"), 0);
}
