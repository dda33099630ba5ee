// The committed stability map (docs/study/stability-map.csv) holds:
// at every (integrator, k_AB, p_a) the largest fixed Δt it calls stable runs 1000 steps of the
// doublet without a failure. (The adaptive ladders' rows say where a run finishes by rejecting
// tries; the fixed-Δt rows are the claim a refusal rests on.)
#include <algorithm>
#include <fstream>
#include <map>
#include <set>
#include <sstream>
#include <string>
#include <tuple>
#include <vector>

#include <gtest/gtest.h>

#include "activefoam/doublet_study.h"
#include "activefoam/simulation.h"

using namespace activefoam;

namespace {

// The numerics the map was measured at, but for the integrator and Δt each row names: the
// supplement's contact law, ε_CG 1e-3, no remesh repairs, the 5 % volume guard. (Under the
// overlap kept within prisms, today's default law, the softest contacts (k_AB × 0.25) oscillate
// at Δt 1 s with both contact-implicit integrators, passive and motile: the map is the law's.)
NumericsParams mapNumerics() {
  NumericsParams n;
  n.cg_tol = 1e-3;
  n.contact_law = ContactLawKind::Supplement;
  n.remesh_repair = RemeshRepair::None;
  n.max_volume_error = 0.05;
  return n;
}

IntegratorKind integratorNamed(const std::string& name) {
  for (IntegratorKind k : {IntegratorKind::SemiImplicit, IntegratorKind::ContactImplicit,
                           IntegratorKind::Ros2, IntegratorKind::ContactImplicitConsistent})
    if (toString(k) == name) return k;
  ADD_FAILURE() << "unknown integrator in the map: " << name;
  return IntegratorKind::ContactImplicit;
}

}  // namespace

TEST(StabilityMap, StableCellsRunAThousandStepsWithoutFailure) {
  std::ifstream in(std::string(STUDY_DIR) + "/stability-map.csv");
  ASSERT_TRUE(in) << "missing " << STUDY_DIR << "/stability-map.csv";
  auto split = [](const std::string& line) {
    std::stringstream ss(line);
    std::vector<std::string> f;
    for (std::string x; std::getline(ss, x, ',');) f.push_back(x);
    return f;
  };
  std::string line;
  std::getline(in, line);
  const std::vector<std::string> header = split(line);
  auto column = [&](const std::string& name) {
    const auto it = std::find(header.begin(), header.end(), name);
    return it == header.end() ? -1 : static_cast<int>(it - header.begin());
  };
  const int c_int = column("integrator"), c_adaptive = column("adaptive"), c_k = column("k_factor"),
            c_pa = column("pa_reduced"), c_dt = column("dt_s"), c_out = column("outcome");
  ASSERT_TRUE(c_int >= 0 && c_adaptive >= 0 && c_k >= 0 && c_pa >= 0 && c_dt >= 0 && c_out >= 0)
      << "unexpected header: " << line;
  // (integrator, k factor, p_a) → the fixed-Δt ladder in file order: (Δt, stable?)
  std::map<std::tuple<std::string, double, double>, std::vector<std::pair<double, bool>>> cells;
  std::set<std::string> integrators;
  // Adaptive runs at the default k_AB that the map says finished at the top of the ladder: the
  // refusals tell users the adaptive step would run such a Δt, so it must.
  std::vector<std::tuple<std::string, double, double>> adaptive_finished;
  double top_dt = 0;
  while (std::getline(in, line)) {
    const std::vector<std::string> f = split(line);
    ASSERT_EQ(f.size(), header.size()) << line;
    if (f[c_adaptive] != "0") {
      const double dt = std::stod(f[c_dt]);
      if (dt > top_dt) adaptive_finished.clear(), top_dt = dt;
      if (dt == top_dt && std::stod(f[c_k]) == 1 && f[c_out] == "stable")
        adaptive_finished.emplace_back(f[c_int], std::stod(f[c_pa]), dt);
      continue;
    }
    integrators.insert(f[c_int]);
    cells[{f[c_int], std::stod(f[c_k]), std::stod(f[c_pa])}].emplace_back(std::stod(f[c_dt]),
                                                                          f[c_out] == "stable");
  }
  // Every integrator the refusals speak of has its own measured rows.
  EXPECT_EQ(integrators, (std::set<std::string>{"semi-implicit", "contact-implicit", "ros2",
                                                "contact-implicit-consistent"}));
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
    NumericsParams n = mapNumerics();
    n.dt_s = largest;
    n.adaptive = false;  // stable at this fixed Δt, not by halving it
    n.integrator = integratorNamed(integrator);
    Simulation sim(doubletStudySpec(n, pa, k_factor));
    StepReport r;
    for (int k = 0; k < 1000 && r.ok(); ++k) r = sim.step();
    EXPECT_TRUE(r.ok()) << integrator << " k×" << k_factor << " p_a r/2γ " << pa << " Δt "
                        << largest << ": " << r.reason;
    ++checked;
  }
  EXPECT_GE(checked, 6);
  ASSERT_FALSE(adaptive_finished.empty()) << "no adaptive rows at the default k_AB";
  for (const auto& [integrator, pa, dt] : adaptive_finished) {
    NumericsParams n = mapNumerics();
    n.dt_s = dt;
    n.adaptive = true;
    n.integrator = integratorNamed(integrator);
    Simulation sim(doubletStudySpec(n, pa, 1));
    StepReport r;
    for (int k = 0; k < 1000 && r.ok(); ++k) r = sim.step();
    EXPECT_TRUE(r.ok()) << integrator << " adaptive, p_a r/2γ " << pa << " Δt " << dt << ": "
                        << r.reason;
    EXPECT_GT(sim.stepsRejected(), 0) << integrator << " at " << dt << " s rejected nothing";
  }
}
