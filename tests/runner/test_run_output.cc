// foam-run's output folder without the engine: CSV lines, summary.json, atomic writes.
#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>

#include <gtest/gtest.h>

#include "activefoam/run_output.h"
#include "activefoam/spec_io.h"
#include "test_files.h"

namespace activefoam {
namespace {

namespace fs = std::filesystem;

using testing::readFile;

class RunOutputTest : public ::testing::Test {
 protected:
  void SetUp() override {
    std::string tmpl = (fs::temp_directory_path() / "run_output_test_XXXXXX").string();
    ASSERT_NE(mkdtemp(tmpl.data()), nullptr);
    dir_ = tmpl;
  }
  void TearDown() override {
    std::error_code ec;
    fs::remove_all(dir_, ec);
  }
  fs::path dir_;
};

TEST(RunOutputFormat, CsvLines) {
  EXPECT_EQ(csvLine(std::vector<double>{0, 0.1, 86400, 1e-7, std::nan("")}),
            "0,0.1,86400,1e-7,nan");
  EXPECT_EQ(csvLine(std::vector<std::string>{"t_s", "steps"}), "t_s,steps");
  EXPECT_EQ(csvLine(std::vector<double>{}), "");
}

TEST(RunOutputFormat, ReducedParameters) {
  const SceneSpec s = resolve(SceneSpec{});
  const nlohmann::json j = reducedParameters(s);
  EXPECT_DOUBLE_EQ(j.at("tau_gamma_s").get<double>(), 10.0);
  EXPECT_NEAR(j.at("pa_reduced").get<double>(), 0.33, 0.001);
  EXPECT_EQ(j.at("alpha").get<double>(), 0.4375);
  EXPECT_NEAR(j.at("l_eta_reduced").get<double>(), 0.50, 0.01);
  EXPECT_EQ(j.at("tau_p_s").get<double>(), 600.0);
  EXPECT_EQ(j.at("n_cells"), 200);
  SceneSpec dry = s;
  dry.cells.xi = 0;
  EXPECT_TRUE(reducedParameters(dry).at("l_eta_reduced").is_null());
}

TEST(RunOutputFormat, SummaryJson) {
  const SceneSpec s = resolve(SceneSpec{});
  RunSummary sum;
  sum.t_s = 100;
  sum.steps = 1000;
  sum.wall_s = 2.5;
  sum.cg_iters_mean = 3.25;
  sum.remesh_ops = 12;
  sum.final_values = {{"theta_deg", 45.0}, {"neck_radius_um", std::nan("")}};
  sum.phase_wall_s = {{"solve", 1.5}};
  SummaryContext ctx;
  ctx.samples_written = 3;
  nlohmann::json j = summaryToJson(sum, s, ctx);
  EXPECT_EQ(j.at("ok"), true);
  EXPECT_EQ(j.at("cancelled"), false);
  EXPECT_EQ(j.at("steps"), 1000);
  EXPECT_EQ(j.at("remesh_ops"), 12);
  EXPECT_EQ(j.at("final_values").at("theta_deg"), 45.0);
  EXPECT_TRUE(j.at("final_values").at("neck_radius_um").is_null());  // nan → null
  EXPECT_EQ(j.at("phase_wall_s").at("solve"), 1.5);
  EXPECT_EQ(j.at("engine_version"), ACTIVEFOAM_VERSION);
  EXPECT_EQ(j.at("seed"), 1);
  EXPECT_EQ(j.at("scene"), "fusion");
  EXPECT_EQ(j.at("samples"), 3);
  EXPECT_EQ(j.at("reason"), "");
  // JSON text that a strict parser accepts.
  EXPECT_TRUE(nlohmann::json::accept(j.dump()));

  sum.failure = FailureKind::Cancelled;
  j = summaryToJson(sum, s, ctx);
  EXPECT_EQ(j.at("ok"), false);
  EXPECT_EQ(j.at("cancelled"), true);
  EXPECT_EQ(j.at("failure"), std::string(toString(FailureKind::Cancelled)));

  sum.failure = FailureKind::None;
  ctx.failure_override = "exception";
  ctx.reason_override = "engine error: boom";
  j = summaryToJson(sum, s, ctx);
  EXPECT_EQ(j.at("ok"), false);
  EXPECT_EQ(j.at("failure"), "exception");
  EXPECT_EQ(j.at("reason"), "engine error: boom");
  EXPECT_FALSE(j.contains("curves"));
}

// The probes' curves go into summary.json by name beside the MSRD, and flattenSummary (foamd's
// pool and Slurm tasks alike) brings every one back as the store keeps them: "msrd" first, then
// the others; a curve without points stays a curve.
TEST(RunOutputFormat, SummaryJsonCarriesTheProbesCurves) {
  const SceneSpec s = resolve(SceneSpec{});
  RunSummary sum;
  sum.msrd = {{30, 0.5}, {60, 0.75}};
  sum.curves = {{"msrd_surface", {30, 60}, {0.25, std::nan("")}}, {"msrd_buried", {}, {}}};
  const nlohmann::json j = summaryToJson(sum, s, {});
  EXPECT_EQ(j.at("msrd").at("lag_s"), nlohmann::json::parse("[30, 60]"));
  EXPECT_EQ(j.at("curves").at("msrd_surface").at("x"), nlohmann::json::parse("[30, 60]"));
  EXPECT_TRUE(j.at("curves").at("msrd_surface").at("y").at(1).is_null());
  EXPECT_TRUE(j.at("curves").at("msrd_buried").at("x").empty());
  const FlatResults flat = flattenSummary(nlohmann::json::parse(j.dump()));
  ASSERT_EQ(flat.curves.size(), 3u);
  EXPECT_EQ(flat.curves[0].name, "msrd");
  EXPECT_EQ(flat.curves[0].y, (std::vector<double>{0.5, 0.75}));
  std::map<std::string, FlatCurve> by_name;
  for (const FlatCurve& c : flat.curves) by_name[c.name] = c;
  EXPECT_EQ(by_name.at("msrd_surface").x, (std::vector<double>{30, 60}));
  EXPECT_EQ(by_name.at("msrd_surface").y[0], 0.25);
  EXPECT_TRUE(std::isnan(by_name.at("msrd_surface").y[1]));
  EXPECT_TRUE(by_name.at("msrd_buried").x.empty() && by_name.at("msrd_buried").y.empty());
  // A malformed entry is left out, the others kept.
  nlohmann::json bad = j;
  bad["curves"]["msrd_mixed"] = {{"x", {1, 2}}, {"y", {1}}};
  EXPECT_EQ(flattenSummary(bad).curves.size(), 3u);
}

TEST_F(RunOutputTest, AtomicWriteReplacesWholeFiles) {
  const fs::path p = dir_ / "summary.json";
  writeFileAtomic(p, "one");
  EXPECT_EQ(readFile(p), "one");
  writeFileAtomic(p, "two, longer");
  EXPECT_EQ(readFile(p), "two, longer");
  EXPECT_FALSE(fs::exists(dir_ / "summary.json.tmp"));
  EXPECT_THROW(writeFileAtomic(dir_ / "missing" / "x.json", "x"), std::runtime_error);
}

TEST_F(RunOutputTest, OutputDirRules) {
  EXPECT_EQ(checkOutputDir(dir_ / "new", false), "");
  EXPECT_EQ(checkOutputDir(dir_, false), "");  // exists, empty
  std::ofstream(dir_ / "x") << "x";
  EXPECT_NE(checkOutputDir(dir_, false).find("not empty"), std::string::npos);
  EXPECT_EQ(checkOutputDir(dir_, true), "");
  EXPECT_NE(checkOutputDir(dir_ / "x", true).find("not a directory"), std::string::npos);
}

TEST_F(RunOutputTest, StreamsSamplesAndSnapshots) {
  SceneSpec spec;
  spec.scene = SceneKind::Cell;
  spec = resolve(spec);
  RunOutput out(dir_, spec);
  out.start();
  ASSERT_EQ(out.error(), "");
  const std::size_t ncols = sampleColumns(spec).size();
  Sample a;
  a.values.assign(ncols, 1.5);
  out.onSample(a);
  Sample short_row;
  short_row.values = {2.0};
  out.onSample(short_row);  // padded, with a warning
  EXPECT_NE(out.warning(), "");
  EXPECT_EQ(out.samplesWritten(), 2);

  Snapshot snap;
  snap.x.resize(3, 3);
  snap.x << 0, 1, 0, 0, 0, 1, 0, 0, 0;
  snap.tri = {{0, 1, 2}};
  snap.vertex_cell = {0, 0, 0};
  out.onSnapshot(snap);
  snap.t_s = 60;
  out.onSnapshot(snap);
  EXPECT_EQ(out.snapshotsWritten(), 2);
  EXPECT_EQ(out.error(), "");

  const std::string csv = readFile(dir_ / "samples.csv");
  std::istringstream in(csv);
  std::string header, row1, row2;
  std::getline(in, header);
  std::getline(in, row1);
  std::getline(in, row2);
  EXPECT_EQ(header, csvLine(sampleColumns(spec)));
  EXPECT_EQ(row1, csvLine(a.values));
  EXPECT_EQ(row2.substr(0, 4), "2,na");
  EXPECT_TRUE(fs::exists(dir_ / "snapshots" / "snap_000001.vtp"));
  const std::string pvd = readFile(dir_ / "snapshots" / "series.pvd");
  EXPECT_NE(pvd.find("timestep=\"60\""), std::string::npos);

  const auto back = parseSpecText(readFile(dir_ / "spec.json"));
  ASSERT_TRUE(back.ok());
  EXPECT_EQ(*back.spec, spec);

  out.writeSummary(nlohmann::json{{"ok", true}});
  EXPECT_EQ(nlohmann::json::parse(readFile(dir_ / "summary.json")).at("ok"), true);
}

}  // namespace
}  // namespace activefoam
