// The step guards: the standard list and its order, and what the inverted-triangle guard says.
#include <algorithm>
#include <array>
#include <cmath>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "activefoam/step_guards.h"
#include "step_scenes.h"
#include "test_support.h"

using namespace activefoam;
using activefoam::testing::cellSpec;
using activefoam::testing::motileDoublet;

TEST(StepGuards, StandardGuardsInOrder) {
  Simulation cell(cellSpec(1.3, 80));
  EXPECT_EQ(cell.guardNames(),
            (std::vector<std::string_view>{"non-finite", "cg-not-converged", "inverted-triangle",
                                           "volume-drift"}));
  Simulation doublet(motileDoublet(0.1));
  EXPECT_EQ(doublet.guardNames(), (std::vector<std::string_view>{
                                      "non-finite", "cg-not-converged", "contact-oscillation",
                                      "inverted-triangle", "volume-drift", "interpenetration"}));
}

// An inverted triangle is named with its shape and contact at the step's start, which tell a
// sliver the remesher left from a pair pressing it: here a vertex of a cell's triangle is pulled
// along one edge's line far past it (a long edge, an angle near 180°), then pushed through.
TEST(StepGuards, AnInvertedTriangleIsDescribedByItsShapeAtTheStepsStart) {
  SceneSpec s = resolve(cellSpec(1.0, 320));
  CellSet before;
  before.addCell(ellipsoidCell(s.cells.radius_mean_um, 1.0, 320, Vec3::Zero()), 8.0);
  const int t = 11;
  const Tri f = before.tri[t];
  // Make the triangle a sliver at the start: vertex 2 moved to just beside the line 0–1,
  // beyond vertex 1 (the longest edge is then 0–2).
  const Vec3 x0 = before.x.col(f[0]), x1 = before.x.col(f[1]);
  const Vec3 n = (x1 - x0).cross(Vec3(before.x.col(f[2])) - x0).normalized();
  const Vec3 side = n.cross(x1 - x0).normalized();
  before.x.col(f[2]) = x0 + 3.0 * (x1 - x0) + 0.1 * side;
  Geometry geo_before, geo;
  computeGeometry(before, geo_before);
  CellSet after = before;
  after.x.col(f[2]) = x0 + 3.0 * (x1 - x0) - 0.1 * side;  // through the line: inverted
  computeGeometry(after, geo);
  ASSERT_LT(geo.tri_normal[t].dot(geo_before.tri_normal[t]), 0);

  std::array<double, 3> edge{}, angle{};
  for (int k = 0; k < 3; ++k) {
    const Vec3 p = before.x.col(f[k]), q = before.x.col(f[(k + 1) % 3]),
               r = before.x.col(f[(k + 2) % 3]);
    edge[k] = (q - p).norm();
    angle[k] = std::acos((q - p).normalized().dot((r - p).normalized())) * 180 / M_PI;
  }
  auto guards = standardGuards(false);
  StepGuard* inverted = nullptr;
  for (auto& g : guards)
    if (g->name() == "inverted-triangle") inverted = g.get();
  ASSERT_NE(inverted, nullptr);
  GuardView view{s, after, geo};
  view.geo_before = &geo_before;
  view.cells_before = &before;
  const auto failure = inverted->check(view);
  ASSERT_TRUE(failure.has_value());
  const std::string& why = failure->reason;
  EXPECT_NE(why.find("triangle 11 of cell 0 inverted"), std::string::npos) << why;
  const auto value_after = [&](const std::string& what) {
    const auto at = why.find(what);
    EXPECT_NE(at, std::string::npos) << what << " in " << why;
    return at == std::string::npos ? NAN : std::stod(why.substr(at + what.size()));
  };
  EXPECT_NEAR(value_after("at the step's start its edges were "), edge[0], 0.01 * edge[0]);
  EXPECT_NEAR(value_after("its largest angle "), *std::max_element(angle.begin(), angle.end()),
              0.5);
  EXPECT_GT(value_after("its largest angle "), 170);
  const double longest = *std::max_element(edge.begin(), edge.end());
  const double area = geo_before.tri_area[t];
  EXPECT_NEAR(value_after("its height on the longest "), 2 * area / longest, 0.01);
  // Without the start (no adaptive stepping) it says the shape is the end's.
  view.cells_before = nullptr;
  EXPECT_NE(inverted->check(view)->reason.find("at its end its edges were"), std::string::npos);
}
