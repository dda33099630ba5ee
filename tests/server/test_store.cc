// The store (SQLite, one writer thread) and the job lifecycle table, without a server: job order
// and requeue after a restart, results and curves, outcomes and their filters, state changes.
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <future>
#include <string>
#include <thread>
#include <vector>

#include "store.h"
// Last: it pulls in <resolv.h>, whose `_res` macro breaks Eigen parameter names.
#include "process.h"

using namespace activefoam;
using namespace activefoam::server;
namespace fs = std::filesystem;

namespace {

fs::path tempDb() {
  return activefoam::testing::tempDir() / "foamd.db";
}

// A queued cell job as the service would store it.
NewJob cellJob(int priority = 0) {
  NewJob j;
  j.spec.scene = SceneKind::Cell;
  j.spec = resolve(j.spec);
  j.spec_json = "{}";
  j.priority = priority;
  return j;
}

}  // namespace

TEST(Store, PriorityThenAgeAndRequeueAfterRestart) {
  const fs::path db = tempDb();
  std::string low, high1, high2;
  {
    Store s(db.string());
    EXPECT_EQ(s.schemaVersion(), kSchemaVersion);
    low = s.submit(cellJob(0)).first;
    high1 = s.submit(cellJob(5)).first;
    high2 = s.submit(cellJob(5)).first;
    EXPECT_EQ(s.claimNext()->job.id(), high1);
    EXPECT_EQ(s.claimNext()->job.id(), high2);
    s.saveCheckpoint(high2, 3.5, "state");
  }  // "crash": two jobs left running
  Store s(db.string());
  EXPECT_EQ(s.requeueRunning("restart"), 2);
  EXPECT_EQ(s.getJob(high1)->state(), v1::JOB_STATE_QUEUED);
  EXPECT_EQ(s.getJob(high1)->reason(), "restart");
  const auto c1 = s.claimNext();
  EXPECT_EQ(c1->job.id(), high1);
  EXPECT_FALSE(c1->checkpoint);
  const auto c2 = s.claimNext();
  EXPECT_EQ(c2->job.id(), high2);
  ASSERT_TRUE(c2->checkpoint);
  EXPECT_EQ(*c2->checkpoint, "state");
  EXPECT_DOUBLE_EQ(c2->checkpoint_t_s, 3.5);
  EXPECT_EQ(c2->job.attempts(), 2);
  EXPECT_EQ(s.claimNext()->job.id(), low);
  fs::remove_all(db.parent_path());
}

// A finished run's curves (fusion: the MSRD against the lag) come back with its results, bit
// for bit and NaN included, and a restart from scratch drops them with the results.
TEST(Store, CurvesOfAFinishedRunComeBackWithItsResults) {
  const fs::path db = tempDb();
  Store s(db.string());
  const NewJob j = cellJob();
  const std::string id = s.submit(j).first;
  ASSERT_EQ(s.claimNext()->job.id(), id);
  const FlatCurve msrd{"msrd", {30, 60, 90.5}, {0.25, 1.0 / 3.0, std::nan("")}};
  // A probe's curves by their names, one with no points (a class that had no pairs).
  const FlatCurve surface{"msrd_surface", {30}, {0.5}}, buried{"msrd_buried", {}, {}};
  ASSERT_TRUE(s.finish(id, v1::JOB_STATE_SUCCEEDED, "", "", {{"x", 1.0}}, 90, 9, "",
                       {msrd, surface, buried}));
  const v1::JobResults r = s.results(id, false);
  ASSERT_EQ(r.curves_size(), 3);  // by name
  EXPECT_EQ(r.curves(1).name(), "msrd_buried");
  EXPECT_EQ(r.curves(1).x_size(), 0);
  EXPECT_EQ(r.curves(2).name(), "msrd_surface");
  EXPECT_EQ(r.curves(2).y(0), 0.5);
  EXPECT_EQ(r.curves(0).name(), "msrd");
  ASSERT_EQ(r.curves(0).x_size(), 3);
  ASSERT_EQ(r.curves(0).y_size(), 3);
  for (int k = 0; k < 3; ++k) EXPECT_EQ(r.curves(0).x(k), msrd.x[static_cast<size_t>(k)]);
  EXPECT_EQ(r.curves(0).y(1), 1.0 / 3.0);
  EXPECT_TRUE(std::isnan(r.curves(0).y(2)));
  s.resetOutputs(id, std::nullopt);
  EXPECT_EQ(s.results(id, false).curves_size(), 0);
  fs::remove_all(db.parent_path());
}

// flattenSummary carries summary.json's MSRD curve and the probes' (foam-run's, and a Slurm
// task's report).
TEST(Store, FlattenSummaryCarriesTheMsrdCurve) {
  const auto flat = flattenSummary(nlohmann::json::parse(
      R"({"t_s": 60, "msrd": {"lag_s": [30, 60], "msrd_um2": [0.5, null]},
          "curves": {"msrd_layer1": {"x": [30], "y": [0.125]}}})"));
  ASSERT_EQ(flat.curves.size(), 2u);
  EXPECT_EQ(flat.curves[1].name, "msrd_layer1");
  EXPECT_EQ(flat.curves[1].x, (std::vector<double>{30}));
  EXPECT_EQ(flat.curves[1].y, (std::vector<double>{0.125}));
  EXPECT_EQ(flat.curves[0].name, "msrd");
  EXPECT_EQ(flat.curves[0].x, (std::vector<double>{30, 60}));
  EXPECT_EQ(flat.curves[0].y[0], 0.5);
  EXPECT_TRUE(std::isnan(flat.curves[0].y[1]));
  EXPECT_TRUE(flattenSummary(nlohmann::json::parse(R"({"t_s": 1})")).curves.empty());
}

// The lifecycle table (job_states.h): exactly these six changes, nothing out of an end state.
TEST(JobStates, OnlyTheLifecycleTransitionsAreAllowed) {
  using S = v1::JobState;
  const std::vector<S> states = {S::JOB_STATE_QUEUED, S::JOB_STATE_RUNNING, S::JOB_STATE_SUCCEEDED,
                                 S::JOB_STATE_FAILED, S::JOB_STATE_CANCELLED};
  const std::set<std::pair<S, S>> allowed = {
      {S::JOB_STATE_QUEUED, S::JOB_STATE_RUNNING},    {S::JOB_STATE_QUEUED, S::JOB_STATE_CANCELLED},
      {S::JOB_STATE_RUNNING, S::JOB_STATE_SUCCEEDED}, {S::JOB_STATE_RUNNING, S::JOB_STATE_FAILED},
      {S::JOB_STATE_RUNNING, S::JOB_STATE_CANCELLED}, {S::JOB_STATE_RUNNING, S::JOB_STATE_QUEUED}};
  for (S from : states)
    for (S to : {S::JOB_STATE_UNSPECIFIED, S::JOB_STATE_QUEUED, S::JOB_STATE_RUNNING,
                 S::JOB_STATE_SUCCEEDED, S::JOB_STATE_FAILED, S::JOB_STATE_CANCELLED})
      EXPECT_EQ(allowedTransition(from, to), allowed.count({from, to}) == 1)
          << v1::JobState_Name(from) << " -> " << v1::JobState_Name(to);
  EXPECT_EQ(jobTransitions().size(), allowed.size());
  for (S s : states)
    EXPECT_EQ(isTerminal(s), s != S::JOB_STATE_QUEUED && s != S::JOB_STATE_RUNNING);
}

// Every store operation that would move a job outside the table leaves it as it is: finishing
// a queued or an ended job, ending it twice, re-queueing an ended one, cancelling an ended one,
// and finish() with a state that is not an end.
TEST(Store, StateChangesOutsideTheLifecycleAreRefused) {
  const fs::path db = tempDb();
  Store s(db.string());
  const NewJob j = cellJob();
  const std::string a = s.submit(j).first;
  EXPECT_FALSE(s.finish(a, v1::JOB_STATE_SUCCEEDED, "", "", {}, 1, 1));  // queued: not running
  EXPECT_FALSE(s.requeue(a, "x"));
  EXPECT_EQ(s.getJob(a)->state(), v1::JOB_STATE_QUEUED);
  ASSERT_EQ(s.claimNext()->job.id(), a);
  EXPECT_THROW(s.finish(a, v1::JOB_STATE_QUEUED, "", "", {}, 1, 1), std::logic_error);
  EXPECT_EQ(s.getJob(a)->state(), v1::JOB_STATE_RUNNING);
  EXPECT_TRUE(s.finish(a, v1::JOB_STATE_FAILED, "non-finite", "boom", {{"x", 1.0}}, 2, 20));
  const std::int64_t seq = s.getJob(a)->last_seq();
  EXPECT_FALSE(s.finish(a, v1::JOB_STATE_SUCCEEDED, "", "", {}, 3, 30));  // once only
  EXPECT_FALSE(s.requeue(a, "restart"));
  EXPECT_EQ(s.requeueRunning("restart"), 0);
  EXPECT_EQ(s.cancel(a, "late").state(), v1::JOB_STATE_FAILED);
  const v1::Job after = *s.getJob(a);
  EXPECT_EQ(after.state(), v1::JOB_STATE_FAILED);
  EXPECT_EQ(after.reason(), "boom");
  EXPECT_EQ(after.steps(), 20);
  EXPECT_EQ(after.last_seq(), seq) << "a refused change records no event";
  fs::remove_all(db.parent_path());
}

// Fusion outcomes are stored with the job's end and filter ListJobs and QueryResults; an
// unknown outcome is refused naming the field.
TEST(Store, OutcomeIsStoredAndFiltersJobsAndResults) {
  const fs::path db = tempDb();
  Store s(db.string());
  std::vector<std::string> ids;
  for (const char* outcome : {"fused", "separated", "fused", ""}) {
    ids.push_back(s.submit(cellJob()).first);
    ASSERT_EQ(s.claimNext()->job.id(), ids.back());
    ASSERT_TRUE(s.finish(ids.back(), v1::JOB_STATE_SUCCEEDED, "", "", {{"theta_deg", 40.0}}, 1, 10,
                         outcome));
  }
  EXPECT_EQ(s.getJob(ids[1])->outcome(), "separated");
  EXPECT_EQ(s.getJob(ids[3])->outcome(), "");
  v1::ListJobsRequest lr;
  lr.set_outcome("fused");
  const v1::ListJobsResponse listed = s.listJobs(lr);
  ASSERT_EQ(listed.jobs_size(), 2);
  EXPECT_EQ(listed.jobs(0).id(), ids[2]);  // newest first
  EXPECT_EQ(listed.jobs(1).id(), ids[0]);
  v1::QueryResultsRequest q;
  q.set_outcome("separated");
  const v1::QueryResultsResponse rows = s.queryResults(q);
  ASSERT_EQ(rows.rows_size(), 1);
  EXPECT_EQ(rows.rows(0).job_id(), ids[1]);
  EXPECT_EQ(rows.rows(0).outcome(), "separated");
  EXPECT_EQ(s.queryResults(v1::QueryResultsRequest()).rows_size(), 4);
  q.set_outcome("merged");
  try {
    s.queryResults(q);
    ADD_FAILURE() << "unknown outcome accepted";
  } catch (const StoreError& e) {
    EXPECT_EQ(e.kind, StoreError::Kind::InvalidArgument);
    EXPECT_NE(std::string(e.what()).find("outcome: 'merged' is not one of"), std::string::npos)
        << e.what();
  }
  fs::remove_all(db.parent_path());
}

namespace {

bool mapsMention(const std::string& what) {
  std::ifstream maps("/proc/self/maps");
  for (std::string line; std::getline(maps, line);)
    if (line.find(what) != std::string::npos) return true;
  return false;
}

// Another process reading the database with Python's sqlite3 (the stock unix VFS).
activefoam::testing::Proc pythonCount(const fs::path& db) {
  return activefoam::testing::sh(
      "/usr/bin/python3 -c \"import sqlite3,sys\ntry:\n print(sqlite3.connect(sys.argv[1], "
      "timeout=0.2).execute('select count(*) from jobs').fetchone()[0])\nexcept Exception as "
      "e:\n print('error:', e)\" '" +
      db.string() + "' 2>&1");
}

}  // namespace

// SQLite kept its WAL index in a memory-mapped `-shm` file, so a storage fault
// under it (the file made immutable mid-job) was a SIGBUS that killed foamd. The index is now in
// the heap (server/heap_shm_vfs.h): no file of the database is mapped, both connections of the
// store share it, and another process cannot use the database beside it.
TEST(Store, TheWalIndexIsInTheHeapAndOtherProcessesAreKeptOut) {
  const fs::path db = tempDb();
  {
    Store s(db.string());
    const std::string id = s.submit(cellJob()).first;
    ASSERT_TRUE(s.getJob(id)) << "the reader connection sees the writer's commit";
    EXPECT_EQ(s.listJobs({}).jobs_size(), 1);
    EXPECT_FALSE(mapsMention(db.string() + "-shm")) << "the WAL index is a mapped file";
    const auto other = pythonCount(db);
    // SQLite's answer when it cannot take the index's locks: BUSY, or PROTOCOL after its
    // retries (~10 s).
    EXPECT_TRUE(other.out.find("database is locked") != std::string::npos ||
                other.out.find("locking protocol") != std::string::npos)
        << other.out;
  }
  EXPECT_EQ(pythonCount(db).out, "1\n") << "the database is whole once the store is closed";
  fs::remove_all(db.parent_path());
}

// The probe's fault itself: `chattr +i` on the -shm file mid-run killed foamd with SIGBUS at the
// next write. Then the whole database read-only: writes fail and are retried (degraded), and
// the store recovers when the storage does. Needs root and a file system with immutable files
// (ext4, xfs, btrfs, tmpfs since 6.0): SKIPPED elsewhere.
TEST(Store, AnImmutableShmFileOrReadOnlyFilesDoNotKillTheStore) {
  const fs::path db = tempDb();
  const std::string files =
      "'" + db.string() + "' '" + db.string() + "-wal' '" + db.string() + "-shm'";
  struct Unfreeze {
    std::string files;
    fs::path dir;
    ~Unfreeze() {
      (void)activefoam::testing::sh("chattr -i " + files + " 2>/dev/null");
      fs::remove_all(dir);
    }
  } unfreeze{files, db.parent_path()};
  Store s(db.string());  // closed before the directory is removed
  for (int k = 0; k < 20; ++k) s.submit(cellJob());
  ASSERT_TRUE(fs::exists(db.string() + "-shm"));
  if (activefoam::testing::sh("chattr +i '" + db.string() + "-shm' 2>&1").rc != 0)
    GTEST_SKIP() << "chattr +i is not possible here (it needs root and a file system with "
                    "immutable files)";
  (void)activefoam::testing::sh("sync");  // clean pages: the next store into a mapping faults
  for (int k = 0; k < 300; ++k) s.submit(cellJob());  // SIGBUS here before the fix
  EXPECT_EQ(s.countRows("jobs"), 320);

  ASSERT_EQ(activefoam::testing::sh("chattr +i " + files + " 2>&1").rc, 0);
  auto write = std::async(std::launch::async, [&] { return s.submit(cellJob()).first; });
  for (int i = 0; i < 300 && !s.degraded(); ++i)
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  EXPECT_TRUE(s.degraded()) << "writes to read-only files fail and are retried";
  EXPECT_EQ(s.countRows("jobs"), 320) << "reads go on";
  ASSERT_EQ(activefoam::testing::sh("chattr -i " + files + " 2>&1").rc, 0);
  ASSERT_EQ(write.wait_for(std::chrono::seconds(10)), std::future_status::ready);
  EXPECT_FALSE(write.get().empty());
  EXPECT_FALSE(s.degraded());
  EXPECT_EQ(s.countRows("jobs"), 321);
}
