// Remeshing inside a running simulation: 10 000 steps with the invariants checked at every
// remesh (closed 2-manifold, oriented, triangle areas within [A_m/2, 2 A_M], volume jump).
#include <cmath>
#include <iostream>

#include <gtest/gtest.h>

#include "test_support.h"

using namespace activefoam;
using activefoam::testing::cellSpec;

TEST(RemeshInSimulation, TenThousandStepsKeepInvariants) {
  // A strongly stretched start (axes 2r, r, r/2) with thresholds [0.5, 1.6]·A_Δ, so splits,
  // collapses and flips all happen while the cell relaxes, then keep happening as nodes flow.
  SceneSpec s = cellSpec(2.0, 320);
  s.numerics.remesh_min_area_factor = 0.5;
  s.numerics.remesh_max_area_factor = 1.6;
  Simulation sim(s);
  const double r = sim.cells().radius[0];
  const double a_ref = 4 * M_PI * r * r / 320;
  const double a_min = s.numerics.remesh_min_area_factor * a_ref;
  const double a_max = s.numerics.remesh_max_area_factor * a_ref;
  int remeshes = 0, ops = 0;
  double worst_jump = 0;
  for (int k = 0; k < 10000; ++k) {
    const StepReport rep = sim.step();
    ASSERT_TRUE(rep.ok()) << rep.reason;
    if (rep.remesh_ops == 0 && sim.steps() % 144 != 0) continue;
    ++remeshes;
    ops += rep.remesh_ops;
    worst_jump = std::max(worst_jump, rep.remesh_volume_jump);
    ASSERT_LT(rep.remesh_volume_jump, 1e-3) << "at step " << sim.steps();
    const TriMesh m = sim.cells().cellMesh(0);
    ASSERT_EQ(checkClosedManifold(m), "") << "at step " << sim.steps();
    for (int t = 0; t < m.numTriangles(); ++t) {
      const double a = triangleArea(m, t);
      ASSERT_GE(a, a_min / 2) << "triangle " << t << " at step " << sim.steps();
      ASSERT_LE(a, 2 * a_max) << "triangle " << t << " at step " << sim.steps();
    }
  }
  std::cout << "[ remesh   ] " << remeshes << " remeshes, " << ops << " operations, "
            << sim.cells().numTriangles() << " triangles at the end, worst volume jump "
            << worst_jump << "\n";
  EXPECT_GT(ops, 0);  // the invariants were exercised, not vacuous
  EXPECT_EQ(sim.remeshOps(), ops);
}
