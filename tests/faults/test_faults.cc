// Fault injection against foamd as a process (issue 18): the everyday mistakes of a deployment
// must not corrupt or split results.
#include <fstream>
#include <iterator>
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
                          " 2>/dev/null";
  for (int i = 0; i < 100; ++i) {
    const Proc r = sh(cmd);
    if (r.rc == 0) return firstLine(r.out);
    std::this_thread::sleep_for(100ms);
  }
  return "";
}

}  // namespace

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
