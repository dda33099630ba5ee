// The default step is the figure studies' step: a fusion spec that names no numerics runs what
// the reduced studies ran (docs/science/presets.md), so that a plain job resolves the cells'
// motion as they did.
#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "activefoam/run.h"
#include "activefoam/spec.h"

using namespace activefoam;
namespace fs = std::filesystem;

namespace {

// A CSV of numbers with a header line: the header and each row.
struct Csv {
  std::vector<std::string> header;
  std::vector<std::vector<double>> rows;
};

Csv readCsv(const fs::path& path, std::size_t max_rows) {
  Csv csv;
  std::ifstream in(path);
  std::string line;
  if (!std::getline(in, line)) return csv;
  std::stringstream h(line);
  for (std::string cell; std::getline(h, cell, ',');) csv.header.push_back(cell);
  while (csv.rows.size() < max_rows && std::getline(in, line)) {
    std::vector<double> row;
    std::stringstream r(line);
    for (std::string cell; std::getline(r, cell, ',');) row.push_back(std::stod(cell));
    csv.rows.push_back(row);
  }
  return csv;
}

}  // namespace

// The reduced base point (2 × 20 cells, p_a r/2γ 0.33, L_η/r 0.5, seed 1) with no numerics
// keys: its first minutes are the committed figure-step day's samples, every column but the
// wall clock the same bits (no step of those minutes was halved).
TEST(DefaultStep, TheReducedBasePointRunsTheFigureStudiesStep) {
  const fs::path committed =
      fs::path(SOURCE_DIR) / "docs/science/fusion-2x20-24h-figure-step/samples.csv";
  const Csv want = readCsv(committed, 3);
  ASSERT_EQ(want.rows.size(), 3u) << committed;
  SceneSpec s;
  s.scene = SceneKind::Fusion;
  s.seed = 1;
  s.scene_params.n_cells = 20;
  ASSERT_EQ(setField(s, "cells.pa_reduced", 0.33), std::nullopt);
  ASSERT_EQ(setField(s, "cells.l_eta_reduced", 0.5), std::nullopt);
  s.duration_s = 120;
  s.sample_every_s = 60;
  s.snapshot_every_s = 0;
  ASSERT_TRUE(validate(s).empty());
  s = resolve(s);

  std::random_device rd;
  const fs::path dir = fs::temp_directory_path() / ("af-default-" + std::to_string(rd()));
  std::vector<Sample> got;
  RunObserver obs;
  obs.spheroid_cache_dir = dir.string();
  obs.on_sample = [&](const Sample& x) { got.push_back(x); };
  const RunSummary r = runScene(s, obs);
  fs::remove_all(dir);
  ASSERT_TRUE(r.ok()) << r.reason;
  ASSERT_EQ(got.size(), 3u);
  const std::vector<std::string> columns = sampleColumns(SceneKind::Fusion);
  int compared = 0;
  for (std::size_t c = 0; c < want.header.size(); ++c) {
    const std::string& name = want.header[c];
    if (name == "wall_s") continue;
    const auto at = std::find(columns.begin(), columns.end(), name);
    ASSERT_NE(at, columns.end()) << name;
    const auto k = static_cast<std::size_t>(at - columns.begin());
    for (std::size_t row = 0; row < 3; ++row) {
      EXPECT_EQ(got[row].values[k], want.rows[row][c]) << name << " at t = " << want.rows[row][0];
      ++compared;
    }
  }
  EXPECT_GE(compared, 3 * 15);
}
