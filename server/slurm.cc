// The Slurm executor (see slurm.h).
#include "slurm.h"

#include <fcntl.h>
#include <poll.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <optional>
#include <sstream>

#include <spdlog/spdlog.h>
#include <nlohmann/json.hpp>

#include "activefoam/run.h"
#include "activefoam/run_output.h"

extern char** environ;

namespace activefoam::server {
namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

namespace {

struct ProcResult {
  int rc = -1;  // exit status; -1 could not start or timed out
  std::string out, err;
};

// Runs argv (PATH lookup) and collects stdout and stderr. posix_spawn, not fork: foamd is
// multithreaded (gRPC), and between fork and exec only async-signal-safe calls are allowed.
ProcResult runProcess(const std::vector<std::string>& argv, double timeout_s = 60) {
  ProcResult r;
  int out_pipe[2], err_pipe[2];
  if (pipe2(out_pipe, O_CLOEXEC) != 0) return r;
  if (pipe2(err_pipe, O_CLOEXEC) != 0) {
    close(out_pipe[0]);
    close(out_pipe[1]);
    return r;
  }
  posix_spawn_file_actions_t fa;
  posix_spawn_file_actions_init(&fa);
  posix_spawn_file_actions_adddup2(&fa, out_pipe[1], 1);
  posix_spawn_file_actions_adddup2(&fa, err_pipe[1], 2);
  posix_spawn_file_actions_addopen(&fa, 0, "/dev/null", O_RDONLY, 0);
  // foamd blocks its stop signals in every thread (main waits for them) and ignores SIGPIPE and
  // SIGXFSZ (server/main.cc): not its children, which get the defaults.
  posix_spawnattr_t attr;
  posix_spawnattr_init(&attr);
  sigset_t none;
  sigemptyset(&none);
  posix_spawnattr_setsigmask(&attr, &none);
  sigset_t defaults;
  sigemptyset(&defaults);
  sigaddset(&defaults, SIGPIPE);
  sigaddset(&defaults, SIGXFSZ);
  posix_spawnattr_setsigdefault(&attr, &defaults);
  posix_spawnattr_setflags(&attr, POSIX_SPAWN_SETSIGMASK | POSIX_SPAWN_SETSIGDEF);
  std::vector<char*> args;
  for (const std::string& a : argv) args.push_back(const_cast<char*>(a.c_str()));
  args.push_back(nullptr);
  pid_t pid = -1;
  const int rc = posix_spawnp(&pid, args[0], &fa, &attr, args.data(), environ);
  posix_spawn_file_actions_destroy(&fa);
  posix_spawnattr_destroy(&attr);
  close(out_pipe[1]);
  close(err_pipe[1]);
  if (rc != 0) {
    r.err = argv[0] + ": " + std::strerror(rc);
    close(out_pipe[0]);
    close(err_pipe[0]);
    return r;
  }
  const auto deadline = Clock::now() + std::chrono::duration<double>(timeout_s);
  pollfd fds[2] = {{out_pipe[0], POLLIN, 0}, {err_pipe[0], POLLIN, 0}};
  int open_fds = 2;
  char buf[4096];
  bool timed_out = false;
  while (open_fds > 0) {
    const auto left =
        std::chrono::duration_cast<std::chrono::milliseconds>(deadline - Clock::now()).count();
    if (left <= 0) {
      timed_out = true;
      break;
    }
    if (poll(fds, 2, static_cast<int>(left)) < 0 && errno != EINTR) break;
    for (int k = 0; k < 2; ++k) {
      if (fds[k].fd < 0 || !(fds[k].revents & (POLLIN | POLLHUP | POLLERR))) continue;
      const ssize_t n = read(fds[k].fd, buf, sizeof buf);
      if (n > 0) {
        (k == 0 ? r.out : r.err).append(buf, static_cast<std::size_t>(n));
      } else if (n == 0 || errno != EINTR) {
        close(fds[k].fd);
        fds[k].fd = -1;
        --open_fds;
      }
    }
  }
  for (auto& f : fds)
    if (f.fd >= 0) close(f.fd);
  if (timed_out) kill(pid, SIGKILL);
  int status = 0;
  while (waitpid(pid, &status, 0) < 0 && errno == EINTR) {
  }
  if (timed_out) {
    r.err += argv[0] + ": timed out after " + std::to_string(timeout_s) + " s";
    return r;
  }
  r.rc = WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
  return r;
}

std::string trimmed(std::string s) {
  while (!s.empty() && std::isspace(static_cast<unsigned char>(s.back()))) s.pop_back();
  std::size_t b = 0;
  while (b < s.size() && std::isspace(static_cast<unsigned char>(s[b]))) ++b;
  return s.substr(b);
}

// 'it''s' → shell-safe single-quoted word.
std::string quoted(const std::string& s) {
  std::string q = "'";
  for (char c : s) q += c == '\'' ? std::string("'\\''") : std::string(1, c);
  return q + "'";
}

void writeFileAtomically(const fs::path& path, const std::string& text) {
  const fs::path tmp = path.string() + ".tmp";
  {
    std::ofstream f(tmp, std::ios::binary | std::ios::trunc);
    f << text;
    f.flush();
    if (!f) throw std::runtime_error("cannot write " + tmp.string());
  }
  fs::rename(tmp, path);
}

constexpr const char* kRefPrefix = "slurm:";

// "slurm:123_4" → "123_4" (empty if not ours).
std::string slurmId(const std::string& ref) {
  return ref.rfind(kRefPrefix, 0) == 0 ? ref.substr(std::strlen(kRefPrefix)) : std::string();
}

// Job states of task ids ("123_4") from `squeue`, then `sacct` for those squeue no longer lists
// (finished longer ago than MinJobAge). Missing ids are unknown to both. nullopt when squeue
// itself failed (slurmctld restarting, unreachable): nothing can be judged this round.
std::optional<std::map<std::string, SlurmState>> queryStates(
    const SlurmOptions& o, const std::set<std::string>& task_ids) {
  std::map<std::string, SlurmState> out;
  if (task_ids.empty()) return out;
  std::set<std::string> arrays;
  for (const std::string& t : task_ids) arrays.insert(t.substr(0, t.find('_')));
  std::string list;
  for (const std::string& a : arrays) list += (list.empty() ? "" : ",") + a;
  const ProcResult q = runProcess(
      {o.squeue, "--noheader", "--array", "--states=all", "--format=%i|%T", "--jobs=" + list});
  if (q.rc != 0) {
    spdlog::warn("slurm: squeue failed (exit {}): {}", q.rc, trimmed(q.err));
    return std::nullopt;
  }
  {
    std::istringstream in(q.out);
    for (std::string line; std::getline(in, line);) {
      const auto bar = line.find('|');
      if (bar == std::string::npos) continue;
      const std::string id = trimmed(line.substr(0, bar));
      if (task_ids.count(id)) out[id] = classifySlurmState(trimmed(line.substr(bar + 1)));
    }
  }
  if (out.size() < task_ids.size()) {
    const ProcResult a = runProcess({o.sacct, "--noheader", "--parsable2", "--allocations",
                                     "--format=JobID,State", "--jobs=" + list});
    if (a.rc == 0) {
      std::istringstream in(a.out);
      for (std::string line; std::getline(in, line);) {
        const auto bar = line.find('|');
        if (bar == std::string::npos) continue;
        const std::string id = trimmed(line.substr(0, bar));
        // "CANCELLED by 0" → CANCELLED
        std::string state = trimmed(line.substr(bar + 1));
        state = state.substr(0, state.find(' '));
        if (task_ids.count(id) && !out.count(id)) out[id] = classifySlurmState(state);
      }
    }
  }
  return out;
}

}  // namespace

SlurmState classifySlurmState(const std::string& state) {
  SlurmState s;
  s.name = state;
  static const std::set<std::string> active = {
      "PENDING",      "RUNNING",     "CONFIGURING",  "COMPLETING", "REQUEUED",
      "REQUEUE_HOLD", "REQUEUE_FED", "RESIZING",     "SUSPENDED",  "STAGE_OUT",
      "SIGNALING",    "STOPPED",     "RESV_DEL_HOLD"};
  static const std::set<std::string> failed = {"FAILED",        "TIMEOUT",      "NODE_FAIL",
                                               "OUT_OF_MEMORY", "PREEMPTED",    "BOOT_FAIL",
                                               "DEADLINE",      "SPECIAL_EXIT", "REVOKED"};
  if (active.count(state))
    s.kind = SlurmState::Active;
  else if (state == "COMPLETED")
    s.kind = SlurmState::Completed;
  else if (state == "CANCELLED")
    s.kind = SlurmState::Cancelled;
  else if (failed.count(state))
    s.kind = SlurmState::Failed;
  else
    s.kind = SlurmState::Unknown;
  return s;
}

SlurmExecutor::SlurmExecutor(Store& store, SlurmOptions options)
    : store_(store), options_(std::move(options)) {
  if (options_.work_dir.empty())
    throw std::invalid_argument("the slurm executor needs --slurm-dir (a shared directory)");
  if (options_.report_to.empty())
    throw std::invalid_argument("the slurm executor needs the address tasks report to");
  fs::create_directories(fs::path(options_.work_dir) / "jobs");
  fs::create_directories(fs::path(options_.work_dir) / "arrays");
}

SlurmExecutor::~SlurmExecutor() {
  stop(false);
}

void SlurmExecutor::start() {
  // Reconcile: a job claimed by an earlier foamd that died before its sbatch returned has no
  // task; back to the queue. Those with tasks are judged by the first poll (Slurm's state) and
  // by their reports, which their tasks retry while foamd is away.
  int requeued = 0, kept = 0;
  for (const v1::Job& j : store_.runningJobs()) {
    if (slurmId(j.executor_ref()).empty()) {
      store_.requeue(j.id(), "foamd restarted before the job reached Slurm; re-queued");
      ++requeued;
    } else {
      ++kept;
    }
  }
  if (requeued + kept > 0)
    spdlog::info("slurm: {} running job(s) still with Slurm, {} re-queued", kept, requeued);
  stats_.running = kept;
  thread_ = std::thread([this] { loop(); });
}

void SlurmExecutor::wake() {
  std::lock_guard lock(mu_);
  ++wake_gen_;
  cv_.notify_all();
}

void SlurmExecutor::stop(bool) {
  {
    std::lock_guard lock(mu_);
    stopping_ = true;
    cv_.notify_all();
  }
  if (thread_.joinable()) thread_.join();
}

void SlurmExecutor::loop() {
  for (;;) {
    std::uint64_t gen;
    {
      std::lock_guard lock(mu_);
      if (stopping_) return;
      gen = wake_gen_;
    }
    try {
      submitQueued();
      poll();
    } catch (const std::exception& e) {
      spdlog::error("slurm: {}", e.what());
    }
    std::unique_lock lock(mu_);
    cv_.wait_for(lock, std::chrono::duration<double>(options_.poll_every_s),
                 [&] { return stopping_ || wake_gen_ != gen; });
  }
}

void SlurmExecutor::submitQueued() {
  {
    std::lock_guard lock(mu_);
    if (Clock::now() < submit_after_) return;  // after an sbatch failure
  }
  std::vector<Claimed> claimed = store_.claimQueued(1000);  // Slurm's default MaxArraySize
  if (claimed.empty()) return;
  // A sweep's jobs as one array; other jobs each as their own.
  std::map<std::string, std::vector<v1::Job>> groups;
  for (Claimed& c : claimed) {
    const std::string key = c.job.sweep_id().empty() ? c.job.id() : c.job.sweep_id();
    groups[key].push_back(std::move(c.job));
  }
  for (const auto& [name, jobs] : groups) {
    try {
      submitGroup(name, jobs);
    } catch (const std::exception& e) {  // the store: leave none of them running without a task
      spdlog::error("slurm: {}: {}", name, e.what());
      for (const v1::Job& j : jobs)
        if (auto now = store_.getJob(j.id()); now && now->executor_ref().empty())
          store_.requeue(j.id(), std::string("submission failed: ") + e.what());
    }
  }
}

std::string SlurmExecutor::writeTaskScript(const std::string& array_dir) const {
  std::ostringstream s;
  s << "#!/bin/bash\n"
       "# Written by foamd's Slurm executor (template: deploy/slurm/foam-task.sh). One array\n"
       "# task runs one job: foam-run computes and checkpoints into the shared work directory,\n"
       "# foam report sends its outputs to foamd and exits with foam-run's exit status.\n"
       "set -u\n"
       "# The engine's OpenMP threads: the CPUs Slurm gave the task, not the node's.\n"
       "export OMP_NUM_THREADS=${SLURM_CPUS_PER_TASK:-1}\n"
    << "ARRAY_DIR=" << quoted(array_dir) << "\n"
    << "WORK_DIR=" << quoted(options_.work_dir) << "\n"
    << "JOB=$(sed -n \"$((SLURM_ARRAY_TASK_ID + 1))p\" \"$ARRAY_DIR/jobs\")\n"
    << "[ -n \"$JOB\" ] || { echo \"no job for task $SLURM_ARRAY_TASK_ID in $ARRAY_DIR/jobs\" >&2; "
       "exit 2; }\n"
    << "RUN=\"$WORK_DIR/jobs/$JOB\"\n"
    << "exec " << quoted(options_.foam) << " --server " << quoted(options_.report_to);
  if (!options_.token_file.empty()) s << " --token-file " << quoted(options_.token_file);
  if (!options_.tls_ca.empty()) s << " --tls-ca " << quoted(options_.tls_ca);
  s << " report \"$JOB\" \"$RUN/run\" --attempt "
       "\"slurm:${SLURM_ARRAY_JOB_ID}_${SLURM_ARRAY_TASK_ID}\" -- "
    << quoted(options_.foam_run) << " \"$RUN/spec.json\" --out \"$RUN/run\" --resume"
    << " --checkpoint-every " << options_.checkpoint_every_s << " --quiet\n";
  return s.str();
}

void SlurmExecutor::submitGroup(const std::string& name, const std::vector<v1::Job>& jobs) {
  const fs::path work(options_.work_dir);
  // Unique per submission: a sweep of more than 1000 jobs goes out in several arrays.
  const fs::path array_dir =
      work / "arrays" /
      (name + "-" + jobs.front().id() + "-" + std::to_string(jobs.front().attempts()));
  std::string failure;
  try {
    fs::create_directories(array_dir.parent_path());
    if (!fs::create_directory(array_dir))
      throw std::runtime_error(array_dir.string() + " exists already");
    std::string list;
    for (const v1::Job& j : jobs) {
      const fs::path dir = work / "jobs" / j.id();
      fs::create_directories(dir);
      // The resolved spec as stored: foam-run runs exactly what the store says.
      writeFileAtomically(dir / "spec.json", j.spec_json());
      list += j.id() + "\n";
    }
    writeFileAtomically(array_dir / "jobs", list);
    writeFileAtomically(array_dir / "task.sh", writeTaskScript(array_dir.string()));
    fs::permissions(array_dir / "task.sh", fs::perms::owner_all | fs::perms::group_read |
                                               fs::perms::group_exec | fs::perms::others_read |
                                               fs::perms::others_exec);
  } catch (const std::exception& e) {
    failure = std::string("cannot prepare the task files in ") + work.string() + ": " + e.what();
  }
  std::string array_id;
  if (failure.empty()) {
    std::vector<std::string> argv = {options_.sbatch,
                                     "--parsable",
                                     "--array=0-" + std::to_string(jobs.size() - 1),
                                     "--job-name=foam-" + name,
                                     "--requeue",
                                     "--output=" + (array_dir / "task-%a.out").string()};
    if (!options_.partition.empty()) argv.push_back("--partition=" + options_.partition);
    for (const std::string& a : options_.sbatch_args) argv.push_back(a);
    argv.push_back((array_dir / "task.sh").string());
    const ProcResult r = runProcess(argv);
    array_id = trimmed(r.out.substr(0, r.out.find(';')));
    if (r.rc != 0 || array_id.empty())
      failure = "sbatch failed (exit " + std::to_string(r.rc) + "): " + trimmed(r.err);
  }
  if (!failure.empty()) {
    // Slurm unreachable, a submit limit, a bad partition: back to the queue with the reason
    // (`foam show` says it), tried again after a pause; `foam cancel` ends them.
    spdlog::error("slurm: {}: {}; jobs re-queued, next try in 60 s", name, failure);
    for (const v1::Job& j : jobs) store_.requeue(j.id(), failure + "; re-queued, retrying");
    std::lock_guard lock(mu_);
    submit_after_ = Clock::now() + std::chrono::seconds(60);
    return;
  }
  spdlog::info("slurm: submitted {} job(s) as array {} ({})", jobs.size(), array_id, name);
  std::vector<std::string> late_cancels;
  {
    std::lock_guard lock(mu_);  // see cancel()
    for (std::size_t k = 0; k < jobs.size(); ++k) {
      const std::string task = array_id + "_" + std::to_string(k);
      store_.setExecutorRef(jobs[k].id(), kRefPrefix + task);
      if (cancelled_unplaced_.erase(jobs[k].id())) late_cancels.push_back(task);
    }
  }
  stats_.running += static_cast<int>(jobs.size() - late_cancels.size());
  for (const std::string& task : late_cancels) runProcess({options_.scancel, task});
}

bool SlurmExecutor::cancel(const std::string& id, const std::string& reason) {
  std::optional<v1::Job> j;
  std::string task;
  {
    // Under the lock submitGroup records refs with: either the ref is read here, or the id is
    // in cancelled_unplaced_ before submitGroup looks.
    std::lock_guard lock(mu_);
    j = store_.getJob(id);
    if (!j || j->state() != v1::JOB_STATE_RUNNING) return false;
    task = slurmId(j->executor_ref());
    if (task.empty()) cancelled_unplaced_.insert(id);  // scancelled once sbatch has answered
  }
  if (!task.empty()) {
    const ProcResult r = runProcess({options_.scancel, task});
    if (r.rc != 0) spdlog::warn("slurm: scancel {}: {}", task, trimmed(r.err));
  }
  // Recorded now: the task's reporter is told to stop at its next report, and Slurm says
  // CANCELLED for it from here on. A final report that came first wins (finish is once).
  if (store_.finish(id, v1::JOB_STATE_CANCELLED, "cancelled", reason, {}, j->t_s(), j->steps())) {
    ++stats_.jobs_cancelled;
    if (!task.empty()) --stats_.running;
  }
  spdlog::info("job {}: cancelled ({})", id, task.empty() ? "before reaching Slurm" : task);
  return true;
}

bool SlurmExecutor::taskFinished(const v1::Job& job, const v1::ReportTaskRequest& report) {
  const std::string& id = job.id();
  const int rc = report.exit_code();
  if (rc == 130 || rc == 143) {
    // foam-run was interrupted (scancel, preemption, time limit): Slurm's state says which.
    spdlog::info("job {}: task {} interrupted; waiting for Slurm's verdict", id, report.attempt());
    return true;
  }
  FlatResults flat;
  const auto& results = flat.values;
  nlohmann::json summary = nlohmann::json::object();  // value() needs an object
  if (!report.summary_json().empty()) {
    try {
      summary = nlohmann::json::parse(report.summary_json());
      flat = flattenSummary(summary);
    } catch (const std::exception& e) {
      spdlog::warn("job {}: unreadable summary.json from {}: {}", id, report.attempt(), e.what());
    }
  }
  const double t = summary.value("t_s", job.t_s());
  const std::int64_t steps = summary.value("steps", job.steps());
  // The summary decides when there is one (a task run again on a finished folder exits 0 for a
  // failed run too); else foam-run's exit status.
  const bool ok = summary.value("ok", false);
  const bool engine_failed = summary.contains("failure") && !ok;
  bool ended = false;
  if (rc == 0 && ok) {
    if ((ended = store_.finish(id, v1::JOB_STATE_SUCCEEDED, "", "", results, t, steps, flat.outcome,
                               flat.curves)))
      ++stats_.jobs_succeeded;
    spdlog::info("job {}: succeeded on Slurm ({})", id, report.attempt());
  } else if (engine_failed) {
    if ((ended = store_.finish(
             id, v1::JOB_STATE_FAILED, summary.value("failure", std::string("failed")),
             summary.value("reason", std::string()), results, t, steps, flat.outcome, flat.curves)))
      ++stats_.jobs_failed;
    spdlog::warn("job {}: failed on Slurm ({}): {}", id, report.attempt(),
                 summary.value("reason", std::string()));
  } else {
    const std::string kind = rc == 2 ? "invalid-spec" : "exception";
    if ((ended = store_.finish(id, v1::JOB_STATE_FAILED, kind,
                               "foam-run exited with status " + std::to_string(rc) + " on Slurm (" +
                                   report.attempt() + ")" +
                                   (report.message().empty() ? "" : ": " + report.message()),
                               results, t, steps)))
      ++stats_.jobs_failed;
    spdlog::warn("job {}: foam-run exited with {} on Slurm ({})", id, rc, report.attempt());
  }
  if (ended) --stats_.running;
  std::lock_guard lock(mu_);
  ended_since_.erase(id);
  return true;
}

void SlurmExecutor::poll() {
  const std::vector<v1::Job> running = store_.runningJobs();
  std::set<std::string> tasks;
  for (const v1::Job& j : running)
    if (std::string t = slurmId(j.executor_ref()); !t.empty()) tasks.insert(t);
  const std::optional<std::map<std::string, SlurmState>> queried = queryStates(options_, tasks);
  if (!queried) return;  // judged next round; running tasks keep reporting meanwhile
  const auto now = Clock::now();
  int active = 0;
  std::set<std::string> seen;
  for (const v1::Job& j : running) {
    const std::string task = slurmId(j.executor_ref());
    if (task.empty()) continue;
    seen.insert(j.id());
    const auto it = queried->find(task);
    const SlurmState st = it == queried->end() ? SlurmState{} : it->second;
    if (st.kind == SlurmState::Active) {
      ++active;
      std::lock_guard lock(mu_);
      ended_since_.erase(j.id());
      continue;
    }
    // Ended (or unknown to Slurm) without a final report yet: give the report time to arrive.
    {
      std::lock_guard lock(mu_);
      auto [e, fresh] = ended_since_.emplace(j.id(), now);
      if (std::chrono::duration<double>(now - e->second).count() < options_.report_grace_s) {
        ++active;
        continue;
      }
      ended_since_.erase(e);
    }
    const fs::path run = fs::path(options_.work_dir) / "jobs" / j.id() / "run";
    std::error_code ec;
    const bool has_summary = fs::exists(run / "summary.json", ec);
    // `foam report` leaves this when it gave up on an unreachable foamd (exit 75): the run
    // itself is fine, checkpointed or finished.
    const fs::path gave_up = run.string() + ".gave-up";
    const bool report_lost = fs::exists(gave_up, ec);
    const std::string what = st.kind == SlurmState::Unknown && st.name.empty()
                                 ? std::string("no longer known to Slurm")
                                 : "ended " + st.name;
    if (st.kind == SlurmState::Completed || report_lost ||
        (st.kind == SlurmState::Unknown && has_summary)) {
      // Its output folder is complete (or checkpointed) but foamd never got the final report:
      // run the task again; foam-run finishes or finds the finished run, and the reporter
      // sends the folder.
      fs::remove(gave_up, ec);
      if (store_.requeue(j.id(), "Slurm task " + task + " " + what +
                                     " without its final report; re-queued to report its outputs"))
        spdlog::info("job {}: task {} {} without a final report; re-queued", j.id(), task, what);
    } else if (st.kind == SlurmState::Cancelled) {
      if (store_.finish(j.id(), v1::JOB_STATE_CANCELLED, "cancelled",
                        "Slurm task " + task + " was cancelled outside foamd", {}, j.t_s(),
                        j.steps()))
        ++stats_.jobs_cancelled;
    } else {
      std::string kind = st.name.empty() ? "lost" : st.name;
      std::transform(kind.begin(), kind.end(), kind.begin(),
                     [](unsigned char c) { return c == '_' ? '-' : std::tolower(c); });
      if (store_.finish(j.id(), v1::JOB_STATE_FAILED, "slurm-" + kind,
                        "Slurm task " + task + " " + what + " (its log: " + options_.work_dir +
                            "/arrays/*/task-" + task.substr(task.find('_') + 1) + ".out)",
                        {}, j.t_s(), j.steps()))
        ++stats_.jobs_failed;
      spdlog::warn("job {}: Slurm task {} {}", j.id(), task, what);
    }
  }
  stats_.running = active;
  std::lock_guard lock(mu_);
  for (auto it = ended_since_.begin(); it != ended_since_.end();)  // jobs that ended meanwhile
    it = seen.count(it->first) ? std::next(it) : ended_since_.erase(it);
}

}  // namespace activefoam::server
