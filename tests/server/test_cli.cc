// foam + foamd as processes: the CLI end to end, and kill -9 / restart of the server.
#include <gtest/gtest.h>

#include <netinet/in.h>
#include <signal.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <map>
#include <memory>
#include <random>
#include <set>
#include <sstream>
#include <thread>
#include <vector>

#include <nlohmann/json.hpp>

#include "activefoam/spec_io.h"
#include "activefoam/utf8.h"
#include "process.h"
#include "spec_convert.h"
#include "store.h"

namespace fs = std::filesystem;
using namespace std::chrono_literals;

namespace {

using namespace activefoam::testing;

nlohmann::json results(const Foamd& d, const std::string& id) {
  const Proc r = sh(d.foam() + " results " + id + " --json");
  EXPECT_EQ(r.rc, 0);
  return nlohmann::json::parse(r.out);
}

}  // namespace

// The help lists the user's commands and says where studies live; `report` (a Slurm task's
// plumbing) is not among them but keeps its own help.
TEST(Cli, HelpNamesTheStudyToolAndLeavesOutTheSlurmPlumbing) {
  const std::string foam = FOAM_EXE;
  const Proc help = sh(foam + " --help 2>&1");
  EXPECT_NE(help.out.find("python3 -m activefoam.study"), std::string::npos) << help.out;
  EXPECT_NE(help.out.find("\n  submit "), std::string::npos) << help.out;
  EXPECT_EQ(help.out.find("\n  report "), std::string::npos) << help.out;
  const Proc report = sh(foam + " report --help 2>&1");
  EXPECT_NE(report.out.find("foam-run"), std::string::npos) << report.out;
}

TEST(Cli, SubmitWaitThenResultsJson) {
  const fs::path dir = tempDir();
  Foamd d(dir / "foamd.db", freePort());
  const std::string submit =
      d.foam() +
      " submit --scene cell --set duration_s=5 --set sample_every_s=1"
      " --set numerics.triangles_per_cell=80 --set snapshot_every_s=0 --wait 2>/dev/null";
  Proc r;
  for (int i = 0; i < 50; ++i) {  // the server may still be starting
    r = sh(submit);
    if (r.rc != 3) break;
    std::this_thread::sleep_for(100ms);
  }
  ASSERT_EQ(r.rc, 0) << r.out;
  const std::string id = firstLine(r.out);
  EXPECT_EQ(id.rfind("j-", 0), 0u) << "first stdout line must be the id alone: " << r.out;
  EXPECT_EQ(state(d, id), "succeeded");
  const nlohmann::json j = results(d, id);
  EXPECT_EQ(j["state"], "succeeded");
  EXPECT_TRUE(j["results"].contains("aspect_ratio"));
  EXPECT_EQ(j["samples"].size(), 6u);
  // Invalid spec: exit 2, nothing on stdout.
  const Proc bad = sh(d.foam() + " submit --scene cell --set cells.gamma=-1 2>/dev/null");
  EXPECT_EQ(bad.rc, 2);
  EXPECT_TRUE(bad.out.empty());
  // A job that fails to exist: show exits 5.
  EXPECT_EQ(sh(d.foam() + " show j-nope 2>/dev/null").rc, 5);
  // A directory or a 2 MiB file given as the spec: exit 2 saying so (before: "scene: missing").
  const Proc folder = sh(d.foam() + " submit " + dir.string() + " 2>&1");
  EXPECT_EQ(folder.rc, 2);
  EXPECT_NE(folder.out.find("is a directory, not a file"), std::string::npos) << folder.out;
  std::ofstream(dir / "huge.toml") << std::string(2 << 20, '#');
  const Proc huge = sh(d.foam() + " submit " + (dir / "huge.toml").string() + " 2>&1");
  EXPECT_EQ(huge.rc, 2);
  EXPECT_NE(huge.out.find("has 2097152 bytes; a spec or certificate file has at most 1 MiB"),
            std::string::npos)
      << huge.out;
  d.stop(SIGTERM);
  fs::remove_all(dir);
}

// A job stored by an earlier version, whose record names the contact law by the two switches
// that preceded numerics.contact_law: `foam show` gives the law as foamd's engine reads it.
TEST(Cli, ShowGivesTheContactLawOfAnEarlierRecordAsTheEngineReadsIt) {
  const fs::path dir = tempDir();
  std::string id;
  {
    const activefoam::server::ConvertResult conv =
        activefoam::server::convertSpec({}, "", {"scene=doublet", "numerics.dt_s=0.5"});
    ASSERT_TRUE(conv.ok()) << activefoam::server::errorText(conv.errors);
    nlohmann::json record = activefoam::specToJson(*conv.spec);
    record["numerics"].erase("contact_law");
    record["numerics"]["contact_within_prisms"] = true;
    record["numerics"]["contact_prisms_overlap_only"] = false;
    activefoam::server::NewJob job;
    job.spec = *conv.spec;
    job.spec_json = record.dump();
    activefoam::server::Store store((dir / "foamd.db").string());
    id = store.submit(job).first;
    store.cancel(id, "test: shown, not run");
  }
  Foamd d(dir / "foamd.db", freePort());
  ASSERT_EQ(state(d, id), "cancelled");
  const Proc show = sh(d.foam() + " show " + id);
  EXPECT_NE(show.out.find("fidelity:  preset standard (contact-implicit-consistent, Δt 0.5 s, 320 "
                          "triangles, ε_CG 0.01, contact law prisms)"),
            std::string::npos)
      << show.out;
  d.stop(SIGTERM);
  fs::remove_all(dir);
}

TEST(Cli, PresetsAndAccuracyTargetsAreRecordedAndUnstableStepsRefused) {
  const fs::path dir = tempDir();
  Foamd d(dir / "foamd.db", freePort());
  const std::string base = d.foam() +
                           " submit --scene doublet --set duration_s=5 --set sample_every_s=2.5"
                           " --set snapshot_every_s=0 --set cells.p_a=0";
  Proc r;
  for (int i = 0; i < 50; ++i) {  // the server may still be starting
    r = sh(base + " --accuracy contact_angle_deg=2 --wait 2>/dev/null");
    if (r.rc != 3) break;
    std::this_thread::sleep_for(100ms);
  }
  ASSERT_EQ(r.rc, 0) << r.out;
  Proc show = sh(d.foam() + " show " + firstLine(r.out));
  EXPECT_NE(show.out.find(
                "fidelity:  preset standard (contact-implicit-consistent, Δt 1 s, 320 triangles"),
            std::string::npos)
      << show.out;
  EXPECT_NE(show.out.find("chosen for the accuracy target contact angle ≤ 2°"), std::string::npos)
      << show.out;

  r = sh(base + " --preset reference --set numerics.triangles_per_cell=80 2>/dev/null");
  ASSERT_EQ(r.rc, 0) << r.out;
  show = sh(d.foam() + " show " + firstLine(r.out));
  EXPECT_NE(show.out.find("preset reference (contact-implicit-consistent, Δt 0.25 s, 80 triangles"),
            std::string::npos)
      << show.out;

  // Semi-implicit at the default Δt: the stability study saw it fail; refused, naming the key.
  r = sh(base + " --set numerics.integrator=semi-implicit 2>&1");
  EXPECT_EQ(r.rc, 2) << r.out;
  EXPECT_NE(r.out.find("numerics.dt_s"), std::string::npos) << r.out;
  // Motile cells of 80 triangles drifted out of volume in the fusion study from Δt = 0.25 s.
  r = sh(
      base +
      " --set cells.p_a=0.0372 --set numerics.dt_s=0.5 --set numerics.triangles_per_cell=80 2>&1");
  EXPECT_EQ(r.rc, 2) << r.out;
  EXPECT_NE(r.out.find("allowed (0, 0.25) s"), std::string::npos) << r.out;
  // A target no preset promises.
  r = sh(base + " --accuracy trajectory_deg=0.01 2>&1");
  EXPECT_EQ(r.rc, 2) << r.out;
  EXPECT_NE(r.out.find("accuracy.trajectory_deg"), std::string::npos) << r.out;
  d.stop(SIGTERM);
  fs::remove_all(dir);
}

// A small fusion job through foamd: fits and fusion observables in its results, the prepared
// spheroids cached next to the database, `foam plot` draws θ(t) as a PNG and `foam export`
// writes the snapshots for ParaView.
TEST(Cli, FusionJobResultsPlotAndExport) {
  const fs::path dir = tempDir();
  Foamd d(dir / "foamd.db", freePort());
  const std::string submit =
      d.foam() +
      " submit --scene fusion --set scene.n_cells_a=3 --set scene.n_cells_b=3"
      " --set scene.prep_max_s=10 --set scene.allow_uncompacted=true"
      " --set numerics.dt_s=0.1 --set duration_s=20"
      " --set sample_every_s=1 --set numerics.triangles_per_cell=80 --set snapshot_every_s=10"
      " --tag fus --wait 2>/dev/null";
  Proc r;
  for (int i = 0; i < 50; ++i) {
    r = sh(submit);
    if (r.rc != 3) break;
    std::this_thread::sleep_for(100ms);
  }
  ASSERT_EQ(r.rc, 0) << r.out;
  const std::string id = firstLine(r.out);
  const nlohmann::json j = results(d, id);
  EXPECT_EQ(j["samples"].size(), 21u);
  for (const char* k : {"theta_deg", "neck_radius_um", "eq1_ok", "eq2_ok", "s1_ok", "mixing_time_s",
                        "prep_compact_a"})
    EXPECT_TRUE(j["results"].contains(k)) << k;
  EXPECT_EQ(std::distance(fs::directory_iterator(dir / "spheroids"), fs::directory_iterator()), 2);
  // Placed touching: fused or arrested, and the job's outcome is what the filters select on.
  const std::string outcome = j.value("outcome", std::string());
  EXPECT_TRUE(outcome == "fused" || outcome == "arrested") << j.dump();
  const Proc table =
      sh(d.foam() + " results --tag fus --outcome " + outcome + " --metrics theta_deg --csv");
  ASSERT_EQ(table.rc, 0) << table.out;
  EXPECT_EQ(table.out.rfind("job_id,state,outcome,seed,", 0), 0u) << table.out;
  EXPECT_NE(table.out.find(",theta_deg\n" + id + ",succeeded," + outcome + ","), std::string::npos)
      << table.out;
  EXPECT_EQ(sh(d.foam() + " results 2>&1").rc, 2) << "a job ID, --sweep or --tag is needed";
  const Proc listed = sh(d.foam() + " list --outcome " + outcome + " 2>&1");
  ASSERT_EQ(listed.rc, 0) << listed.out;
  EXPECT_NE(listed.out.find(id), std::string::npos) << listed.out;
  const std::string other = outcome == "fused" ? "arrested" : "fused";
  EXPECT_EQ(sh(d.foam() + " list --outcome " + other + " 2>&1").out.find(id), std::string::npos);
  const Proc wrong = sh(d.foam() + " list --outcome merged 2>&1");
  EXPECT_EQ(wrong.rc, 2) << wrong.out;
  EXPECT_NE(wrong.out.find("outcome"), std::string::npos) << wrong.out;

  const fs::path png = dir / "theta.png";
  const Proc plot = sh(d.foam() + " plot " + id + " --out " + png.string() + " 2>&1");
  ASSERT_EQ(plot.rc, 0) << plot.out;
  std::ifstream in(png, std::ios::binary);
  char magic[8] = {};
  in.read(magic, 8);
  EXPECT_EQ(std::string(magic + 1, 3), "PNG");
  const Proc bad = sh(d.foam() + " plot " + id + " --column nope 2>&1");
  EXPECT_EQ(bad.rc, 2);
  EXPECT_NE(bad.out.find("theta_deg"), std::string::npos) << bad.out;  // lists the columns

  // foam export: the three snapshots (t = 0, 10, 20 s) as .vtp with a .pvd index; each file
  // holds the 6 cells × 42 vertices the engine had (80 triangles per cell).
  const fs::path out = dir / "vtk";
  const Proc ex = sh(d.foam() + " export " + id + " --out " + out.string() + " 2>&1");
  ASSERT_EQ(ex.rc, 0) << ex.out;
  std::ifstream pvd(out / "series.pvd");
  const std::string index((std::istreambuf_iterator<char>(pvd)), std::istreambuf_iterator<char>());
  int files = 0;
  for (const auto& e : fs::directory_iterator(out)) {
    if (e.path().extension() != ".vtp") continue;
    ++files;
    EXPECT_NE(index.find(e.path().filename().string()), std::string::npos);
    std::ifstream f(e.path());
    const std::string text((std::istreambuf_iterator<char>(f)), std::istreambuf_iterator<char>());
    EXPECT_NE(text.find("NumberOfPolys=\"480\""), std::string::npos) << e.path();
    EXPECT_NE(text.find("Name=\"spheroid\""), std::string::npos);
  }
  EXPECT_EQ(files, 3);
  d.stop(SIGTERM);
  fs::remove_all(dir);
}

// kill -9 mid-run: the restarted server re-queues the job and resumes it from its last checkpoint
// (or from scratch if none was written yet); either way the results equal an uninterrupted run.
TEST(Cli, KillDashNineThenRestartFinishesEveryJobWithTheSameResults) {
  const fs::path dir = tempDir();
  const int port = freePort();
  auto d = std::make_unique<Foamd>(dir / "foamd.db", port, 1);
  const std::string spec =
      " --scene cell --set duration_s=1500 --set sample_every_s=100 --set numerics.dt_s=0.1"
      " --set numerics.triangles_per_cell=80 --set snapshot_every_s=0 --set seed=5";
  Proc r;
  for (int i = 0; i < 50; ++i) {
    r = sh(d->foam() + " submit" + spec + " 2>/dev/null");
    if (r.rc == 0) break;
    std::this_thread::sleep_for(100ms);
  }
  ASSERT_EQ(r.rc, 0);
  const std::string id = firstLine(r.out);
  const std::string id2 =
      firstLine(sh(d->foam() + " submit" + spec + " --set seed=6 2>/dev/null").out);
  // Wait until it runs, then kill the server without warning.
  for (int i = 0; i < 200 && state(*d, id) != "running"; ++i) std::this_thread::sleep_for(10ms);
  ASSERT_EQ(state(*d, id), "running");
  d->stop(SIGKILL);
  d.reset();

  Foamd d2(dir / "foamd.db", port, 1);
  const Proc w = sh(d2.foam() + " watch " + id + " -q 2>/dev/null");
  EXPECT_EQ(w.rc, 0);
  EXPECT_EQ(state(d2, id), "succeeded");
  EXPECT_EQ(sh(d2.foam() + " watch " + id2 + " -q 2>/dev/null").rc, 0);
  const nlohmann::json interrupted = results(d2, id);

  // The same spec and seed, uninterrupted.
  const std::string ref =
      firstLine(sh(d2.foam() + " submit" + spec + " --wait -q 2>/dev/null").out);
  const nlohmann::json clean = results(d2, ref);
  for (const char* k : {"aspect_ratio", "pressure_kpa", "steps", "t_s", "volume_error_max"})
    EXPECT_EQ(interrupted["results"][k], clean["results"][k]) << k;
  EXPECT_EQ(interrupted["samples"].size(), clean["samples"].size());
  for (std::size_t i = 0; i < clean["samples"].size(); ++i)
    EXPECT_EQ(interrupted["samples"][i][7], clean["samples"][i][7])
        << "sample " << i;  // aspect_ratio
  d2.stop(SIGTERM);
  fs::remove_all(dir);
}

// SIGTERM: running jobs go back to the queue and finish after the next start.
TEST(Cli, SigtermRequeuesRunningJobs) {
  const fs::path dir = tempDir();
  const int port = freePort();
  auto d = std::make_unique<Foamd>(dir / "foamd.db", port, 1);
  Proc r;
  for (int i = 0; i < 50; ++i) {
    r = sh(d->foam() +
           " submit --scene cell --set duration_s=1500 --set sample_every_s=100"
           " --set numerics.dt_s=0.1 --set numerics.triangles_per_cell=80"
           " --set snapshot_every_s=0 2>/dev/null");
    if (r.rc == 0) break;
    std::this_thread::sleep_for(100ms);
  }
  const std::string id = firstLine(r.out);
  for (int i = 0; i < 200 && state(*d, id) != "running"; ++i) std::this_thread::sleep_for(10ms);
  d->stop(SIGTERM);
  d.reset();
  Foamd d2(dir / "foamd.db", port, 1);
  EXPECT_EQ(sh(d2.foam() + " watch " + id + " -q 2>/dev/null").rc, 0);
  const nlohmann::json j = results(d2, id);
  EXPECT_EQ(j["state"], "succeeded");
  d2.stop(SIGTERM);
  // The cancelled run wrote a checkpoint on its way out; the restart resumed from it rather
  // than starting over.
  std::ifstream log(dir / "foamd.log");
  const std::string text((std::istreambuf_iterator<char>(log)), std::istreambuf_iterator<char>());
  EXPECT_NE(text.find("resuming from checkpoint at t = "), std::string::npos) << text;
  EXPECT_EQ(text.find("cannot resume"), std::string::npos) << text;
  fs::remove_all(dir);
}

// foam results --sweep --by: per parameter value over seeds, the counts and the median and
// quartiles of each result, equal to those computed here from the per-job table.
TEST(Cli, SweepResultsAggregateOverSeeds) {
  const fs::path dir = tempDir();
  Foamd d(dir / "foamd.db", freePort(), 2);
  Proc r;
  for (int i = 0; i < 50; ++i) {
    r = sh(d.foam() +
           " sweep --scene cell --set duration_s=5 --set sample_every_s=1"
           " --set numerics.triangles_per_cell=80 --set snapshot_every_s=0"
           " --grid cells.gamma=0.4,0.6 --seeds 1,2,3 --wait 2>/dev/null");
    if (r.rc != 3) break;
    std::this_thread::sleep_for(100ms);
  }
  ASSERT_EQ(r.rc, 0) << r.out;
  const std::string sweep = firstLine(r.out);
  const Proc per_job =
      sh(d.foam() + " results --sweep " + sweep + " --metrics aspect_ratio,wall_s --json");
  ASSERT_EQ(per_job.rc, 0) << per_job.out;
  std::map<double, std::map<std::string, std::vector<double>>> expected;
  for (const auto& row : nlohmann::json::parse(per_job.out))
    for (const char* m : {"aspect_ratio", "wall_s"})
      expected[row["params"]["cells.gamma"].get<double>()][m].push_back(row["results"][m]);
  ASSERT_EQ(expected.size(), 2u);
  // The swept key is the only parameter column: nothing else differs between the jobs.
  const nlohmann::json first = nlohmann::json::parse(per_job.out)[0];
  EXPECT_EQ(first["params"].size(), 1u) << first.dump();
  EXPECT_EQ(first["state"], "succeeded");
  auto quantile = [](std::vector<double> v, double q) {
    std::sort(v.begin(), v.end());
    const double pos = q * static_cast<double>(v.size() - 1);
    const auto lo = static_cast<std::size_t>(pos);
    const std::size_t hi = std::min(lo + 1, v.size() - 1);
    return v[lo] + (pos - static_cast<double>(lo)) * (v[hi] - v[lo]);
  };
  const Proc agg = sh(d.foam() + " results --sweep " + sweep +
                      " --by cells.gamma --metrics aspect_ratio,wall_s --json");
  ASSERT_EQ(agg.rc, 0) << agg.out;
  const nlohmann::json groups = nlohmann::json::parse(agg.out);
  ASSERT_EQ(groups.size(), 2u) << agg.out;
  for (const auto& g : groups) {
    const double gamma = g["cells.gamma"];
    EXPECT_EQ(g["jobs"], 3);
    EXPECT_EQ(g["succeeded"], 3);
    EXPECT_EQ(g["failed"], 0);
    for (const char* m : {"aspect_ratio", "wall_s"}) {
      const std::vector<double>& v = expected.at(gamma).at(m);
      ASSERT_EQ(v.size(), 3u);
      EXPECT_EQ(g[m]["n"], 3);
      EXPECT_DOUBLE_EQ(g[m]["median"].get<double>(), quantile(v, 0.5)) << m;
      EXPECT_DOUBLE_EQ(g[m]["q25"].get<double>(), quantile(v, 0.25)) << m;
      EXPECT_DOUBLE_EQ(g[m]["q75"].get<double>(), quantile(v, 0.75)) << m;
    }
  }
  const Proc csv = sh(d.foam() + " results --sweep " + sweep + " --by cells.gamma --csv");
  ASSERT_EQ(csv.rc, 0);
  EXPECT_EQ(csv.out.rfind("cells.gamma,jobs,succeeded,failed,", 0), 0u) << csv.out;
  const Proc bad = sh(d.foam() + " results --sweep " + sweep + " --by cells.nope 2>&1");
  EXPECT_EQ(bad.rc, 2);
  EXPECT_NE(bad.out.find("'cells.nope' is not a numeric key"), std::string::npos) << bad.out;

  // foam plot --sweep: median and IQR against a key (per value of --by), and a heat map; PNGs.
  auto isPng = [](const fs::path& p) {
    std::ifstream in(p, std::ios::binary);
    char magic[4] = {};
    in.read(magic, 4);
    return std::string(magic + 1, 3) == "PNG";
  };
  const std::string plot = d.foam() + " plot --sweep " + sweep;
  for (const std::string& args :
       {std::string(" --x cells.gamma --y wall_s --out ") + (dir / "a.png").string(),
        std::string(" --x cells.gamma --by seed --y aspect_ratio --out ") +
            (dir / "b.png").string(),
        std::string(" --heatmap cells.gamma,seed --y wall_s --out ") + (dir / "c.png").string()}) {
    const Proc p = sh(plot + args + " 2>&1");
    EXPECT_EQ(p.rc, 0) << args << "\n" << p.out;
    const std::string file = args.substr(args.rfind(' ') + 1);
    EXPECT_TRUE(isPng(file)) << file;
  }
  const Proc no_result = sh(plot + " --x cells.gamma --y nope 2>&1");
  EXPECT_EQ(no_result.rc, 2);
  EXPECT_NE(no_result.out.find("--y: 'nope' is not a result"), std::string::npos) << no_result.out;
  const Proc no_key = sh(plot + " --x cells.nope --y wall_s 2>&1");
  EXPECT_EQ(no_key.rc, 2);
  EXPECT_NE(no_key.out.find("'cells.nope' is not a numeric key"), std::string::npos) << no_key.out;
  d.stop(SIGTERM);
  fs::remove_all(dir);
}

// TLS files are checked before anything starts, each error naming the option
// and the file (a garbage --tls-ca was gRPC's "empty address list: (14)", a key of another
// certificate "the port is taken"; a key that others can read was accepted).
TEST(Cli, TlsFilesAreCheckedAtStartNamingTheFile) {
  const fs::path dir = tempDir();
  const fs::path data = SERVER_TEST_DATA;
  const fs::path cert = data / "test-cert.pem", garbage = dir / "garbage.pem";
  std::ofstream(garbage) << "this is not a certificate\n";
  auto privateCopy = [&](const char* name) {
    fs::copy_file(data / name, dir / name);
    fs::permissions(dir / name, fs::perms::owner_read | fs::perms::owner_write);
    return (dir / name).string();
  };
  const std::string key = privateCopy("test-key.pem"), other = privateCopy("other-key.pem");
  auto foamd = [&](const std::string& cert_file, const std::string& key_file) {
    // `timeout`: a foamd that accepts the files starts and serves (the test then fails, not hangs).
    return sh("timeout 10 " + std::string(FOAMD_EXE) + " --listen 127.0.0.1:" +
              std::to_string(freePort()) + " --db " + (dir / "foamd.db").string() + " --tls-cert " +
              cert_file + " --tls-key " + key_file + " 2>&1");
  };
  Proc r = foamd(garbage.string(), key);
  EXPECT_EQ(r.rc, 2) << r.out;
  EXPECT_NE(r.out.find("--tls-cert '" + garbage.string() + "': not a PEM certificate"),
            std::string::npos)
      << r.out;
  r = foamd(cert.string(), other);
  EXPECT_EQ(r.rc, 2) << r.out;
  EXPECT_NE(r.out.find("--tls-cert and --tls-key do not belong together"), std::string::npos)
      << r.out;
  const fs::path garbage_key = dir / "garbage-key.pem";
  fs::copy_file(garbage, garbage_key);
  fs::permissions(garbage_key, fs::perms::owner_read | fs::perms::owner_write);
  r = foamd(cert.string(), garbage_key.string());
  EXPECT_EQ(r.rc, 2) << r.out;
  EXPECT_NE(r.out.find("--tls-key '" + garbage_key.string() + "': not a PEM private key"),
            std::string::npos)
      << r.out;
  fs::permissions(key, fs::perms::group_read, fs::perm_options::add);
  r = foamd(cert.string(), key);
  EXPECT_EQ(r.rc, 2) << r.out;
  EXPECT_NE(r.out.find("a private key accessible to other users (mode 0640): chmod 600"),
            std::string::npos)
      << r.out;
  EXPECT_FALSE(fs::exists(dir / "foamd.db"));  // refused before the database is touched
  r = sh(std::string(FOAM_EXE) + " --server 127.0.0.1:1 --tls-ca " + garbage.string() +
         " list 2>&1");
  EXPECT_EQ(r.rc, 2) << r.out;
  EXPECT_NE(r.out.find("--tls-ca '" + garbage.string() + "': not a PEM certificate"),
            std::string::npos)
      << r.out;
  fs::remove_all(dir);
}

// A certificate outside its validity period was served: clients saw only "certificate verify
// failed". foamd refuses it at start, naming the file and the certificate's dates, before the
// database is touched; with the same key, a certificate valid now starts.
TEST(Cli, CertificatesOutsideTheirDatesAreRefusedAtStart) {
  const fs::path dir = tempDir();
  const fs::path data = SERVER_TEST_DATA;
  fs::copy_file(data / "test-key.pem", dir / "key.pem");
  fs::permissions(dir / "key.pem", fs::perms::owner_read | fs::perms::owner_write);
  auto foamd = [&](const fs::path& cert, int timeout_s = 10) {
    return sh("timeout " + std::to_string(timeout_s) + " " + std::string(FOAMD_EXE) +
              " --listen 127.0.0.1:" + std::to_string(freePort()) + " --db " +
              (dir / "foamd.db").string() + " --tls-cert " + cert.string() + " --tls-key " +
              (dir / "key.pem").string() + " 2>&1");
  };
  Proc r = foamd(data / "expired-cert.pem");
  EXPECT_EQ(r.rc, 2) << r.out;
  EXPECT_NE(r.out.find("--tls-cert '" + (data / "expired-cert.pem").string() +
                       "': the certificate has expired (valid from 2000-01-01 00:00:00 UTC to "
                       "2001-01-01 00:00:00 UTC; now "),
            std::string::npos)
      << r.out;
  r = foamd(data / "future-cert.pem");
  EXPECT_EQ(r.rc, 2) << r.out;
  EXPECT_NE(r.out.find("--tls-cert '" + (data / "future-cert.pem").string() +
                       "': the certificate is not valid yet (valid from 2100-01-01 00:00:00 UTC "
                       "to 2101-01-01 00:00:00 UTC; now "),
            std::string::npos)
      << r.out;
  EXPECT_NE(r.out.find("check this machine's clock"), std::string::npos) << r.out;
  EXPECT_FALSE(fs::exists(dir / "foamd.db"));
  // A chain whose second certificate has expired: named as such.
  {
    std::ofstream chain(dir / "chain.pem");
    chain << std::ifstream(data / "test-cert.pem").rdbuf()
          << std::ifstream(data / "expired-cert.pem").rdbuf();
  }
  r = foamd(dir / "chain.pem");
  EXPECT_EQ(r.rc, 2) << r.out;
  EXPECT_NE(r.out.find("certificate 2 of the file has expired"), std::string::npos) << r.out;
  // The key and a certificate valid now: foamd starts (and serves until `timeout` ends it).
  r = foamd(data / "test-cert.pem", 3);
  EXPECT_EQ(r.rc, 124) << r.out;
  fs::remove_all(dir);
}

TEST(Cli, TlsAndTokenFromFlagsAndEnvironment) {
  const fs::path dir = tempDir();
  const std::string cert = std::string(SERVER_TEST_DATA) + "/test-cert.pem";
  // A private key that others can read is refused as a token file is: a copy only we read.
  const std::string key = (dir / "key.pem").string();
  fs::copy_file(std::string(SERVER_TEST_DATA) + "/test-key.pem", key);
  fs::permissions(key, fs::perms::owner_read | fs::perms::owner_write);
  const fs::path token = dir / "token";
  const std::string secret = "t0ken-of-20-bytes-x";
  std::ofstream(token) << secret << "\n";
  // Token files are refused, by foamd and by foam, when others may read them or when they are
  // too short to be a secret (as ssh refuses keys).
  fs::permissions(token, fs::perms::owner_read | fs::perms::owner_write | fs::perms::group_read);
  Foamd open_file(dir / "open.db", freePort(), 1, {"--token-file", token.string()});
  EXPECT_EQ(open_file.exited(10s), 2);
  const Proc foam_open =
      sh(std::string(FOAM_EXE) + " --token-file " + token.string() + " list 2>&1");
  EXPECT_EQ(foam_open.rc, 2);
  EXPECT_NE(foam_open.out.find("is accessible to other users (mode 0640): chmod 600"),
            std::string::npos)
      << foam_open.out;
  const fs::path short_token = dir / "short";
  std::ofstream(short_token) << "t0ken\n";
  fs::permissions(short_token, fs::perms::owner_read | fs::perms::owner_write);
  Foamd short_file(dir / "short.db", freePort(), 1, {"--token-file", short_token.string()});
  EXPECT_EQ(short_file.exited(10s), 2);
  std::ifstream log(dir / "foamd.log");
  const std::string text((std::istreambuf_iterator<char>(log)), std::istreambuf_iterator<char>());
  EXPECT_NE(text.find("holds 5 bytes; a token needs at least 16"), std::string::npos) << text;
  fs::permissions(token, fs::perms::owner_read | fs::perms::owner_write);
  const int port = freePort();
  Foamd d(dir / "foamd.db", port, 1,
          {"--tls-cert", cert, "--tls-key", key, "--token-file", token.string()});
  const std::string foam = d.foam();
  const std::string tls = " --tls-ca " + cert;
  int rc = -1;
  for (int i = 0; i < 100 && rc != 0; ++i) {
    rc = sh(foam + tls + " --token-file " + token.string() + " list 2>/dev/null").rc;
    if (rc != 0) std::this_thread::sleep_for(100ms);
  }
  EXPECT_EQ(rc, 0) << "foam list over TLS with the token";
  EXPECT_EQ(sh(foam + tls + " list 2>/dev/null").rc, 4);  // no token: unauthenticated
  EXPECT_EQ(
      sh("FOAM_TLS_CA=" + cert + " FOAM_TOKEN=" + secret + " " + foam + " list 2>/dev/null").rc, 0);
  EXPECT_EQ(sh(foam + " --token-file " + token.string() + " list 2>/dev/null").rc, 3);  // plain
  d.stop(SIGTERM);
  fs::remove_all(dir);
}

// ---- the Slurm executor against a stand-in Slurm (tests/slurm/fake: sbatch runs the array's
// tasks on this machine; the real single-node Slurm test is tests/slurm/test_slurm.sh) ------

namespace {

struct FakeSlurm {
  fs::path dir = tempDir();
  FakeSlurm() {
    setenv("FAKE_SLURM_STATE", (dir / "state").c_str(), 1);
    const std::string path = std::string(FAKE_SLURM_DIR) + ":" + std::getenv("PATH");
    setenv("PATH", path.c_str(), 1);
  }
  std::vector<std::string> args() const {
    return {"--executor",
            "slurm",
            "--slurm-dir",
            (dir / "work").string(),
            "--slurm-poll-s",
            "0.2",
            "--slurm-checkpoint-every-s",
            "1"};
  }
  std::string taskState(const std::string& task) const {
    std::ifstream f(dir / "state" / (task + ".state"));
    std::string s;
    f >> s;
    return s;
  }
};

// `foam show` field ("executor:  slurm:1001_0" → "slurm:1001_0").
std::string showField(const Foamd& d, const std::string& id, const std::string& field) {
  const Proc r = sh(d.foam() + " show " + id + " 2>/dev/null");
  std::istringstream in(r.out);
  for (std::string line; std::getline(in, line);)
    if (line.rfind(field + ":", 0) == 0) {
      std::string v = line.substr(field.size() + 1);
      return v.substr(v.find_first_not_of(' '));
    }
  return "";
}

std::map<std::uint64_t, nlohmann::json> sweepResults(const Foamd& d, const std::string& sweep) {
  std::map<std::uint64_t, nlohmann::json> out;
  const Proc l = sh(d.foam() + " list --sweep " + sweep + " 2>/dev/null");
  std::istringstream in(l.out);
  std::string line;
  std::getline(in, line);  // header
  while (std::getline(in, line)) {
    const std::string id = line.substr(0, line.find(' '));
    nlohmann::json j = results(d, id);
    out[j["seed"].get<std::uint64_t>()] = j;
  }
  return out;
}

// Results and samples without the wall-clock ones.
void expectSameRun(const nlohmann::json& a, const nlohmann::json& b) {
  EXPECT_EQ(a["state"], b["state"]);
  nlohmann::json ra = a["results"], rb = b["results"];
  ra.erase("wall_s");
  rb.erase("wall_s");
  EXPECT_EQ(ra, rb);
  ASSERT_EQ(a["samples"].size(), b["samples"].size());
  const auto cols = a["columns"].get<std::vector<std::string>>();
  for (std::size_t i = 0; i < a["samples"].size(); ++i)
    for (std::size_t c = 0; c < cols.size(); ++c)
      if (cols[c] != "wall_s") {
        EXPECT_EQ(a["samples"][i][c], b["samples"][i][c]) << cols[c];
      }
  EXPECT_EQ(a["snapshots"], b["snapshots"]);
}

std::string waitForState(const Foamd& d, const std::string& id, const std::string& want,
                         double timeout_s) {
  std::string s;
  for (int i = 0; i < timeout_s * 10; ++i) {
    s = state(d, id);
    if (s == want) break;
    std::this_thread::sleep_for(100ms);
  }
  return s;
}

}  // namespace

TEST(CliSlurm, ASweepRunsAsArrayTasksWithTheLocalPoolsResults) {
  FakeSlurm slurm;
  Foamd s(slurm.dir / "db" / "foamd.db", freePort(), 1, slurm.args());
  Foamd p(slurm.dir / "db2" / "foamd.db", freePort(), 2);
  const std::string sweep_args =
      " sweep --scene doublet --set duration_s=30 --set sample_every_s=5"
      " --set snapshot_every_s=15 --set cells.p_a=0 --seeds 1,2,3,4 --wait 2>/dev/null";
  Proc rs, rp;
  for (int i = 0; i < 50; ++i) {  // the servers may still be starting
    rs = sh(s.foam() + sweep_args);
    if (rs.rc != 3) break;
    std::this_thread::sleep_for(100ms);
  }
  ASSERT_EQ(rs.rc, 0) << rs.out;
  for (int i = 0; i < 50; ++i) {
    rp = sh(p.foam() + sweep_args);
    if (rp.rc != 3) break;
    std::this_thread::sleep_for(100ms);
  }
  ASSERT_EQ(rp.rc, 0) << rp.out;
  const auto a = sweepResults(s, firstLine(rs.out));
  const auto b = sweepResults(p, firstLine(rp.out));
  ASSERT_EQ(a.size(), 4u);
  ASSERT_EQ(b.size(), 4u);
  std::set<std::string> arrays;
  for (const auto& [seed, j] : a) {
    SCOPED_TRACE("seed " + std::to_string(seed));
    expectSameRun(j, b.at(seed));
    const std::string ref = showField(s, j["id"], "executor");
    arrays.insert(ref.substr(0, ref.find('_')));
  }
  EXPECT_EQ(arrays.size(), 1u) << "a sweep is one sbatch --array";
  fs::remove_all(slurm.dir);
}

TEST(CliSlurm, CancelFailureAndAFoamdRestartMidSweep) {
  FakeSlurm slurm;
  const int port = freePort();
  auto s = std::make_unique<Foamd>(slurm.dir / "db" / "foamd.db", port, 1, slurm.args());
  const std::string base =
      " submit --scene doublet --set sample_every_s=5 --set cells.p_a=0"
      " --set snapshot_every_s=0";
  // Cancel: a long job, cancelled once it reports progress → CANCELLED, its task scancelled.
  Proc r;
  for (int i = 0; i < 50; ++i) {
    r = sh(s->foam() + base + " --set duration_s=100000 2>/dev/null");
    if (r.rc != 3) break;
    std::this_thread::sleep_for(100ms);
  }
  ASSERT_EQ(r.rc, 0);
  const std::string long_id = firstLine(r.out);
  std::string ref;
  for (int i = 0; i < 300 && (ref.empty() || showField(*s, long_id, "progress")[0] == '0'); ++i) {
    ref = showField(*s, long_id, "executor");
    std::this_thread::sleep_for(100ms);
  }
  ASSERT_EQ(ref.rfind("slurm:", 0), 0u) << ref;
  const Proc cancelled = sh(s->foam() + " cancel " + long_id + " 2>/dev/null");
  EXPECT_EQ(cancelled.rc, 0);
  // Slurm's executor cancels at once ("cancelled"); the pool's job stops at its next step.
  EXPECT_TRUE(firstLine(cancelled.out) == "cancelled" || firstLine(cancelled.out) == "cancelling")
      << cancelled.out;
  EXPECT_EQ(waitForState(*s, long_id, "cancelled", 10), "cancelled");
  EXPECT_EQ(slurm.taskState(ref.substr(6)), "CANCELLED");

  // A task whose run fails: FAILED with the engine's failure and reason.
  r = sh(s->foam() + base + " --set duration_s=50 --set numerics.max_volume_error=1e-9 --wait");
  EXPECT_EQ(r.rc, 1) << r.out;
  const std::string failed_id = firstLine(r.out);
  EXPECT_NE(showField(*s, failed_id, "reason").find("volume error"), std::string::npos)
      << showField(*s, failed_id, "reason");

  // foamd killed mid-sweep and restarted: the tasks keep running and retry their reports; the
  // sweep ends complete.
  r = sh(s->foam() +
         " sweep --scene doublet --set duration_s=1500 --set sample_every_s=5"
         " --set snapshot_every_s=500 --set cells.p_a=0 --seeds 5,6 2>/dev/null");
  ASSERT_EQ(r.rc, 0);
  const std::string sweep = firstLine(r.out);
  std::this_thread::sleep_for(2s);
  s->stop(SIGKILL);
  std::this_thread::sleep_for(3s);
  s = std::make_unique<Foamd>(slurm.dir / "db" / "foamd.db", port, 1, slurm.args());
  std::map<std::uint64_t, nlohmann::json> done;
  for (int i = 0; i < 1200; ++i) {
    std::this_thread::sleep_for(100ms);
    const Proc l = sh(s->foam() + " list --sweep " + sweep + " 2>/dev/null");
    if (l.rc == 0 && l.out.find("running") == std::string::npos &&
        l.out.find("queued") == std::string::npos && l.out.find("succeeded") != std::string::npos)
      break;
  }
  done = sweepResults(*s, sweep);
  ASSERT_EQ(done.size(), 2u);
  for (const auto& [seed, j] : done) {
    EXPECT_EQ(j["state"], "succeeded") << seed;
    EXPECT_EQ(j["samples"].size(), 301u) << seed;  // 0, 5, ..., 1500 s: none lost, none twice
    EXPECT_EQ(j["snapshots"], 4) << seed;
    EXPECT_EQ(j["results"]["t_s"], 1500) << seed;
  }
  s->stop(SIGTERM);
  fs::remove_all(slurm.dir);
}

TEST(Utf8, WellFormedAndMalformedSequences) {
  using activefoam::invalidUtf8At;
  constexpr auto ok = std::string::npos;
  EXPECT_EQ(invalidUtf8At(""), ok);
  EXPECT_EQ(invalidUtf8At("plain ascii"), ok);
  EXPECT_EQ(invalidUtf8At("θ_eq 64° — 細胞 🧫"), ok);
  EXPECT_EQ(invalidUtf8At("caf\xe9"), 3u);                       // Latin-1 é
  EXPECT_EQ(invalidUtf8At("ab\xc3"), 2u);                        // truncated
  EXPECT_EQ(invalidUtf8At("\xc0\xaf"), 0u);                      // overlong '/'
  EXPECT_EQ(invalidUtf8At("x\xe0\x80\xaf"), 1u);                 // overlong, 3 bytes
  EXPECT_EQ(invalidUtf8At("\xed\xa0\x80"), 0u);                  // a surrogate (U+D800)
  EXPECT_EQ(invalidUtf8At("\xf4\x90\x80\x80"), 0u);              // above U+10FFFF
  EXPECT_EQ(invalidUtf8At("\xe2\x82\x28"), 0u);                  // bad continuation
  EXPECT_EQ(invalidUtf8At("\xef\xbf\xbf\xf4\x8f\xbf\xbf"), ok);  // U+FFFF, U+10FFFF
}

// Text that is not UTF-8 never reaches the server (whose protobuf parser would refuse it and
// gRPC answer an empty UNIMPLEMENTED, exit 3): foam exits 2 saying where it is.
TEST(Cli, TextThatIsNotUtf8IsRefusedBeforeItIsSent) {
  const fs::path dir = tempDir();
  const std::string foam = std::string(FOAM_EXE) + " --server 127.0.0.1:1";
  Proc r = sh(foam + " submit --scene cell --tag $(printf 'caf\\351') 2>&1");
  EXPECT_EQ(r.rc, 2) << r.out;
  EXPECT_NE(r.out.find("argument 7 (the value of --tag) is not valid UTF-8 (byte 3)"),
            std::string::npos)
      << r.out;
  std::ofstream(dir / "latin1.toml") << "scene = \"cell\"\n# r\xe9sum\xe9\nduration_s = 10\n";
  r = sh(foam + " submit " + (dir / "latin1.toml").string() + " 2>&1");
  EXPECT_EQ(r.rc, 2) << r.out;
  EXPECT_NE(r.out.find("not valid UTF-8 at byte 18 (line 2); save the spec as UTF-8"),
            std::string::npos)
      << r.out;
  fs::remove_all(dir);
}
