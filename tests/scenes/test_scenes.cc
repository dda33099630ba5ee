// Whole scenes over minutes of simulated time (label `scenes`, release build only).
#include <algorithm>
#include <cmath>
#include <filesystem>
#include <iostream>
#include <random>

#include <gtest/gtest.h>

#include "activefoam/run.h"
#include "activefoam/spheroid.h"
#include "test_support.h"

using namespace activefoam;
using activefoam::testing::physicsColumns;
namespace fs = std::filesystem;

namespace {
SceneSpec specOf(SceneKind scene) {
  SceneSpec s;
  s.scene = scene;
  return s;
}
int column(SceneKind scene, const std::string& name) {
  const auto cols = sampleColumns(specOf(scene));
  return static_cast<int>(std::find(cols.begin(), cols.end(), name) - cols.begin());
}
}  // namespace

// Two spheroids of 20 cells with motility (Table 1/2 defaults: p_a r/2γ = 0.33, α = 0.4375,
// 320 triangles per cell; at 80 the coarse meshes interpenetrate within 300 s) fuse: the fusion
// angle grows from its value at contact, and a second run of the same seed (its spheroids now from
// the cache) reproduces every sample.
TEST(Fusion2x20, AngleGrowsAndTheRunIsReproducibleFromItsSeed) {
  SceneSpec s;
  s.scene = SceneKind::Fusion;
  s.seed = 3;
  s.scene_params.n_cells = 20;
  s.scene_params.prep_max_s = 180;  // still compacting (4e-4 /s): enough for θ to grow here
  s.scene_params.allow_uncompacted = true;
  s.numerics.dt_s = 0.5;
  s.duration_s = 300;
  s.sample_every_s = 10;
  s.snapshot_every_s = 0;
  ASSERT_TRUE(validate(s).empty());
  s = resolve(s);
  ASSERT_GT(s.cells.p_a, 0);

  std::random_device rd;
  const fs::path dir = fs::temp_directory_path() / ("af-scenes-" + std::to_string(rd()));
  std::vector<Sample> first, second;
  RunObserver obs;
  obs.spheroid_cache_dir = dir.string();
  obs.on_sample = [&](const Sample& x) { first.push_back(x); };
  const RunSummary a = runScene(s, obs);
  ASSERT_TRUE(a.ok()) << a.reason;
  const int theta = column(SceneKind::Fusion, "theta_deg");
  ASSERT_EQ(first.size(), 31u);
  // θ(0) of two lumpy 20-cell aggregates is noisy (a few degrees with the seed), so the growth
  // is judged on thirds of the run: each mean above the last, the end above the start.
  double third[3] = {0, 0, 0};
  std::cout << "[ fusion   ] 2 x 20 cells, theta(t):";
  for (std::size_t k = 0; k < first.size(); ++k) {
    std::cout << " " << std::round(first[k].values[theta] * 10) / 10;
    if (k > 0) third[(k - 1) / 10] += first[k].values[theta] / 10;
  }
  std::cout << "\n";
  EXPECT_GT(third[1], third[0]);
  EXPECT_GT(third[2], third[1]);
  EXPECT_GT(first.back().values[theta], first.front().values[theta] + 2);
  // Neck radius grows and the centroids approach: the same process seen by a and d.
  EXPECT_GT(first.back().values[theta + 1], first.front().values[theta + 1]);
  EXPECT_LT(first.back().values[theta + 3], first.front().values[theta + 3]);
  for (const Sample& x : first)
    for (double v : x.values) EXPECT_TRUE(std::isfinite(v)) << "t=" << x.values[0];

  // The first minute again (the run length is not part of the spheroids' key).
  SceneSpec shorter = s;
  shorter.duration_s = 60;
  obs.on_sample = [&](const Sample& x) { second.push_back(x); };
  const RunSummary b = runScene(shorter, obs);
  ASSERT_TRUE(b.ok()) << b.reason;
  ASSERT_EQ(second.size(), 7u);
  EXPECT_EQ(physicsColumns(second), physicsColumns({first.begin(), first.begin() + 7}));

  std::error_code ec;
  fs::remove_all(dir, ec);
}

// A compacting aggregate squeezes triangles at the contact rims to zero area faster than the
// periodic remesh (τ_r = 14.4 s) comes round: this seed failed with an inverted triangle at
// t = 208.7 s before cells were remeshed as soon as a triangle falls below A_m/2.
TEST(Spheroid, CompactsWithoutInvertedTriangles) {
  SceneSpec s;
  s.scene = SceneKind::Spheroid;
  s.seed = 2;
  s.scene_params.n_cells = 20;
  s.numerics.triangles_per_cell = 80;
  s.duration_s = 300;
  s.sample_every_s = 30;
  s.snapshot_every_s = 0;
  s = resolve(s);
  std::vector<Sample> samples;
  RunObserver obs;
  obs.on_sample = [&](const Sample& x) { samples.push_back(x); };
  const RunSummary r = runScene(s, obs);
  ASSERT_TRUE(r.ok()) << r.reason;
  const int rg = column(SceneKind::Spheroid, "radius_gyration_um");
  EXPECT_LT(samples.back().values[rg], samples.front().values[rg]);  // compaction
  for (const Sample& x : samples) EXPECT_LT(x.values[4], 0.03);  // volume error (measured ≤ 0.021)
}
