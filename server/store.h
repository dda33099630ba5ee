// The job store: one SQLite file (WAL, busy timeout), schema versioned with migrations
// (PRAGMA user_version). Every write goes through one writer thread, which groups queued writes
// into one IMMEDIATE transaction (one SAVEPOINT each, so one failing write does not undo the
// others) and returns only after COMMIT: what a write call returns is on disk. Reads use their
// own connection and see committed data only.
//
// Its parts: sqlite.h (the SQLite C API wrapped), store_sql.h (schema and migrations, rows to
// messages, filter clauses), job_states.h (the one table of allowed state changes), db_lock.cc
// (one server per database), store.cc (the writer thread and the writes), store_reads.cc.
#pragma once

#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <functional>
#include <future>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include "activefoam/run_output.h"
#include "activefoam/spec.h"
#include "activefoam/v1/job.pb.h"
#include "activefoam/v1/service.pb.h"
#include "job_states.h"

struct sqlite3;

namespace activefoam::server {

inline constexpr int kSchemaVersion = 5;

// A request that cannot be served as asked (bad filter, unknown id, key reuse): the service
// maps these to gRPC codes.
// A client-supplied value inside an error message: quoted, at most `max` bytes of it (a 64 KB
// job id echoed back would exceed gRPC's metadata limit).
std::string cappedQuote(const std::string& value, std::size_t max = 200);

struct StoreError : std::runtime_error {
  enum class Kind { InvalidArgument, NotFound, FailedPrecondition };
  Kind kind;
  StoreError(Kind k, const std::string& what) : std::runtime_error(what), kind(k) {}
};

// One server per database: exclusive flock(2)s on the database file itself (its identity: any
// alias — symlink, hard link, relative path — meets it) and on "<resolved db>.lock", held for
// the Store's life and released by the kernel when the process ends (a crash leaves no stale
// lock). The .lock file names the holder (pid, host, start time) for the error a second server
// gets; through a hard link the holder's pid comes from /proc/locks. Two foamd on one database
// would each re-queue and run the other's jobs.
class DbLock {
 public:
  // Throws StoreError(FailedPrecondition) naming the holder when another process holds it.
  explicit DbLock(const std::string& db_path);
  ~DbLock();
  DbLock(const DbLock&) = delete;
  DbLock& operator=(const DbLock&) = delete;

 private:
  int fd_ = -1;     // <resolved db>.lock
  int db_fd_ = -1;  // the database file
};

// SQLite's full integrity_check of the database at `path` (foamd --check-db), which foamd's
// start (quick_check) leaves out: it also compares every index with its table, so a row whose
// indexed value was altered on disk is found. Content SQLite keeps no index of (a zeroed overflow
// page of a spec) stays unseen by both. Held under DbLock: refused (std::runtime_error, naming
// the holder) while a foamd serves the database, and refused when no database is there.
struct DbCheck {
  bool ok = false;
  std::string problems;    // the first problems SQLite reports, one line ("ok" when none)
  std::int64_t bytes = 0;  // of the database file (its WAL, if any, is checkpointed first)
  double seconds = 0;      // of the check
};
DbCheck checkDatabase(const std::string& path);

struct NewJob {
  SceneSpec spec;         // resolved
  std::string spec_json;  // specToJson(spec), what the worker runs
  int priority = 0;
  std::string tag;
  std::string sweep_id;
  std::string idempotency_key;
};

struct Claimed {
  v1::Job job;
  std::optional<std::string> checkpoint;  // last checkpoint, if any
  double checkpoint_t_s = 0;
};

struct StoreOptions {
  int keep_snapshots = 0;  // per job, newest kept; 0 = all
  int busy_timeout_ms = 5000;
};

class Store {
 public:
  explicit Store(const std::string& path, StoreOptions options = {});
  ~Store();
  Store(const Store&) = delete;
  Store& operator=(const Store&) = delete;

  int schemaVersion();
  const std::string& path() const { return path_; }

  // Called (on the writer thread, after COMMIT) with the ids of jobs that got new events.
  void setEventListener(std::function<void(const std::string& job_id)> listener);

  // ---- writes (blocking until committed)
  // Returns (id, created). Same idempotency key again: the existing job (created = false);
  // with a different spec: StoreError FailedPrecondition.
  std::pair<std::string, bool> submit(const NewJob& job);
  // All jobs or none. Returns (sweep id, job ids, created).
  std::tuple<std::string, std::vector<std::string>, bool> submitSweep(
      const std::string& name, const std::string& idempotency_key, const std::vector<NewJob>& jobs,
      const std::vector<std::string>& keys = {});
  // The next queued job by priority then age, marked running (attempts + 1).
  std::optional<Claimed> claimNext();
  // Up to `max` queued jobs by priority then age, all marked running (an executor that submits
  // them in batches: a sweep as one Slurm array). The checkpoint's bytes only on request (a
  // Slurm task reads its own from the shared directory).
  std::vector<Claimed> claimQueued(int max, bool with_checkpoint = false);
  // Where a running job runs outside the pool ("slurm:123_4"); "" when not (yet) placed.
  void setExecutorRef(const std::string& id, const std::string& ref);
  // A task's report (ReportTask): samples from index first_sample and snapshots (zlib
  // SnapshotData with their infos) from first_snapshot, of which those the store lacks are
  // added, with their events, in one transaction; then the progress. Returns the counts held.
  struct Held {
    std::int64_t samples = 0;
    int snapshots = 0;
  };
  Held ingestReport(const std::string& id, const std::vector<std::string>& columns,
                    std::int64_t first_sample, const std::vector<std::vector<double>>& samples,
                    int first_snapshot,
                    const std::vector<std::pair<v1::SnapshotInfo, std::string>>& snapshots,
                    const std::optional<v1::Progress>& progress);
  // Queued → cancelled at once; running: returns the job unchanged (the pool stops it).
  v1::Job cancel(const std::string& id, const std::string& reason);
  // Final state of a running job, with its results (name, value) and curves (fusion: MSRD).
  // False (nothing written) when the job is not running any more: it ended already.
  bool finish(const std::string& id, v1::JobState state, const std::string& failure_kind,
              const std::string& reason, const std::vector<std::pair<std::string, double>>& results,
              double t_s, std::int64_t steps, const std::string& outcome = {},
              const std::vector<FlatCurve>& curves = {});
  // Running → queued (shutdown or restart), with the reason; false when it was not running.
  bool requeue(const std::string& id, const std::string& reason);
  // At startup: every job left running by a previous process → queued. Returns how many.
  int requeueRunning(const std::string& reason);
  // The same without waiting for the write (foamd's start): queued ahead of any later write, so
  // no job is claimed before it, and retried like every write while the storage fails — a
  // server restarted on a full disk listens at once, degraded, instead of blocking here.
  // Returns how many jobs it will re-queue (a read).
  int requeueRunningInBackground(const std::string& reason);
  // Before a (re)start: drops outputs after the checkpoint time (all of them without one).
  void resetOutputs(const std::string& id, std::optional<double> keep_until_t_s);
  void dropCheckpoint(const std::string& id);

  // ---- writes from a running job (queued; ordered; not waited for)
  void addSample(const std::string& id, const std::vector<std::string>& columns,
                 const std::vector<double>& values);
  void addProgress(const std::string& id, const v1::Progress& p);
  void addSnapshot(const std::string& id, const v1::SnapshotInfo& info,
                   const std::string& compression, std::string data);
  void saveCheckpoint(const std::string& id, double t_s, std::string data);
  // Waits until every queued write is committed.
  void flush();

  // ---- the storage's health: true while writes fail (disk full, I/O error). Failed writes are
  // kept and retried with backoff until they commit; `storeErrors` counts failed tries.
  bool degraded() const { return degraded_.load(); }
  std::int64_t storeErrors() const { return store_errors_.load(); }
  std::string lastError() const;
  // Called from the writer thread when writes start failing (false) and succeed again (true).
  void setHealthListener(std::function<void(bool writable)> listener);

  // ---- reads
  std::optional<v1::Job> getJob(const std::string& id);
  std::vector<v1::Job> runningJobs();
  v1::ListJobsResponse listJobs(const v1::ListJobsRequest& request);
  std::vector<v1::JobEvent> events(const std::string& id, std::int64_t after_seq, int limit);
  v1::JobResults results(const std::string& id, bool with_samples);
  v1::QueryResultsResponse queryResults(const v1::QueryResultsRequest& request);
  // (info, compression, data) of snapshot `index` (-1 = latest).
  std::optional<std::tuple<v1::SnapshotInfo, std::string, std::string>> snapshot(
      const std::string& id, int index);
  std::optional<std::pair<double, std::string>> checkpoint(const std::string& id);
  std::map<v1::JobState, std::int64_t> countByState();
  std::int64_t countRows(const std::string& table);  // tests: "store unchanged"

  // Normalised parameter columns (filter keys of ListJobs/QueryResults).
  static const std::vector<std::string>& paramKeys();

 private:
  struct Tx;
  struct Task {
    std::function<void(Tx&)> fn;
    std::promise<void> done;
  };
  template <class F>
  auto write(F f) -> decltype(f(std::declval<Tx&>()));
  void post(std::function<void(Tx&)> fn);  // fire and forget (errors logged)
  void writerLoop();
  void notifyHealth(bool writable);
  static int requeueAll(Tx& tx, const std::string& reason);

  std::string path_;
  StoreOptions options_;
  DbLock lock_;             // before the connections: taken first, released last
  sqlite3* wdb_ = nullptr;  // writer thread only
  sqlite3* rdb_ = nullptr;  // under rmu_
  std::mutex rmu_;
  std::mutex qmu_;
  std::condition_variable qcv_;
  std::condition_variable idle_cv_;
  std::deque<std::unique_ptr<Task>> queue_;
  bool busy_ = false;
  bool stop_ = false;
  std::function<void(const std::string&)> listener_;
  std::atomic<bool> degraded_{false};
  std::atomic<std::int64_t> store_errors_{0};
  // Held while the writer runs a listener and while one is replaced: a listener that is
  // replaced (or cleared by its owner's destructor) is never called afterwards. Listeners must
  // not call setEventListener / setHealthListener.
  std::mutex lmu_;          // listener_, health_listener_
  mutable std::mutex emu_;  // last_error_
  std::string last_error_;
  std::function<void(bool)> health_listener_;
  std::thread writer_;
};

std::string newId(const std::string& prefix);
std::string utcNowText();

}  // namespace activefoam::server
