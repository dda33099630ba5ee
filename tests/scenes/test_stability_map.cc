// The committed stability map (docs/study/stability-map.csv, bench/study_stability_map) holds:
// at every (integrator, k_AB, p_a) the largest Δt it calls stable runs 1000 steps of the doublet
// without a failure.
#include <fstream>
#include <map>
#include <sstream>
#include <string>
#include <tuple>
#include <vector>

#include <gtest/gtest.h>

#include "activefoam/doublet_study.h"
#include "activefoam/simulation.h"

using namespace activefoam;

TEST(StabilityMap, StableCellsRunAThousandStepsWithoutFailure) {
  std::ifstream in(std::string(STUDY_DIR) + "/stability-map.csv");
  ASSERT_TRUE(in) << "missing " << STUDY_DIR << "/stability-map.csv";
  std::string line;
  std::getline(in, line);  // header
  // (integrator, k factor, p_a) → the ladder in file order: (Δt, stable?)
  std::map<std::tuple<std::string, double, double>, std::vector<std::pair<double, bool>>> cells;
  while (std::getline(in, line)) {
    std::stringstream ss(line);
    std::vector<std::string> f;
    for (std::string x; std::getline(ss, x, ',');) f.push_back(x);
    ASSERT_GE(f.size(), 6u) << line;
    cells[{f[0], std::stod(f[1]), std::stod(f[3])}].emplace_back(std::stod(f[4]), f[5] == "stable");
  }
  ASSERT_GE(cells.size(), 6u);
  int checked = 0;
  for (const auto& [key, ladder] : cells) {
    double largest = 0;
    for (const auto& [dt, stable] : ladder) {
      if (!stable) break;
      largest = dt;
    }
    if (largest == 0) continue;
    const auto& [integrator, k_factor, pa] = key;
    NumericsParams n;
    n.dt_s = largest;
    n.adaptive = false;  // stable at this fixed Δt, not by halving it
    n.integrator = integrator == "semi-implicit" ? IntegratorKind::SemiImplicit
                   : integrator == "ros2"        ? IntegratorKind::Ros2
                                                 : IntegratorKind::ContactImplicit;
    Simulation sim(doubletStudySpec(n, pa, k_factor));
    StepReport r;
    for (int k = 0; k < 1000 && r.ok(); ++k) r = sim.step();
    EXPECT_TRUE(r.ok()) << integrator << " k×" << k_factor << " p_a r/2γ " << pa << " Δt "
                        << largest << ": " << r.reason;
    ++checked;
  }
  EXPECT_GE(checked, 6);
}
