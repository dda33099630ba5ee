// Fault injection against foamd as a process: the everyday mistakes of a deployment
// must not corrupt or split results.
#include <algorithm>
#include <csignal>
#include <fstream>
#include <iostream>
#include <iterator>
#include <random>
#include <set>
#include <sstream>
#include <string>

#include <gtest/gtest.h>

#include "process.h"

using namespace activefoam::testing;

namespace {

std::string readAll(const fs::path& p) {
  std::ifstream in(p);
  return std::string((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
}

// Submits a small cell job (retrying while the server starts); returns its id.
std::string submitCell(const Foamd& d, double duration_s, double sample_every_s = 1) {
  const std::string cmd = d.foam() +
                          " submit --scene cell --set duration_s=" + std::to_string(duration_s) +
                          " --set sample_every_s=" + std::to_string(sample_every_s) +
                          " --set numerics.triangles_per_cell=320 --set snapshot_every_s=0"
                          " --set numerics.dt_s=0.1 2>/dev/null";
  for (int i = 0; i < 100; ++i) {
    const Proc r = sh(cmd);
    if (r.rc == 0) return firstLine(r.out);
    std::this_thread::sleep_for(100ms);
  }
  return "";
}

// A job's samples as CSV lines without the wall-clock column (wall_s, the third): what must be
// identical between an interrupted run and an uninterrupted one.
std::vector<std::string> samplesWithoutWallTime(const Foamd& d, const std::string& id) {
  const Proc r = sh(d.foam() + " results " + id + " --csv 2>&1");
  EXPECT_EQ(r.rc, 0) << r.out;
  std::vector<std::string> out;
  std::istringstream lines(r.out);
  for (std::string line; std::getline(lines, line);) {
    const auto a = line.find(',', line.find(',') + 1);
    const auto b = line.find(',', a + 1);
    out.push_back(line.substr(0, a) + line.substr(b));
  }
  return out;
}

}  // namespace

// kill -9 at random moments while a queue of three jobs runs on one worker (each ~1 s of wall
// time, checkpoints every 200 simulated seconds, 60 a job): after the last restart every job ends
// succeeded with the samples of an uninterrupted run, bit for bit (wall time aside), each time
// once. Each kill waits for a job to start in that incarnation and then for a random moment, so
// that kills land mid-run however fast the host is (a fixed window from the start let a fast host
// finish the whole queue between two kills). The seed of the moments is printed for a rerun
// (FOAM_KILL_SEED).
TEST(Faults, KillDashNineAtRandomMomentsOfAThreeJobQueue) {
  const fs::path dir = tempDir();
  const int port = freePort();
  std::uint64_t seed = std::random_device{}();
  if (const char* s = std::getenv("FOAM_KILL_SEED")) seed = std::stoull(s);
  SCOPED_TRACE("FOAM_KILL_SEED=" + std::to_string(seed));
  std::mt19937_64 rng(seed);
  const std::vector<std::string> flags{"--checkpoint-every-s", "200"};
  auto submit = [](const Foamd& d, int job_seed, const std::string& tag) {
    const std::string cmd = d.foam() +
                            " submit --scene cell --set duration_s=12000 --set sample_every_s=800"
                            " --set numerics.dt_s=0.1 --set numerics.triangles_per_cell=80"
                            " --set snapshot_every_s=0"
                            " --set seed=" +
                            std::to_string(job_seed) + " --tag " + tag + " 2>/dev/null";
    for (int i = 0; i < 100; ++i) {
      const Proc r = sh(cmd);
      if (r.rc == 0) return firstLine(r.out);
      std::this_thread::sleep_for(100ms);
    }
    return std::string();
  };
  std::string log;
  auto count = [&](const std::string& what) {
    std::size_t n = 0;
    for (auto p = log.find(what); p != std::string::npos; p = log.find(what, p + 1)) ++n;
    return n;
  };
  // Attempts begun, from scratch or from a checkpoint.
  auto starts = [&] { return count(": starting (") + count(": resuming from checkpoint at"); };
  // Waits (up to 10 s) for a job to start after `started_before` starts in the log, then for a
  // random moment of up to half a job's wall time, and kills. False when no job started: the queue
  // has drained.
  auto killWhileRunning = [&](Foamd& d, std::size_t started_before) {
    const auto until = std::chrono::steady_clock::now() + 10s;
    bool started = false;
    while (!started && std::chrono::steady_clock::now() < until) {
      log = readAll(dir / "foamd.log");
      started = starts() > started_before;
      if (!started) std::this_thread::sleep_for(5ms);
    }
    if (started)
      std::this_thread::sleep_for(
          std::chrono::milliseconds(std::uniform_int_distribution<int>(20, 500)(rng)));
    d.stop(SIGKILL);
    log = readAll(dir / "foamd.log");
    return started;
  };
  std::vector<std::string> ids;
  {
    Foamd d(dir / "foamd.db", port, 1, flags);
    for (int s = 1; s <= 3; ++s) ids.push_back(submit(d, s, "killed"));
    for (const auto& id : ids) ASSERT_FALSE(id.empty());
    killWhileRunning(d, 0);
  }
  for (int k = 0; k < 5 || (k < 12 && (count("were running when foamd stopped") < 2 ||
                                       count("resuming from checkpoint") < 1));
       ++k) {
    const std::size_t started_before = starts();
    Foamd d(dir / "foamd.db", port, 1, flags);
    if (!killWhileRunning(d, started_before)) break;
  }
  Foamd d(dir / "foamd.db", port, 1, flags);
  // The kills must have hit running jobs, and some of those must have resumed from a checkpoint
  // (not from the start): otherwise this tests nothing.
  log = readAll(dir / "foamd.log");
  std::cout << "kills that hit a running job: " << count("were running when foamd stopped")
            << ", resumed from a checkpoint: " << count("resuming from checkpoint") << "\n";
  EXPECT_GE(count("were running when foamd stopped"), 2u) << log;
  EXPECT_GE(count("resuming from checkpoint"), 1u) << log;
  for (const auto& id : ids) {
    const Proc w = sh(d.foam() + " watch " + id + " -q 2>&1");
    EXPECT_EQ(w.rc, 0) << id << ": " << w.out;
  }
  for (int s = 1; s <= 3; ++s) {
    const std::string ref = submit(d, s, "uninterrupted");
    ASSERT_FALSE(ref.empty());
    ASSERT_NE(ref, ids[s - 1]);
    EXPECT_EQ(sh(d.foam() + " watch " + ref + " -q 2>/dev/null").rc, 0);
    const std::vector<std::string> clean = samplesWithoutWallTime(d, ref);
    const std::vector<std::string> killed = samplesWithoutWallTime(d, ids[s - 1]);
    ASSERT_EQ(clean.size(), 17u);  // the header and t = 0, 800, ..., 12000 s
    EXPECT_EQ(killed, clean) << "job " << ids[s - 1] << " (seed " << s << ")";
  }
  d.stop(SIGTERM);
  fs::remove_all(dir);
}

// The second foamd on a database in use exits 2 naming the first's pid, before it touches the
// database: the first's running job is not re-queued and run twice, and ends with exactly its
// own samples (before the lock: 52 samples instead of 31, times repeated and out of order).
TEST(Faults, ASecondFoamdOnTheSameDatabaseIsRefused) {
  const fs::path dir = tempDir();
  Foamd a(dir / "foamd.db", freePort());
  const std::string id = submitCell(a, 3000, 100);
  ASSERT_FALSE(id.empty());
  for (int i = 0; i < 200 && state(a, id) != "running"; ++i) std::this_thread::sleep_for(50ms);
  ASSERT_EQ(state(a, id), "running");

  Foamd b(dir / "foamd.db", freePort());  // logs into the same foamd.log
  const std::optional<int> rc = b.exited(10s);
  ASSERT_TRUE(rc.has_value()) << "the second foamd is still running";
  EXPECT_EQ(*rc, 2);
  const std::string log = readAll(dir / "foamd.log");
  EXPECT_NE(log.find("is in use by another foamd (pid " + std::to_string(a.pid())),
            std::string::npos)
      << log;

  const Proc w = sh(a.foam() + " watch " + id + " -q");
  EXPECT_EQ(firstLine(w.out), "succeeded") << w.out;
  const Proc r = sh(a.foam() + " results " + id + " --csv");
  ASSERT_EQ(r.rc, 0);
  std::istringstream lines(r.out);
  std::string line;
  std::getline(lines, line);  // header
  std::vector<double> t;
  while (std::getline(lines, line)) t.push_back(std::stod(line.substr(0, line.find(','))));
  ASSERT_EQ(t.size(), 31u) << r.out;
  for (std::size_t k = 0; k < t.size(); ++k) EXPECT_DOUBLE_EQ(t[k], 100.0 * k);

  // Once the first has stopped, the database is free again: the lock dies with its holder.
  a.stop(SIGKILL);
  Foamd c(dir / "foamd.db", freePort());
  EXPECT_FALSE(c.exited(1500ms).has_value()) << readAll(dir / "foamd.log");
  EXPECT_EQ(state(c, id), "succeeded");
  fs::remove_all(dir);
}

// The lock is the database file's, not its name's (a second foamd through a symlink
// re-queued and resumed the first's running job — 56 samples where 31 belong — and through a
// hard link migrated the schema of the shared file): through a symlink, a hard link, a
// symlinked directory or a relative path, the second foamd exits 2 naming the first's pid, and
// the first's job ends with exactly its own samples.
TEST(Faults, ASecondFoamdThroughAnyAliasOfTheDatabaseIsRefused) {
  const fs::path dir = tempDir();
  const fs::path db = dir / "foamd.db";
  Foamd a(db, freePort());
  const std::string id = submitCell(a, 3000, 100);
  ASSERT_FALSE(id.empty());
  for (int i = 0; i < 200 && state(a, id) != "running"; ++i) std::this_thread::sleep_for(50ms);
  ASSERT_EQ(state(a, id), "running");

  fs::create_directories(dir / "links");
  fs::create_symlink(db, dir / "links" / "symlink.db");
  fs::create_hard_link(db, dir / "links" / "hardlink.db");
  fs::create_directory_symlink(dir, dir / "links" / "dirlink");
  const std::vector<fs::path> aliases = {
      dir / "links" / "symlink.db", dir / "links" / "hardlink.db",
      dir / "links" / "dirlink" / "foamd.db", fs::relative(db, fs::current_path())};
  for (const fs::path& alias : aliases) {
    fs::remove(alias.parent_path() / "foamd.log");
    Foamd b(alias, freePort());
    const std::optional<int> rc = b.exited(10s);
    ASSERT_TRUE(rc.has_value()) << alias << ": the second foamd is still running";
    EXPECT_EQ(*rc, 2) << alias;
    const std::string log = readAll(alias.parent_path() / "foamd.log");
    EXPECT_NE(log.find("is in use by another foamd (pid " + std::to_string(a.pid())),
              std::string::npos)
        << alias << ":\n"
        << log;
  }
  const Proc w = sh(a.foam() + " watch " + id + " -q");
  EXPECT_EQ(firstLine(w.out), "succeeded") << w.out;
  const Proc r = sh(a.foam() + " results " + id + " --csv");
  ASSERT_EQ(r.rc, 0);
  EXPECT_EQ(std::count(r.out.begin(), r.out.end(), '\n'), 32) << r.out;  // header + 31 samples
  a.stop(SIGKILL);
  Foamd c(dir / "foamd.db", freePort());
  EXPECT_FALSE(c.exited(1500ms).has_value()) << readAll(dir / "foamd.log");
  EXPECT_EQ(state(c, id), "succeeded");
  fs::remove_all(dir);
}

// A second foamd on a port in use (with its own database) exits 2 naming the address; every
// client reaches the first (before: gRPC's SO_REUSEPORT let both listen, and 1 submit in 10
// went to the other database).
TEST(Faults, ASecondFoamdOnTheSamePortIsRefused) {
  const fs::path dir = tempDir();
  const int port = freePort();
  Foamd a(dir / "a.db", port);
  ASSERT_FALSE(submitCell(a, 1).empty());  // serving
  Foamd b(dir / "b.db", port);
  const std::optional<int> rc = b.exited(10s);
  ASSERT_TRUE(rc.has_value()) << "the second foamd is still running";
  EXPECT_EQ(*rc, 2);
  const std::string log = readAll(dir / "foamd.log");
  EXPECT_NE(log.find("cannot listen on 127.0.0.1:" + std::to_string(port) + ": the port is taken"),
            std::string::npos)
      << log;
  std::set<std::string> ids;
  for (int i = 0; i < 10; ++i) ids.insert(submitCell(a, 1));
  EXPECT_EQ(ids.size(), 10u);
  for (const std::string& id : ids) EXPECT_FALSE(state(a, id).empty()) << id;

  // foam cancel of a running job answers "cancelling" (it stops at its next step), not the
  // "running" it used to print; the job then ends cancelled.
  const std::string id = submitCell(a, 3000, 100);
  for (int i = 0; i < 400 && state(a, id) != "running"; ++i) std::this_thread::sleep_for(50ms);
  ASSERT_EQ(state(a, id), "running");
  EXPECT_EQ(firstLine(sh(a.foam() + " cancel " + id).out), "cancelling");
  for (int i = 0; i < 200 && state(a, id) == "running"; ++i) std::this_thread::sleep_for(50ms);
  EXPECT_EQ(state(a, id), "cancelled");
  fs::remove_all(dir);
}

// A foamd on [::1]:P started beside one on 127.0.0.1:P (`localhost:P` then
// reached either), and a second --http on a taken port bound too (cpp-httplib's SO_REUSEPORT:
// requests alternated between the two servers). Each is refused, naming the other listener.
// An empty --token-file (on the command line or in the config) is refused, not taken as "no
// token": foamd once started without auth in silence.
TEST(Faults, AnEmptyTokenFileIsRefused) {
  const fs::path dir = tempDir();
  const std::string base = "timeout 10 " + std::string(FOAMD_EXE) +
                           " --listen 127.0.0.1:" + std::to_string(freePort()) + " --db " +
                           (dir / "f.db").string();
  Proc r = sh(base + " --token-file '' 2>&1");
  EXPECT_EQ(r.rc, 2) << r.out;
  EXPECT_NE(r.out.find("--token-file: empty"), std::string::npos) << r.out;
  { std::ofstream(dir / "foamd.toml") << "token-file = \"\"\n"; }
  r = sh(base + " --config " + (dir / "foamd.toml").string() + " 2>&1");
  EXPECT_EQ(r.rc, 2) << r.out;
  EXPECT_NE(r.out.find("--token-file: empty"), std::string::npos) << r.out;
  EXPECT_FALSE(fs::exists(dir / "f.db"));
  fs::remove_all(dir);
}

TEST(Faults, ListenersBesideAnotherFoamdAreRefused) {
  const fs::path dir = tempDir();
  const int port = freePort(), http = freePort();
  Foamd a(dir / "a.db", port, 1, {"--http", "127.0.0.1:" + std::to_string(http)});
  ASSERT_FALSE(submitCell(a, 1).empty());  // serving
  auto foamd = [&](const std::string& listen, const std::string& http_listen, const char* db) {
    // `timeout`: without the check the second foamd starts and serves (the test then fails).
    return sh("timeout 10 " + std::string(FOAMD_EXE) + " --listen " + listen + " --db " +
              (dir / db).string() + (http_listen.empty() ? "" : " --http " + http_listen) +
              " 2>&1");
  };
  Proc r =
      foamd("127.0.0.1:" + std::to_string(freePort()), "127.0.0.1:" + std::to_string(http), "c.db");
  EXPECT_EQ(r.rc, 2) << r.out;
  EXPECT_NE(r.out.find("--http: cannot listen on 127.0.0.1:" + std::to_string(http)),
            std::string::npos)
      << r.out;
  // The other loopback family needs ::1 on this machine (containers may lack it).
  const int probe = socket(AF_INET6, SOCK_STREAM, 0);
  sockaddr_in6 any6{};
  any6.sin6_family = AF_INET6;
  any6.sin6_addr = in6addr_loopback;
  const bool ipv6 = probe >= 0 && bind(probe, reinterpret_cast<sockaddr*>(&any6), sizeof any6) == 0;
  if (probe >= 0) close(probe);
  if (ipv6) {
    r = foamd("[::1]:" + std::to_string(port), "", "b.db");
    EXPECT_EQ(r.rc, 2) << r.out;
    EXPECT_NE(r.out.find("port " + std::to_string(port) + " is taken on 127.0.0.1"),
              std::string::npos)
        << r.out;
    r = foamd("127.0.0.1:" + std::to_string(freePort()), "[::1]:" + std::to_string(http), "d.db");
    EXPECT_EQ(r.rc, 2) << r.out;
    EXPECT_NE(r.out.find("is taken on 127.0.0.1"), std::string::npos) << r.out;
  }
  EXPECT_FALSE(submitCell(a, 1).empty());  // the first still serves
  fs::remove_all(dir);
  if (!ipv6) GTEST_SKIP() << "no ::1 here: the IPv4/IPv6 half was not checked";
}

// Pages of the database overwritten on disk went unnoticed at start (health
// SERVING, then ListJobs INTERNAL "database disk image is malformed"). foamd checks the store
// (PRAGMA quick_check) before it serves, and refuses a damaged one naming it.
TEST(Faults, ADamagedDatabaseIsRefusedAtStart) {
  const fs::path dir = tempDir();
  const fs::path db = dir / "foamd.db";
  {
    Foamd a(db, freePort());
    for (int i = 0; i < 30; ++i) ASSERT_FALSE(submitCell(a, 1e6).empty());  // queued jobs: pages
    a.stop(SIGTERM);                                                        // WAL checkpointed
  }
  ASSERT_GT(fs::file_size(db), 4u * 4096);
  {
    std::fstream f(db, std::ios::in | std::ios::out | std::ios::binary);
    f.seekp(2 * 4096);  // past the header page: b-tree pages of the tables
    const std::string junk(2 * 4096, '\x55');
    f.write(junk.data(), static_cast<std::streamsize>(junk.size()));
  }
  const Proc r = sh("timeout 10 " + std::string(FOAMD_EXE) + " --listen 127.0.0.1:" +
                    std::to_string(freePort()) + " --db " + db.string() + " 2>&1");
  EXPECT_EQ(r.rc, 2) << r.out;
  EXPECT_NE(r.out.find("database '" + db.string() + "' is damaged"), std::string::npos) << r.out;
  fs::remove_all(dir);
}

// A job's tag altered on disk in its table row (its index entry left as it was) passes the
// quick_check that foamd's start runs: foamd serves the altered row.
// foamd --check-db runs the full integrity_check, which compares each index with its table:
// exit 1, one line naming the database and the index. A sound store: exit 0; one that a running
// foamd holds, or none at all: exit 2, nothing created.
TEST(Faults, CheckDbFindsDamageThatTheStartMisses) {
  const fs::path dir = tempDir();
  const fs::path db = dir / "foamd.db";
  const std::string marker = "integrity-marker-0001";
  {
    Foamd a(db, freePort());
    for (int i = 0; i < 5; ++i) ASSERT_FALSE(submitCell(a, 1e6).empty());
    const Proc r =
        sh(a.foam() + " submit --scene cell --set duration_s=1e6 --set numerics.dt_s=0.1 --tag " +
           marker + " 2>&1");
    ASSERT_EQ(r.rc, 0) << r.out;
    const Proc held = sh(std::string(FOAMD_EXE) + " --check-db --db " + db.string() + " 2>&1");
    EXPECT_EQ(held.rc, 2) << held.out;
    EXPECT_NE(held.out.find("foamd --check-db: "), std::string::npos) << held.out;
    a.stop(SIGTERM);  // the WAL checkpointed into the file
  }
  Proc r = sh(std::string(FOAMD_EXE) + " --check-db --db " + db.string() + " 2>&1");
  EXPECT_EQ(r.rc, 0) << r.out;
  EXPECT_NE(r.out.find("database '" + db.string() + "' is sound"), std::string::npos) << r.out;
  // The marker's copies: the jobs row, on a leaf page of a rowid table (type byte 0x0d at the
  // page's start, past the file header on page 1; the tag is among the row's first columns, so
  // not in an overflow page), the jobs_tag entry (an index page) and the submit event (events
  // is a table WITHOUT ROWID: index pages too).
  std::string bytes = readAll(db);
  const std::size_t page = 4096;
  ASSERT_EQ(static_cast<unsigned char>(bytes[16]) * 256 + static_cast<unsigned char>(bytes[17]),
            static_cast<int>(page));
  std::size_t in_row = std::string::npos;
  int rows = 0, others = 0;
  for (std::size_t at = bytes.find(marker); at != std::string::npos;
       at = bytes.find(marker, at + 1)) {
    const std::size_t start = at / page * page + (at < page ? 100 : 0);
    if (static_cast<unsigned char>(bytes[start]) == 0x0d)
      ++rows, in_row = at;
    else
      ++others;
  }
  ASSERT_EQ(rows, 1);
  ASSERT_GE(others, 1);                     // the index entry
  bytes[in_row + marker.size() - 1] = '2';  // ...-0002: same length, the record stays well-formed
  {
    std::ofstream f(db, std::ios::binary | std::ios::trunc);
    f.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
  }
  {
    Foamd b(db, freePort());  // quick_check passes: foamd serves the altered row
    std::string listed;
    for (int i = 0; i < 100; ++i) {
      const Proc l = sh(b.foam() + " list 2>&1");
      if (l.rc == 0) {
        listed = l.out;
        break;
      }
      std::this_thread::sleep_for(100ms);
    }
    EXPECT_NE(listed.find("integrity-marker-0002"), std::string::npos) << listed;
  }
  r = sh(std::string(FOAMD_EXE) + " --check-db --db " + db.string() + " 2>&1");
  EXPECT_EQ(r.rc, 1) << r.out;
  EXPECT_NE(r.out.find("database '" + db.string() + "' is damaged (integrity_check: "),
            std::string::npos)
      << r.out;
  EXPECT_NE(r.out.find("jobs_tag"), std::string::npos) << r.out;
  EXPECT_EQ(std::count(r.out.begin(), r.out.end(), '\n'), 1) << r.out;
  r = sh(std::string(FOAMD_EXE) + " --check-db --db " + (dir / "none.db").string() + " 2>&1");
  EXPECT_EQ(r.rc, 2) << r.out;
  EXPECT_NE(r.out.find("no such file"), std::string::npos) << r.out;
  EXPECT_FALSE(fs::exists(dir / "none.db"));
  fs::remove_all(dir);
}

// Each signal that stops foamd stops it as SIGTERM does: exit 0, its running job re-queued to
// resume, a log line naming the signal, and a store that passes SQLite's integrity_check
// (foamd --check-db) and serves the job on the next start. SIGHUP once killed it in silence
// (exit 129, no log), SIGQUIT with a core dump.
class StopSignal : public ::testing::TestWithParam<std::pair<int, std::string>> {};

TEST_P(StopSignal, StopsFoamdCleanlyWithALogLine) {
  const auto& [sig, name] = GetParam();
  const fs::path dir = tempDir();
  const int port = freePort();
  std::string id;
  {
    Foamd a(dir / "foamd.db", port);
    id = submitCell(a, 3000, 100);
    ASSERT_FALSE(id.empty());
    for (int i = 0; i < 200 && state(a, id) != "running"; ++i) std::this_thread::sleep_for(50ms);
    ASSERT_EQ(state(a, id), "running");
    ::kill(a.pid(), sig);
    const std::optional<int> rc = a.exited(30s);
    ASSERT_TRUE(rc.has_value()) << "foamd ignored " << name;
    EXPECT_EQ(*rc, 0) << name;
  }
  const std::string log = readAll(dir / "foamd.log");
  EXPECT_NE(log.find(name + " received, shutting down"), std::string::npos) << log;
  EXPECT_NE(log.find("re-queued at shutdown"), std::string::npos) << log;
  EXPECT_NE(log.find("foamd: stopped"), std::string::npos) << log;
  const Proc check =
      sh(std::string(FOAMD_EXE) + " --check-db --db " + (dir / "foamd.db").string() + " 2>&1");
  EXPECT_EQ(check.rc, 0) << check.out;
  Foamd b(dir / "foamd.db", port);
  const std::string after = state(b, id);
  EXPECT_TRUE(after == "queued" || after == "running" || after == "succeeded") << after;
  fs::remove_all(dir);
}

INSTANTIATE_TEST_SUITE_P(Faults, StopSignal,
                         ::testing::Values(std::pair<int, std::string>{SIGTERM, "SIGTERM"},
                                           std::pair<int, std::string>{SIGINT, "SIGINT"},
                                           std::pair<int, std::string>{SIGHUP, "SIGHUP"},
                                           std::pair<int, std::string>{SIGQUIT, "SIGQUIT"},
                                           std::pair<int, std::string>{SIGXCPU, "SIGXCPU"}),
                         [](const auto& info) { return info.param.second; });

// SIGUSR1, SIGUSR2, SIGALRM and SIGPIPE ended foamd with no log line (exit 138, 140, 142, 141).
// Each signal whose default would end it is logged and ignored, SIGPIPE ignored without a word;
// foamd then serves and runs a job. Without --http: cpp-httplib ignores SIGPIPE for the whole
// process once its server exists, which hid the gap whenever the dashboard was on.
TEST(Faults, SignalsThatDoNotStopFoamdAreIgnored) {
  const fs::path dir = tempDir();
  Foamd a(dir / "foamd.db", freePort());
  ASSERT_FALSE(submitCell(a, 1).empty());  // serving
  const std::vector<std::pair<int, std::string>> ignored = {
      {SIGUSR1, "SIGUSR1"},     {SIGUSR2, "SIGUSR2"}, {SIGALRM, "SIGALRM"},
      {SIGVTALRM, "SIGVTALRM"}, {SIGIO, "SIGIO"},     {SIGPWR, "SIGPWR"},
      {SIGSTKFLT, "SIGSTKFLT"}, {SIGPIPE, "SIGPIPE"}};
  for (const auto& [sig, name] : ignored) {
    ::kill(a.pid(), sig);
    std::this_thread::sleep_for(100ms);
    ASSERT_FALSE(a.exited(0ms).has_value()) << "foamd ended on " << name;
  }
  const std::string id = submitCell(a, 1);
  ASSERT_FALSE(id.empty());
  for (int i = 0; i < 200 && state(a, id) != "succeeded"; ++i) std::this_thread::sleep_for(50ms);
  EXPECT_EQ(state(a, id), "succeeded");
  a.stop(SIGTERM);
  const std::string log = readAll(dir / "foamd.log");
  for (const auto& [sig, name] : ignored) {
    if (sig == SIGPIPE) continue;
    EXPECT_NE(log.find(name + " received, ignored"), std::string::npos) << name << "\n" << log;
  }
  EXPECT_EQ(log.find("SIGPIPE"), std::string::npos) << log;
  fs::remove_all(dir);
}

// A TLS client of the HTTP endpoint that is gone before its answer: foamd's writes to it fail
// with EPIPE (SSL_write writes without MSG_NOSIGNAL, so each raises SIGPIPE). foamd goes on
// serving: the client then reads /healthz whole.
TEST(Faults, AClientGoneMidAnswerDoesNotStopFoamd) {
  const fs::path dir = tempDir();
  const int http = freePort();
  const std::string data = SERVER_TEST_DATA;
  fs::copy_file(data + "/test-key.pem", dir / "key.pem");
  fs::permissions(dir / "key.pem", fs::perms::owner_read | fs::perms::owner_write);
  Foamd a(dir / "foamd.db", freePort(), 1,
          {"--http", "127.0.0.1:" + std::to_string(http), "--tls-cert", data + "/test-cert.pem",
           "--tls-key", (dir / "key.pem").string()});
  // Asks for the dashboard's script (32 KiB, several TLS records) and closes at once, five
  // times; then /healthz.
  const Proc gone = sh("/usr/bin/python3 - " + std::to_string(http) +
                       " 2>&1 <<'EOF'\n"
                       "import socket, ssl, sys, time\n"
                       "ctx = ssl.SSLContext(ssl.PROTOCOL_TLS_CLIENT)\n"
                       "ctx.check_hostname = False\n"
                       "ctx.verify_mode = ssl.CERT_NONE\n"
                       "def connect():\n"
                       "    for _ in range(100):\n"
                       "        try:\n"
                       "            return ctx.wrap_socket(socket.create_connection(('127.0.0.1', "
                       "int(sys.argv[1]))))\n"
                       "        except OSError:\n"
                       "            time.sleep(0.1)\n"
                       "    sys.exit('foamd did not listen')\n"
                       "for _ in range(5):\n"
                       "    t = connect()\n"
                       "    t.sendall(b'GET /app.js HTTP/1.1\\r\\nHost: 127.0.0.1\\r\\n\\r\\n')\n"
                       "    t.close()\n"
                       "    time.sleep(0.3)\n"
                       "t = connect()\n"
                       "t.sendall(b'GET /healthz HTTP/1.1\\r\\nHost: 127.0.0.1\\r\\n\\r\\n')\n"
                       "answer = b''\n"
                       "try:\n"
                       "    while chunk := t.recv(4096):\n"
                       "        answer += chunk\n"
                       "except OSError:\n"
                       "    pass  # closed without a close_notify: the answer is read\n"
                       "print(answer.decode())\n"
                       "EOF");
  EXPECT_EQ(gone.rc, 0) << gone.out;
  EXPECT_NE(gone.out.find("HTTP/1.1 200"), std::string::npos) << gone.out;
  EXPECT_NE(gone.out.find("{\"status\":\"ok\"}"), std::string::npos) << gone.out;
  EXPECT_FALSE(a.exited(0ms).has_value()) << "foamd ended when a client left mid-answer";
  fs::remove_all(dir);
}

// A misspelt config key (`token_file` for `token-file`) started foamd without its
// token; a bogus --log-level ran with no log. Both exit 2 naming what is wrong.
TEST(Faults, ConfigTyposAndBadLogLevelsAreRefused) {
  const fs::path dir = tempDir();
  std::ofstream(dir / "token") << "s3cret-s3cret-s3cret-42\n";
  fs::permissions(dir / "token", fs::perms::owner_read | fs::perms::owner_write);
  std::ofstream(dir / "foamd.toml") << "token_file = \"" << (dir / "token").string() << "\"\n";
  {
    Foamd a(dir / "foamd.db", freePort(), 1, {"--config", (dir / "foamd.toml").string()});
    const std::optional<int> rc = a.exited(10s);
    ASSERT_TRUE(rc.has_value()) << "foamd started with an unknown config key";
    EXPECT_EQ(*rc, 2);
    const std::string log = readAll(dir / "foamd.log");
    EXPECT_NE(log.find("unknown key 'token_file' (did you mean 'token-file'?)"), std::string::npos)
        << log;
  }
  {
    Foamd b(dir / "foamd.db", freePort(), 1, {"--log-level", "bogus"});
    const std::optional<int> rc = b.exited(10s);
    ASSERT_TRUE(rc.has_value()) << "foamd started with --log-level bogus";
    EXPECT_EQ(*rc, 2);
    EXPECT_NE(readAll(dir / "foamd.log").find("--log-level"), std::string::npos);
  }
  // The spelling of the flag works: foamd starts and wants the token.
  std::ofstream(dir / "foamd.toml") << "token-file = \"" << (dir / "token").string() << "\"\n";
  Foamd c(dir / "foamd.db", freePort(), 1, {"--config", (dir / "foamd.toml").string()});
  EXPECT_FALSE(c.exited(1500ms).has_value()) << readAll(dir / "foamd.log");
  const Proc anon = sh(c.foam() + " list 2>&1");
  EXPECT_EQ(anon.rc, 4) << anon.out;  // unauthenticated
  fs::remove_all(dir);
}

// Ports beyond 65535 were taken modulo 65536 (--listen 127.0.0.1:92786 listened on
// 27250; foam --server 127.0.0.1:87366 reached port 21830). Both refuse them, naming the flag.
TEST(Faults, PortsOutsideTheirRangeAreRefused) {
  const fs::path dir = tempDir();
  // `timeout`: without the check foamd starts and serves (the test then fails, not hangs).
  const Proc d = sh("timeout 10 " + std::string(FOAMD_EXE) + " --listen 127.0.0.1:92786 --db " +
                    (dir / "foamd.db").string() + " 2>&1");
  EXPECT_EQ(d.rc, 2) << d.out;
  EXPECT_NE(d.out.find("--listen: '127.0.0.1:92786': the port 92786 is outside 0..65535"),
            std::string::npos)
      << d.out;
  EXPECT_FALSE(fs::exists(dir / "foamd.db"));  // refused before the store is touched
  const Proc h = sh("timeout 10 " + std::string(FOAMD_EXE) + " --http 127.0.0.1:0x50 --db " +
                    (dir / "foamd.db").string() + " 2>&1");
  EXPECT_EQ(h.rc, 2) << h.out;
  EXPECT_NE(h.out.find("--http:"), std::string::npos) << h.out;
  for (const std::string server : {"127.0.0.1:87366", "127.0.0.1:", "localhost", "::1:50051"}) {
    const Proc c =
        sh("timeout 10 " + std::string(FOAM_EXE) + " --server '" + server + "' list 2>&1");
    EXPECT_EQ(c.rc, 2) << server << ": " << c.out;
    EXPECT_NE(c.out.find("--server (or FOAM_SERVER)"), std::string::npos) << c.out;
  }
  const Proc env = sh("FOAM_SERVER=127.0.0.1:70000 " + std::string(FOAM_EXE) + " list 2>&1");
  EXPECT_EQ(env.rc, 2) << env.out;
  fs::remove_all(dir);
}

// A token file with a newline inside, binary or non-ASCII bytes, or 1 MB was accepted
// by foamd, and foam then aborted in gRPC's metadata check (exit 134). Both refuse it at load,
// naming the file and the byte; FOAM_TOKEN likewise.
TEST(Faults, TokensThatCannotBeSentAreRefusedAtLoad) {
  const fs::path dir = tempDir();
  const std::vector<std::pair<std::string, std::string>> bad = {
      {"newline", "first-half-of-it\nsecond-half-of-it\n"},
      {"binary", std::string("binary-token-") + '\0' + '\x01' + "-0123456789"},
      {"non-ascii", "t\xc3\xb6ken-0123456789-abcdef"},
      {"huge", std::string(1 << 20, 'x')}};
  for (const auto& [name, content] : bad) {
    const fs::path f = dir / name;
    std::ofstream(f, std::ios::binary) << content;
    fs::permissions(f, fs::perms::owner_read | fs::perms::owner_write);
    const Proc d = sh("timeout 10 " + std::string(FOAMD_EXE) +
                      " --listen 127.0.0.1:" + std::to_string(freePort()) + " --db " +
                      (dir / "foamd.db").string() + " --token-file " + f.string() + " 2>&1");
    EXPECT_EQ(d.rc, 2) << name << ": " << d.out;
    EXPECT_NE(d.out.find("token file '" + f.string() + "'"), std::string::npos) << d.out;
    const Proc c =
        sh("timeout 10 " + std::string(FOAM_EXE) + " --token-file " + f.string() + " list 2>&1");
    EXPECT_EQ(c.rc, 2) << name << ": " << c.out;
  }
  const Proc env =
      sh("FOAM_TOKEN=$(printf 'has a space in it 0123') " + std::string(FOAM_EXE) + " list 2>&1");
  EXPECT_EQ(env.rc, 2) << env.out;
  EXPECT_NE(env.out.find("FOAM_TOKEN has byte 0x20"), std::string::npos) << env.out;
  fs::remove_all(dir);
}

// An empty FOAM_TOKEN (`FOAM_TOKEN=$TOKEN` with TOKEN unset) made foam call without a token in
// silence, and so did `--token-file ''`; `--tls-ca ''` connected without TLS. Each is an error
// naming the variable or option (exit 2) before any call: foam is pointed at port 1, where a
// call would end in "unreachable" (exit 3) instead.
TEST(Faults, EmptyTokenAndCaValuesOfFoamAreErrors) {
  const std::string foam = std::string(FOAM_EXE) + " --server 127.0.0.1:1";
  Proc r = sh("FOAM_TOKEN= timeout 10 " + foam + " list 2>&1");
  EXPECT_EQ(r.rc, 2) << r.out;
  EXPECT_NE(r.out.find("FOAM_TOKEN holds 0 bytes"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("set but empty"), std::string::npos) << r.out;
  for (const std::string opt : {"--token-file", "--tls-ca"}) {
    r = sh("timeout 10 " + std::string(FOAM_EXE) + " --server 127.0.0.1:1 " + opt +
           " '' list 2>&1");
    EXPECT_EQ(r.rc, 2) << opt << ": " << r.out;
    EXPECT_NE(r.out.find(opt + ": empty"), std::string::npos) << r.out;
  }
  // Unset is no token: the call is made (and finds nothing on port 1).
  r = sh("env -u FOAM_TOKEN timeout 10 " + foam + " list 2>&1");
  EXPECT_EQ(r.rc, 3) << r.out;
}

// CLI11's Range lets NaN through (every comparison with it is false): `foam export --movie
// --fps nan` reached ffmpeg. A number option that is not finite is refused naming the option
// (exit 2), before any call.
TEST(Faults, NonFiniteNumbersOfFoamAreRefused) {
  for (const std::string v : {"nan", "inf", "-inf"}) {
    const Proc r = sh("timeout 10 " + std::string(FOAM_EXE) +
                      " --server 127.0.0.1:1 export j-1 x.mp4 --movie --fps " + v + " 2>&1");
    EXPECT_EQ(r.rc, 2) << v << ": " << r.out;
    EXPECT_NE(r.out.find("--fps: '" + v + "' is not a finite number"), std::string::npos) << r.out;
  }
}

// `foam submit /dev/zero` was OOM-killed at 24 GB and `yes | foam submit -` never
// ended: foam reads at most the 1 MiB a spec may have, and says so (exit 2).
TEST(Faults, UnboundedSpecInputIsCutAtItsLimit) {
  const Proc zero =
      sh("timeout 30 " + std::string(FOAM_EXE) + " --server 127.0.0.1:1 submit /dev/zero 2>&1");
  EXPECT_EQ(zero.rc, 2) << zero.out;
  EXPECT_NE(zero.out.find("'/dev/zero' holds more than 1 MiB"), std::string::npos) << zero.out;
  const Proc yes =
      sh("yes | timeout 30 " + std::string(FOAM_EXE) + " --server 127.0.0.1:1 submit - 2>&1");
  EXPECT_EQ(yes.rc, 2) << yes.out;
  EXPECT_NE(yes.out.find("standard input holds more than 1 MiB"), std::string::npos) << yes.out;
}
