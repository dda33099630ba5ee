// The foam-run binary: exit codes, messages, and what it leaves in the output folder.
#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "activefoam/run.h"
#include "activefoam/run_output.h"
#include "activefoam/spec.h"
#include "activefoam/spec_io.h"
#include "test_files.h"

extern char** environ;

namespace activefoam {
namespace {

namespace fs = std::filesystem;

using testing::lines;
using testing::readFile;
using testing::writeFile;

// A spec of the scene with no probes: the scene's own columns.
SceneSpec specOf(SceneKind scene) {
  SceneSpec s;
  s.scene = scene;
  return s;
}

std::string quote(const std::string& s) {
  std::string q = "'";
  for (char c : s) q += c == '\'' ? std::string("'\\''") : std::string(1, c);
  return q + "'";
}

struct Result {
  int code = -1;
  std::string out, err;
};

class FoamRun : public ::testing::Test {
 protected:
  void SetUp() override {
    std::string tmpl = (fs::temp_directory_path() / "foam_run_test_XXXXXX").string();
    ASSERT_NE(mkdtemp(tmpl.data()), nullptr);
    dir_ = tmpl;
  }
  void TearDown() override {
    std::error_code ec;
    fs::remove_all(dir_, ec);
  }

  // Runs foam-run with `args` (already quoted where needed); stdin from `input` if given.
  Result run(const std::string& args, const std::string* input = nullptr) {
    const fs::path out = dir_ / "stdout.txt", err = dir_ / "stderr.txt";
    std::string cmd = quote(FOAM_RUN_EXE) + " " + args;
    if (input) {
      writeFile(dir_ / "stdin.txt", *input);
      cmd += " < " + quote((dir_ / "stdin.txt").string());
    }
    cmd += " > " + quote(out.string()) + " 2> " + quote(err.string());
    const int status = std::system(cmd.c_str());
    Result r;
    r.code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
    r.out = readFile(out);
    r.err = readFile(err);
    return r;
  }

  fs::path spec(const std::string& text, const std::string& name = "spec.toml") {
    const fs::path p = dir_ / name;
    writeFile(p, text);
    return p;
  }

  fs::path dir_;
};

// ---- invalid input: exit 2, one line per error naming the key, nothing created --------------

struct BadSpec {
  const char* text;
  const char* key;
};

const BadSpec kBad[] = {
    {"scene = \"cell\"\n[numerics]\ndt_s = -1\n", "numerics.dt_s"},
    {"scene = \"cell\"\n[cells]\ngamma = nan\n", "cells.gamma"},
    {"scene = \"cell\"\n[cells]\ngama = 0.5\n", "cells.gama"},
    {"scene = \"blob\"\n", "scene"},
    {"seed = 2\n", "scene"},
    {"[scene]\nkind = \"spheroid\"\nn_cells = 1e9\n", "scene.n_cells"},
    {"scene = \"cell\"\nduration_s = 1e12\n", "duration_s"},
    {"scene = \"cell\"\n[numerics]\ntriangles_per_cell = 100\n", "numerics.triangles_per_cell"},
    {"scene = \"cell\"\n[mesh]\nx = 1\n", "mesh"},
    {"scene = \"cell\"\nduration_s = 10\nsample_every_s = 60\n", "sample_every_s"},
    // [scene] keys that the scene does not read: a mistake about what runs.
    {"scene = \"cell\"\n[scene]\nn_cells = 20\n", "scene.n_cells"},
    {"scene = \"doublet\"\n[scene]\naxes_ratio = 2\n", "scene.axes_ratio"},
    {"scene = \"spheroid\"\n[scene]\ngap_um = 0.01\n", "scene.gap_um"},
    // A probe where its scene gives it no meaning: a doublet's two centroids fix no turn.
    {"scene = \"doublet\"\n[observe]\nrigid_motion = true\n", "observe.rigid_motion"},
    {"scene = \"cell\"\n[observe]\ndissipation = 1\n", "observe.dissipation"},
    // The MSRD is a fusion's: a spheroid has no neighbours' MSRD to split.
    {"scene = \"spheroid\"\n[observe]\nmsrd_by_depth = true\n", "observe.msrd_by_depth"},
    // The cells of an aggregate (spheroid, fusion); the turn of two fused ones.
    {"scene = \"doublet\"\n[observe]\nshape = true\n", "observe.shape"},
    {"scene = \"spheroid\"\n[observe]\ntorque = true\n", "observe.torque"},
    {"scene = \"cell\"\n[observ]\ndissipation = true\n", "observ"},
};

TEST_F(FoamRun, InvalidSpecExits2NamingTheKeyAndWritesNothing) {
  for (const BadSpec& b : kBad) {
    const fs::path s = spec(b.text);
    const fs::path out = dir_ / "out";
    const Result r = run(quote(s.string()) + " --out " + quote(out.string()));
    EXPECT_EQ(r.code, 2) << b.text << r.err;
    const auto l = lines(r.err);
    ASSERT_EQ(l.size(), 1u) << b.text << r.err;
    EXPECT_EQ(l[0].rfind("foam-run: invalid spec: " + std::string(b.key) + ": ", 0), 0u) << l[0];
    EXPECT_FALSE(fs::exists(out)) << b.text;
  }
}

// A gap beyond the adhesion range runs (a study may want it) but is named on stderr: foamd
// refuses the same spec (SpecConvert.AGapBeyondTheAdhesionRangeIsRefusedAndTheDefaultIsInsideIt).
TEST_F(FoamRun, AGapBeyondTheAdhesionRangeRunsWithAWarning) {
  const fs::path s = spec(
      "scene = \"doublet\"\nduration_s = 1\nsample_every_s = 0.5\nsnapshot_every_s = 0\n"
      "[cells]\nalpha = 0.9\n[scene]\ngap_um = 0.05\n[numerics]\ntriangles_per_cell = 80\n"
      "dt_s = 0.1\n");
  const Result r = run(quote(s.string()) + " -q --out " + quote((dir_ / "o").string()));
  EXPECT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.err.find("foam-run: warning: scene.gap_um: 0.05 µm is at or beyond the adhesion "
                       "range h0 = √(w/k_AB) = 0.0265"),
            std::string::npos)
      << r.err;
  EXPECT_NE(r.err.find("running anyway"), std::string::npos) << r.err;
  EXPECT_TRUE(fs::exists(dir_ / "o" / "summary.json"));
}

TEST_F(FoamRun, TheDesignExampleMessage) {
  const fs::path s = spec("scene = \"cell\"\n[numerics]\ndt_s = -1\n");
  const Result r = run(quote(s.string()) + " --out " + quote((dir_ / "o").string()));
  EXPECT_EQ(r.err,
            "foam-run: invalid spec: numerics.dt_s: -1 is outside the allowed range (0, 10] s\n");
}

TEST_F(FoamRun, EveryErrorGetsItsLine) {
  const fs::path s =
      spec("scene = \"cell\"\nseed = -1\n[cells]\ngamma = 0\n[numerics]\ndt_s = 0\n");
  const Result r = run(quote(s.string()) + " --out " + quote((dir_ / "o").string()));
  EXPECT_EQ(r.code, 2);
  EXPECT_EQ(lines(r.err).size(), 3u) << r.err;
  EXPECT_FALSE(fs::exists(dir_ / "o"));
}

TEST_F(FoamRun, InvalidSetExits2) {
  const fs::path s = spec("scene = \"cell\"\n");
  const Result r =
      run(quote(s.string()) + " --out " + quote((dir_ / "o").string()) + " --set cells.alpha=2");
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("cells.alpha: 2 is outside the allowed range [0, 1)"), std::string::npos)
      << r.err;
  EXPECT_FALSE(fs::exists(dir_ / "o"));
}

TEST_F(FoamRun, MalformedSpecGivesLineAndColumn) {
  const fs::path s = spec("scene = \"cell\"\n[cells\n");
  const Result r = run(quote(s.string()) + " --out " + quote((dir_ / "o").string()));
  EXPECT_EQ(r.code, 2);
  ASSERT_EQ(lines(r.err).size(), 1u) << r.err;
  EXPECT_NE(r.err.find("line 2"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(dir_ / "o"));
}

TEST_F(FoamRun, MissingSpecFile) {
  const Result r =
      run(quote((dir_ / "nope.toml").string()) + " --out " + quote((dir_ / "o").string()));
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("nope.toml"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(dir_ / "o"));
}

TEST_F(FoamRun, UsageErrors) {
  EXPECT_EQ(run("").code, 2);
  const fs::path s = spec("scene = \"cell\"\n");
  EXPECT_EQ(run(quote(s.string())).code, 2);  // no --out
  EXPECT_EQ(run(quote(s.string()) + " --out").code, 2);
  EXPECT_EQ(run(quote(s.string()) + " --out x --frobnicate").code, 2);
  EXPECT_EQ(run(quote(s.string()) + " " + quote(s.string()) + " --out x").code, 2);
  EXPECT_FALSE(fs::exists("x"));
}

TEST_F(FoamRun, HelpVersionKeys) {
  Result r = run("--help");
  EXPECT_EQ(r.code, 0);
  EXPECT_NE(r.out.find("usage: foam-run"), std::string::npos);
  r = run("--version");
  EXPECT_EQ(r.code, 0);
  EXPECT_EQ(r.out, std::string("foam-run ") + ACTIVEFOAM_VERSION + "\n");
  r = run("--keys");
  EXPECT_EQ(r.code, 0);
  for (const SpecField& f : specFields()) EXPECT_NE(r.out.find(f.key + " = "), std::string::npos);
  // The key table's history, said where it applies: the contact law's value before the key,
  // what the preparation runs it at, the scenes that read it.
  const auto law = r.out.find("numerics.contact_law = \"prisms-overlap\"");
  ASSERT_NE(law, std::string::npos) << r.out;
  EXPECT_NE(r.out.find("(before it existed: \"supplement\"; spheroid preparation: \"supplement\"; "
                       "read by: doublet, spheroid, fusion)",
                       law),
            std::string::npos)
      << r.out.substr(law, 400);
  // Which keys [prepare] takes: those the preparation otherwise takes from the run.
  const auto xi = r.out.find("cells.xi = ");
  ASSERT_NE(xi, std::string::npos);
  EXPECT_NE(r.out.substr(xi, r.out.find("cells.xi_normal", xi) - xi).find("[prepare] may give"),
            std::string::npos)
      << r.out.substr(xi, 400);
  const auto dt = r.out.find("numerics.dt_s = ");
  EXPECT_EQ(r.out.substr(dt, r.out.find("numerics.integrator", dt) - dt).find("[prepare]"),
            std::string::npos);
  EXPECT_NE(r.out.find("[prepare] (fusion)"), std::string::npos);
}

TEST_F(FoamRun, RefusesANonEmptyOutputDir) {
  const fs::path out = dir_ / "o";
  fs::create_directories(out);
  writeFile(out / "keep.txt", "mine");
  const fs::path s = spec("scene = \"cell\"\nduration_s = 5\nsample_every_s = 1\n");
  const Result r = run(quote(s.string()) + " --out " + quote(out.string()));
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("not empty"), std::string::npos) << r.err;
  EXPECT_EQ(readFile(out / "keep.txt"), "mine");
  EXPECT_FALSE(fs::exists(out / "spec.json"));
}

// ---- end to end (needs the engine's runScene) --------------------------------------------------

constexpr const char* kCell =
    "scene = \"cell\"\nduration_s = 5\nsample_every_s = 1\nsnapshot_every_s = 0\n"
    "[numerics]\ntriangles_per_cell = 80\ndt_s = 0.1\n";

void expectCompleteOutput(const fs::path& out, SceneKind scene, std::size_t rows) {
  ASSERT_TRUE(fs::exists(out / "spec.json"));
  ASSERT_TRUE(fs::exists(out / "samples.csv"));
  ASSERT_TRUE(fs::exists(out / "summary.json"));
  const auto csv = lines(readFile(out / "samples.csv"));
  ASSERT_EQ(csv.size(), rows + 1);
  std::string header;
  for (const std::string& c : sampleColumns(specOf(scene)))
    header += (header.empty() ? "" : ",") + c;
  EXPECT_EQ(csv[0], header);
  const std::size_t ncols = sampleColumns(specOf(scene)).size();
  for (std::size_t i = 1; i < csv.size(); ++i)
    EXPECT_EQ(static_cast<std::size_t>(std::count(csv[i].begin(), csv[i].end(), ',')) + 1, ncols)
        << csv[i];
  const auto summary = nlohmann::json::parse(readFile(out / "summary.json"));
  EXPECT_EQ(summary.at("ok"), true);
  EXPECT_EQ(summary.at("engine_version"), ACTIVEFOAM_VERSION);
  for (const char* k : {"failure", "reason", "t_s", "steps", "wall_s", "cg_iters_mean",
                        "remesh_ops", "final_values", "phase_wall_s", "seed", "reduced"})
    EXPECT_TRUE(summary.contains(k)) << k;
  for (const char* k : {"tau_gamma_s", "pa_reduced", "alpha", "l_eta_reduced", "tau_p_s"})
    EXPECT_TRUE(summary.at("reduced").contains(k)) << k;
  EXPECT_TRUE(summary.at("final_values").is_object());
  EXPECT_FALSE(fs::exists(out / "summary.json.tmp"));
}

TEST_F(FoamRun, CellSceneEndToEnd) {
  const fs::path s = spec(kCell);
  const fs::path out = dir_ / "out";
  const Result r = run(quote(s.string()) + " --out " + quote(out.string()) + " --quiet");
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_EQ(r.err, "");  // --quiet
  expectCompleteOutput(out, SceneKind::Cell, 6);
  const auto summary = nlohmann::json::parse(readFile(out / "summary.json"));
  EXPECT_NEAR(summary.at("t_s").get<double>(), 5.0, 1e-9);
  EXPECT_EQ(summary.at("steps"), 50);
  EXPECT_EQ(summary.at("seed"), 1);
  // spec.json is the resolved spec and reads back to it.
  const auto parsed = parseSpecText(readFile(out / "spec.json"));
  ASSERT_TRUE(parsed.ok());
  const auto expected = validateAndResolve(*parseSpecText(kCell).spec);
  ASSERT_TRUE(expected.ok());
  EXPECT_EQ(*parsed.spec, *expected.spec);
  EXPECT_FALSE(fs::exists(out / "snapshots"));  // snapshot_every_s = 0
}

TEST_F(FoamRun, DoubletReportsContactAnglePerSample) {
  const std::string text =
      "scene = \"doublet\"\nduration_s = 300\nsample_every_s = 50\n"
      "[cells]\nradius_gamma_k = 0\np_a = 0\n";
  const fs::path out = dir_ / "out";
  const Result r = run("- --out " + quote(out.string()) + " --quiet", &text);
  ASSERT_EQ(r.code, 0) << r.err;
  expectCompleteOutput(out, SceneKind::Doublet, 7);
  const auto rows = lines(readFile(out / "samples.csv"));
  const auto cols = sampleColumns(specOf(SceneKind::Doublet));
  const auto at = std::find(cols.begin(), cols.end(), "contact_angle_deg") - cols.begin();
  ASSERT_LT(at, static_cast<long>(cols.size()));
  // The angle starts at 0 (cells apart) and has opened towards arccos α = 64° by t = 300 s.
  auto angle = [&](const std::string& row) {
    std::stringstream ss(row);
    std::string cell;
    for (long k = 0; k <= at; ++k) std::getline(ss, cell, ',');
    return std::stod(cell);
  };
  EXPECT_EQ(angle(rows[1]), 0.0);
  EXPECT_GT(angle(rows.back()), 30.0);
  EXPECT_LT(angle(rows.back()), 70.0);
}

// A probe's columns follow the scene's in samples.csv, with its values (no step yet at t = 0),
// and the probe is in spec.json.
TEST_F(FoamRun, ProbeColumnsReachSamplesCsv) {
  const std::string text = std::string(kCell) + "[observe]\ndissipation = true\n";
  const fs::path out = dir_ / "out";
  const Result r = run(quote(spec(text).string()) + " --out " + quote(out.string()) + " --quiet");
  ASSERT_EQ(r.code, 0) << r.err;
  const auto parsed = parseSpecText(readFile(out / "spec.json"));
  ASSERT_TRUE(parsed.ok());
  EXPECT_TRUE(parsed.spec->observe.dissipation);
  const std::vector<std::string> cols = sampleColumns(*parsed.spec);
  const std::vector<std::string> scene = sampleColumns(specOf(SceneKind::Cell));
  ASSERT_EQ(cols.size(), scene.size() + 14);  // the dissipation probe's 14 columns
  const auto csv = lines(readFile(out / "samples.csv"));
  ASSERT_EQ(csv.size(), 7u);
  EXPECT_EQ(csv[0], csvLine(cols));
  auto field = [&](const std::string& row, std::size_t k) {
    std::stringstream ss(row);
    std::string cell;
    for (std::size_t i = 0; i <= k; ++i) std::getline(ss, cell, ',');
    return cell;
  };
  const std::size_t medium = scene.size(), forces = scene.size() + 5;
  EXPECT_EQ(cols[medium], "diss_medium_nw");
  EXPECT_EQ(field(csv[1], medium), "nan");
  for (std::size_t row = 2; row < csv.size(); ++row) {
    EXPECT_GT(std::stod(field(csv[row], medium)), 0) << csv[row];
    EXPECT_GT(std::stod(field(csv[row], forces)), 0) << csv[row];
  }
}

TEST_F(FoamRun, OverridesStdinAndSnapshots) {
  const std::string text = "{\"scene\": \"cell\", \"duration_s\": 50}";
  const fs::path out = dir_ / "out";
  const Result r = run("- --out " + quote(out.string()) +
                           " --quiet --set duration_s=2 --set sample_every_s=0.5"
                           " --set snapshot_every_s=1 --set numerics.triangles_per_cell=80"
                           " --set seed=7 --set numerics.dt_s=0.1",
                       &text);
  ASSERT_EQ(r.code, 0) << r.err;
  expectCompleteOutput(out, SceneKind::Cell, 5);
  const auto spec_json = nlohmann::json::parse(readFile(out / "spec.json"));
  EXPECT_EQ(spec_json.at("duration_s"), 2.0);
  EXPECT_EQ(spec_json.at("seed"), 7);
  // Snapshots at t = 0, 1, 2 and an index naming them.
  for (const char* f : {"snap_000000.vtp", "snap_000001.vtp", "snap_000002.vtp", "series.pvd"})
    EXPECT_TRUE(fs::exists(out / "snapshots" / f)) << f;
  const std::string pvd = readFile(out / "snapshots" / "series.pvd");
  EXPECT_NE(pvd.find("file=\"snap_000002.vtp\""), std::string::npos) << pvd;
  const std::string vtp = readFile(out / "snapshots" / "snap_000000.vtp");
  EXPECT_NE(vtp.find("<VTKFile type=\"PolyData\""), std::string::npos);
  EXPECT_NE(vtp.find("NumberOfPolys=\"80\""), std::string::npos);
}

TEST_F(FoamRun, ForceReplacesAnEarlierRun) {
  const fs::path s = spec(kCell);
  const fs::path out = dir_ / "out";
  ASSERT_EQ(run(quote(s.string()) + " --out " + quote(out.string()) + " -q").code, 0);
  EXPECT_EQ(run(quote(s.string()) + " --out " + quote(out.string()) + " -q").code, 2);
  const Result r =
      run(quote(s.string()) + " --out " + quote(out.string()) + " -q --force --set duration_s=3");
  ASSERT_EQ(r.code, 0) << r.err;
  expectCompleteOutput(out, SceneKind::Cell, 4);
}

TEST_F(FoamRun, SigintCancelsWithExit130AndASummary) {
  const fs::path s = spec(
      "scene = \"cell\"\nduration_s = 1e6\nsample_every_s = 1\nsnapshot_every_s = 0\n"
      "[numerics]\ntriangles_per_cell = 80\n");
  const fs::path out = dir_ / "out";
  const std::string exe = FOAM_RUN_EXE, spec_path = s.string(), out_path = out.string();
  std::vector<char*> argv{const_cast<char*>(exe.c_str()), const_cast<char*>(spec_path.c_str()),
                          const_cast<char*>("--out"),     const_cast<char*>(out_path.c_str()),
                          const_cast<char*>("--quiet"),   nullptr};
  pid_t pid = 0;
  ASSERT_EQ(posix_spawn(&pid, exe.c_str(), nullptr, nullptr, argv.data(), environ), 0);
  // Wait until it is running (the header of samples.csv is written before the engine starts).
  const auto t0 = std::chrono::steady_clock::now();
  while (!fs::exists(out / "samples.csv") &&
         std::chrono::steady_clock::now() - t0 < std::chrono::seconds(30))
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  std::this_thread::sleep_for(std::chrono::milliseconds(500));
  kill(pid, SIGINT);
  int status = 0;
  const auto t1 = std::chrono::steady_clock::now();
  while (waitpid(pid, &status, WNOHANG) == 0) {
    if (std::chrono::steady_clock::now() - t1 > std::chrono::seconds(30)) {
      kill(pid, SIGKILL);
      waitpid(pid, &status, 0);
      FAIL() << "foam-run did not stop within 30 s of SIGINT";
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  ASSERT_TRUE(WIFEXITED(status));
  EXPECT_EQ(WEXITSTATUS(status), 130);
  const auto summary = nlohmann::json::parse(readFile(out / "summary.json"));
  EXPECT_EQ(summary.at("ok"), false);
  EXPECT_EQ(summary.at("cancelled"), true);
  EXPECT_LT(summary.at("t_s").get<double>(), 1e6);
  // Every row is complete.
  const auto csv = lines(readFile(out / "samples.csv"));
  for (std::size_t i = 1; i < csv.size(); ++i)
    EXPECT_EQ(static_cast<std::size_t>(std::count(csv[i].begin(), csv[i].end(), ',')) + 1,
              sampleColumns(specOf(SceneKind::Cell)).size());
}

// ---- interrupted runs continue from their checkpoint ------------------------------------------

namespace resume {

// Spawns foam-run, sends SIGINT once samples.csv holds `rows` data rows, waits; the exit code
// (or -1).
int runAndInterrupt(const std::vector<std::string>& args, const fs::path& out, std::size_t rows) {
  std::vector<std::string> all{FOAM_RUN_EXE};
  all.insert(all.end(), args.begin(), args.end());
  std::vector<char*> argv;
  for (std::string& a : all) argv.push_back(a.data());
  argv.push_back(nullptr);
  pid_t pid = 0;
  if (posix_spawn(&pid, argv[0], nullptr, nullptr, argv.data(), environ) != 0) return -1;
  const auto t0 = std::chrono::steady_clock::now();
  int status = 0;
  while (waitpid(pid, &status, WNOHANG) == 0) {
    if (fs::exists(out / "samples.csv") && lines(readFile(out / "samples.csv")).size() > rows) {
      kill(pid, SIGINT);
      waitpid(pid, &status, 0);
      break;
    }
    if (std::chrono::steady_clock::now() - t0 > std::chrono::seconds(120)) {
      kill(pid, SIGKILL);
      waitpid(pid, &status, 0);
      return -1;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

// samples.csv without its wall-clock column.
std::vector<std::string> physicsRows(const fs::path& csv) {
  std::vector<std::string> rows;
  for (const std::string& line : lines(readFile(csv))) {
    std::stringstream ss(line);
    std::string cell, kept;
    for (int k = 0; std::getline(ss, cell, ','); ++k)
      if (k != 2) kept += cell + ",";  // t_s, steps, wall_s, ...
    rows.push_back(kept);
  }
  return rows;
}

}  // namespace resume

TEST_F(FoamRun, InterruptedRunResumesToTheUninterruptedResult) {
  ASSERT_EQ(sampleColumns(specOf(SceneKind::Doublet))[2], "wall_s");
  const fs::path s = spec(
      "scene = \"doublet\"\nduration_s = 200\nsample_every_s = 5\nsnapshot_every_s = 20\n"
      "[cells]\nradius_gamma_k = 0\n");
  const fs::path whole = dir_ / "whole", parts = dir_ / "parts";
  ASSERT_EQ(run(quote(s.string()) + " --out " + quote(whole.string()) + " -q").code, 0);
  EXPECT_FALSE(fs::exists(whole / "checkpoint.bin"));  // finished runs keep none

  // Interrupted after a few samples: exit 130 with a checkpoint; then resumed, twice over.
  ASSERT_EQ(resume::runAndInterrupt({s.string(), "--out", parts.string(), "-q"}, parts, 6), 130);
  ASSERT_TRUE(fs::exists(parts / "checkpoint.bin"));
  ASSERT_EQ(resume::runAndInterrupt(
                {s.string(), "--out", parts.string(), "-q", "--resume", "--checkpoint-every", "0"},
                parts, 20),
            130);
  // The wrong spec is refused, naming the key, and leaves the folder as it was.
  const std::string before = readFile(parts / "samples.csv");
  Result r = run(quote(s.string()) + " --out " + quote(parts.string()) +
                 " --resume --set cells.alpha=0.5");
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("cells.alpha"), std::string::npos) << r.err;
  EXPECT_EQ(readFile(parts / "samples.csv"), before);
  r = run(quote(s.string()) + " --out " + quote(parts.string()) + " --resume");
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.err.find("resuming from the checkpoint"), std::string::npos) << r.err;

  // Same samples (wall clock aside), same snapshots, the same final values; no checkpoint left.
  EXPECT_EQ(resume::physicsRows(parts / "samples.csv"), resume::physicsRows(whole / "samples.csv"));
  EXPECT_FALSE(fs::exists(parts / "checkpoint.bin"));
  for (const char* f : {"snap_000000.vtp", "snap_000005.vtp", "series.pvd"})
    EXPECT_EQ(readFile(parts / "snapshots" / f), readFile(whole / "snapshots" / f)) << f;
  EXPECT_FALSE(fs::exists(parts / "snapshots" / "snap_000011.vtp"));
  const auto a = nlohmann::json::parse(readFile(whole / "summary.json"));
  const auto b = nlohmann::json::parse(readFile(parts / "summary.json"));
  EXPECT_EQ(a.at("final_values"), b.at("final_values"));
  EXPECT_EQ(a.at("steps"), b.at("steps"));
  EXPECT_GT(b.at("resumed_from_t_s").get<double>(), 0.0);

  // A finished run is left alone; --force and --resume do not mix.
  r = run(quote(s.string()) + " --out " + quote(parts.string()) + " --resume");
  EXPECT_EQ(r.code, 0);
  EXPECT_NE(r.err.find("finished run"), std::string::npos) << r.err;
  EXPECT_EQ(run(quote(s.string()) + " --out " + quote(parts.string()) + " --resume --force").code,
            2);
}

// foam-run's checkpoint.bin is sealed as a whole: every flipped bit of its header (the sample
// count among them: "samples":13 → 12 once dropped a sample in silence) and a sample of its
// state's bits is refused as damaged, and --resume on a damaged file exits 2 naming it, the
// folder untouched.
TEST_F(FoamRun, EveryFlippedBitOfACheckpointIsRefused) {
  const fs::path s = spec(
      "scene = \"doublet\"\nduration_s = 200\nsample_every_s = 5\nsnapshot_every_s = 0\n"
      "[cells]\nradius_gamma_k = 0\n[numerics]\ntriangles_per_cell = 80\ndt_s = 0.1\n");
  const fs::path out = dir_ / "cut";
  ASSERT_EQ(resume::runAndInterrupt({s.string(), "--out", out.string(), "-q"}, out, 6), 130);
  const std::string good = readFile(out / "checkpoint.bin");
  ASSERT_NO_THROW(decodeRunCheckpoint(good, "checkpoint.bin"));
  const std::size_t header_bits = 8 * (good.find('\n', good.find('\n') + 1) + 1);
  std::size_t tried = 0;
  for (std::size_t bit = 0; bit < 8 * good.size(); bit += bit < header_bits ? 1 : 101) {
    std::string damaged = good;
    damaged[bit / 8] = static_cast<char>(damaged[bit / 8] ^ (1 << (bit % 8)));
    EXPECT_THROW(decodeRunCheckpoint(damaged, "checkpoint.bin"), std::runtime_error)
        << "bit " << bit;
    ++tried;
  }
  EXPECT_GT(tried, header_bits);
  std::string damaged = good;
  damaged[good.size() / 2] = static_cast<char>(damaged[good.size() / 2] ^ 1);
  writeFile(out / "checkpoint.bin", damaged);
  const std::string before = readFile(out / "samples.csv");
  const Result r = run(quote(s.string()) + " --out " + quote(out.string()) + " --resume");
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("checkpoint.bin is damaged (its checksum does not match"), std::string::npos)
      << r.err;
  EXPECT_EQ(readFile(out / "samples.csv"), before);
}

// A spec is read to at most 1 MiB: /dev/zero and an endless pipe are refused at once, naming the
// input and the cap (they once aborted with bad_alloc).
TEST_F(FoamRun, UnboundedSpecInputIsRefusedAtItsCap) {
  Result r = run("/dev/zero --out " + quote((dir_ / "z").string()));
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("'/dev/zero' holds more than 1 MiB"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(dir_ / "z" / "spec.json"));
  const std::string cmd = "yes | timeout 30 " + quote(FOAM_RUN_EXE) + " - --out " +
                          quote((dir_ / "y").string()) + " 2> " + quote((dir_ / "y.err").string());
  const int status = std::system(cmd.c_str());
  EXPECT_EQ(WIFEXITED(status) ? WEXITSTATUS(status) : -1, 2);
  const std::string err = readFile(dir_ / "y.err");
  EXPECT_NE(err.find("standard input holds more than 1 MiB"), std::string::npos) << err;
}

TEST_F(FoamRun, ResumeWithoutCheckpointStartsOverAndADamagedOneIsRefused) {
  const fs::path s = spec(kCell);
  const fs::path out = dir_ / "out";
  fs::create_directories(out);
  writeFile(out / "samples.csv", "left over\n");
  Result r = run(quote(s.string()) + " --out " + quote(out.string()) + " --resume");
  ASSERT_EQ(r.code, 0) << r.err;
  EXPECT_NE(r.err.find("starting over"), std::string::npos) << r.err;
  expectCompleteOutput(out, SceneKind::Cell, 6);

  fs::remove(out / "summary.json");
  writeFile(out / "checkpoint.bin", "activefoam-run-checkpoint 1\n{\"t_s\": 1}\n");
  r = run(quote(s.string()) + " --out " + quote(out.string()) + " --resume");
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("checkpoint.bin is damaged"), std::string::npos) << r.err;
  EXPECT_EQ(lines(readFile(out / "samples.csv")).size(), 7u);  // untouched
  EXPECT_EQ(
      run(quote(s.string()) + " --out " + quote(out.string()) + " --checkpoint-every -1").code, 2);
}

}  // namespace
}  // namespace activefoam
