// The Slurm executor's pure parts: Slurm job states → job outcomes, and summary.json → the
// results the local pool stores (the end-to-end tests: CliSlurm.* and tests/slurm/).
#include <gtest/gtest.h>

#include <cmath>
#include <map>

#include "activefoam/run.h"
#include "activefoam/run_output.h"
#include "slurm.h"

using namespace activefoam::server;

TEST(SlurmExecutor, EverySlurmStateHasAMeaning) {
  for (const char* s : {"PENDING", "RUNNING", "CONFIGURING", "COMPLETING", "REQUEUED", "SUSPENDED"})
    EXPECT_EQ(classifySlurmState(s).kind, SlurmState::Active) << s;
  EXPECT_EQ(classifySlurmState("COMPLETED").kind, SlurmState::Completed);
  EXPECT_EQ(classifySlurmState("CANCELLED").kind, SlurmState::Cancelled);
  for (const char* s :
       {"FAILED", "TIMEOUT", "NODE_FAIL", "OUT_OF_MEMORY", "PREEMPTED", "BOOT_FAIL", "DEADLINE"})
    EXPECT_EQ(classifySlurmState(s).kind, SlurmState::Failed) << s;
  EXPECT_EQ(classifySlurmState("").kind, SlurmState::Unknown);
  EXPECT_EQ(classifySlurmState("SOMETHING_NEW").kind, SlurmState::Unknown);
  EXPECT_EQ(classifySlurmState("TIMEOUT").name, "TIMEOUT");
}

TEST(SlurmExecutor, ResultsFromSummaryJsonAreNamedAsThePoolNamesThem) {
  const activefoam::FlatResults flat = activefoam::flattenSummary(nlohmann::json::parse(R"({
    "ok": true, "t_s": 3600, "steps": 7200, "wall_s": 12.5, "cg_iters_mean": 4.5,
    "remesh_ops": 17, "final_values": {"theta_deg": 50.5, "neck_um": null},
    "fits": {
      "eq1": {"ok": true, "r2": 0.98, "parameters": {
        "theta_eq": {"value": 53.6, "std_error": 0.9}, "tau_f": {"value": 1916, "std_error": null}}},
      "s1": {"ok": false, "why": "too few samples", "parameters": {}}
    }, "outcome": "arrested"})"));
  const auto& results = flat.values;
  EXPECT_EQ(flat.outcome, "arrested");
  std::map<std::string, double> r(results.begin(), results.end());
  EXPECT_EQ(r.size(), results.size()) << "no name twice";
  EXPECT_EQ(r.at("t_s"), 3600);
  EXPECT_EQ(r.at("steps"), 7200);
  EXPECT_EQ(r.at("remesh_ops"), 17);
  EXPECT_EQ(r.at("theta_deg"), 50.5);
  EXPECT_TRUE(std::isnan(r.at("neck_um")));  // null → NaN, stored as NULL like the pool's NaN
  EXPECT_EQ(r.at("eq1_ok"), 1);
  EXPECT_EQ(r.at("eq1_r2"), 0.98);
  EXPECT_EQ(r.at(activefoam::fitResultName("eq1", "theta_eq")), 53.6);
  EXPECT_EQ(r.at(activefoam::fitResultName("eq1", "theta_eq") + "_se"), 0.9);
  EXPECT_TRUE(std::isnan(r.at(activefoam::fitResultName("eq1", "tau_f") + "_se")));
  EXPECT_EQ(r.at("s1_ok"), 0);
  EXPECT_FALSE(r.count("s1_r2"));  // a failed fit's parameters are left out, as in the pool
  EXPECT_THROW(activefoam::flattenSummary(nlohmann::json::array()), std::exception);
}
