// Probes ([observe]): the aggregate's rigid motion and the dissipation by term, on states with
// known answers; a run's other columns keep their bits with probes on.
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

// A motile fusion at a tight tolerance: at every sample the terms sum to the forces' power.
TEST(Probes, SmallFusionTermsSumToThePowerOfTheForces) {
  SceneSpec s = smallFusionSpec(5, 3, 4, 3, 1);
  s.numerics.cg_tol = 1e-10;
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

// Probes read and never write: a fusion with both has every other column's bits and the same
// summary; the probes' columns come last, in the key table's order.
TEST(Probes, ChangeNoBitOfTheRun) {
  const SceneSpec plain = smallFusionSpec(11, 3, 4, 6, 1);
  SceneSpec probed = plain;
  probed.observe.rigid_motion = true;
  probed.observe.dissipation = true;
  std::vector<Sample> a, b;
  RunObserver oa, ob;
  oa.on_sample = [&](const Sample& x) { a.push_back(x); };
  ob.on_sample = [&](const Sample& x) { b.push_back(x); };
  const RunSummary sa = runScene(plain, oa), sb = runScene(probed, ob);
  ASSERT_TRUE(sa.ok() && sb.ok());
  const std::vector<std::string> cols = sampleColumns(plain), more = sampleColumns(probed);
  ASSERT_EQ(more.size(), cols.size() + 9);
  EXPECT_TRUE(std::equal(cols.begin(), cols.end(), more.begin()));
  EXPECT_EQ(more[cols.size()], "rigid_turn_deg");
  EXPECT_EQ(more[cols.size() + 2], "diss_medium_nw");
  ASSERT_EQ(a.size(), b.size());
  for (Sample& x : b) x.values.resize(cols.size());
  EXPECT_EQ(bits(physicsColumns(a)), bits(physicsColumns(b)));
  EXPECT_EQ(sa.steps, sb.steps);
  ASSERT_EQ(sa.final_values.size(), sb.final_values.size());
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
  EXPECT_EQ(probeColumns(s).size(), 7u);  // the dissipation's alone
  EXPECT_FALSE(findField("observe.rigid_motion")->readBy(SceneKind::Cell));
  EXPECT_FALSE(findField("observe.rigid_motion")->readBy(SceneKind::Doublet));
  EXPECT_TRUE(findField("observe.rigid_motion")->readBy(SceneKind::Fusion));
  s.scene = SceneKind::Spheroid;
  EXPECT_EQ(probeColumns(s).size(), 9u);
}

// The keys change neither the preparation nor, while off, the fingerprint; on, they are in it:
// a checkpoint without a probe's state is refused by a run that asks for the probe, and back.
TEST(Probes, KeysLeaveThePreparationAloneAndSeparateCheckpoints) {
  const SceneSpec plain = smallFusionSpec();
  SceneSpec probed = plain;
  probed.observe.rigid_motion = true;
  probed.observe.dissipation = true;
  EXPECT_EQ(spheroidPrepSpec(probed, 3, 11), spheroidPrepSpec(plain, 3, 11));
  EXPECT_EQ(specFingerprint(plain).find("observe"), std::string::npos);
  EXPECT_NE(specFingerprint(probed).find("observe.rigid_motion=1"), std::string::npos);

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
