// foam + foamd as processes: the CLI end to end, and kill -9 / restart of the server.
#include <gtest/gtest.h>

#include <netinet/in.h>
#include <signal.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <random>
#include <sstream>
#include <thread>
#include <vector>

#include <nlohmann/json.hpp>

namespace fs = std::filesystem;
using namespace std::chrono_literals;

namespace {

int freePort() {
  const int fd = socket(AF_INET, SOCK_STREAM, 0);
  sockaddr_in a{};
  a.sin_family = AF_INET;
  a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  bind(fd, reinterpret_cast<sockaddr*>(&a), sizeof a);
  socklen_t len = sizeof a;
  getsockname(fd, reinterpret_cast<sockaddr*>(&a), &len);
  close(fd);
  return ntohs(a.sin_port);
}

struct Proc {
  int rc = -1;
  std::string out;
};

// Runs a shell command; stdout captured, stderr to the given file.
Proc sh(const std::string& cmd) {
  Proc r;
  FILE* p = popen(cmd.c_str(), "r");
  char buf[4096];
  std::size_t n;
  while ((n = fread(buf, 1, sizeof buf, p)) > 0) r.out.append(buf, n);
  const int st = pclose(p);
  r.rc = WIFEXITED(st) ? WEXITSTATUS(st) : -1;
  return r;
}

class Foamd {
 public:
  Foamd(fs::path db, int port, int workers = 1, std::vector<std::string> extra = {})
      : db_(std::move(db)), port_(port), workers_(workers), extra_(std::move(extra)) {
    start();
  }
  ~Foamd() { stop(SIGTERM); }
  void start() {
    pid_ = fork();
    if (pid_ == 0) {
      const std::string listen = "127.0.0.1:" + std::to_string(port_);
      const std::string log = (db_.parent_path() / "foamd.log").string();
      freopen(log.c_str(), "a", stderr);
      freopen(log.c_str(), "a", stdout);
      const std::string workers = std::to_string(workers_);
      std::vector<const char*> argv{FOAMD_EXE,   "--listen",  listen.c_str(), "--db",
                                    db_.c_str(), "--workers", workers.c_str()};
      for (const std::string& e : extra_) argv.push_back(e.c_str());
      argv.push_back(nullptr);
      execv(FOAMD_EXE, const_cast<char* const*>(argv.data()));
      _exit(127);
    }
  }
  void stop(int sig) {
    if (pid_ <= 0) return;
    kill(pid_, sig);
    int st = 0;
    waitpid(pid_, &st, 0);
    pid_ = -1;
  }
  std::string foam() const {
    return std::string(FOAM_EXE) + " --server 127.0.0.1:" + std::to_string(port_);
  }

 private:
  fs::path db_;
  int port_;
  int workers_;
  std::vector<std::string> extra_;
  pid_t pid_ = -1;
};

fs::path tempDir() {
  static std::mt19937_64 rng{std::random_device{}()};
  const fs::path d = fs::temp_directory_path() / ("foam-cli-test-" + std::to_string(rng()));
  fs::create_directories(d);
  return d;
}

std::string firstLine(const std::string& s) {
  return s.substr(0, s.find('\n'));
}

// foam show ID → the state (first line); retries while the server starts.
std::string state(const Foamd& d, const std::string& id) {
  for (int i = 0; i < 100; ++i) {
    const Proc r = sh(d.foam() + " show " + id + " 2>/dev/null");
    if (r.rc == 0) return firstLine(r.out);
    std::this_thread::sleep_for(100ms);
  }
  return "";
}

nlohmann::json results(const Foamd& d, const std::string& id) {
  const Proc r = sh(d.foam() + " results " + id + " --json");
  EXPECT_EQ(r.rc, 0);
  return nlohmann::json::parse(r.out);
}

}  // namespace

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
  EXPECT_NE(show.out.find("fidelity:  preset draft (contact-implicit, Δt 0.5 s, 320 triangles"),
            std::string::npos)
      << show.out;
  EXPECT_NE(show.out.find("chosen for the accuracy target contact angle ≤ 2°"), std::string::npos)
      << show.out;

  r = sh(base + " --preset reference --set numerics.triangles_per_cell=80 2>/dev/null");
  ASSERT_EQ(r.rc, 0) << r.out;
  show = sh(d.foam() + " show " + firstLine(r.out));
  EXPECT_NE(show.out.find("preset reference (contact-implicit, Δt 0.1 s, 80 triangles"),
            std::string::npos)
      << show.out;

  // Semi-implicit at the default Δt: the stability study saw it fail; refused, naming the key.
  r = sh(base + " --set numerics.integrator=semi-implicit 2>&1");
  EXPECT_EQ(r.rc, 2) << r.out;
  EXPECT_NE(r.out.find("numerics.dt_s"), std::string::npos) << r.out;
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
      " --set scene.prep_max_s=10 --set numerics.dt_s=0.5 --set duration_s=20"
      " --set sample_every_s=1 --set numerics.triangles_per_cell=80 --set snapshot_every_s=10"
      " --wait 2>/dev/null";
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
      " --scene cell --set duration_s=1500 --set sample_every_s=100"
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
    EXPECT_EQ(interrupted["samples"][i][5], clean["samples"][i][5]) << "sample " << i;
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
           " --set numerics.triangles_per_cell=80 --set snapshot_every_s=0 2>/dev/null");
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

TEST(Cli, TlsAndTokenFromFlagsAndEnvironment) {
  const fs::path dir = tempDir();
  const std::string cert = std::string(SERVER_TEST_DATA) + "/test-cert.pem";
  const std::string key = std::string(SERVER_TEST_DATA) + "/test-key.pem";
  const fs::path token = dir / "token";
  std::ofstream(token) << "t0ken\n";
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
  EXPECT_EQ(sh("FOAM_TLS_CA=" + cert + " FOAM_TOKEN=t0ken " + foam + " list 2>/dev/null").rc, 0);
  EXPECT_EQ(sh(foam + " --token-file " + token.string() + " list 2>/dev/null").rc, 3);  // plain
  d.stop(SIGTERM);
  fs::remove_all(dir);
}
