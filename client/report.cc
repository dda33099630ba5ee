// `foam report` (see report.h).
#include "report.h"

#include <fcntl.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>
#include <zlib.h>

#include <atomic>
#include <charconv>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <optional>
#include <sstream>
#include <thread>

#include <nlohmann/json.hpp>

#include "activefoam/vtk.h"

extern char** environ;

namespace activefoam::client {
namespace {

namespace fs = std::filesystem;
using Clock = std::chrono::steady_clock;

std::atomic<int> g_signal{0};
void onSignal(int sig) {
  g_signal = sig;
}

std::optional<std::string> readFile(const fs::path& p) {
  std::ifstream f(p, std::ios::binary);
  if (!f) return std::nullopt;
  std::ostringstream s;
  s << f.rdbuf();
  return s.str();
}

std::vector<std::string> splitCsv(const std::string& line) {
  std::vector<std::string> out;
  std::string cell;
  std::istringstream in(line);
  while (std::getline(in, cell, ',')) out.push_back(cell);
  return out;
}

struct Folder {
  std::vector<std::string> columns;
  std::vector<std::string> rows;  // complete data lines of samples.csv
  int snapshots = 0;              // snap_NNNNNN.vtp files present, counted from 0 without gaps
};

Folder scan(const fs::path& run) {
  Folder f;
  if (const auto text = readFile(run / "samples.csv")) {
    std::size_t at = 0;
    bool header = true;
    while (at < text->size()) {
      const std::size_t nl = text->find('\n', at);
      if (nl == std::string::npos) break;  // a line being written
      std::string line = text->substr(at, nl - at);
      at = nl + 1;
      if (header) {
        f.columns = splitCsv(line);
        header = false;
      } else if (!line.empty()) {
        f.rows.push_back(std::move(line));
      }
    }
  }
  char name[32];
  for (;; ++f.snapshots) {
    std::snprintf(name, sizeof name, "snap_%06d.vtp", f.snapshots);
    std::error_code ec;
    if (!fs::exists(run / "snapshots" / name, ec)) break;
  }
  return f;
}

bool parseRow(const std::string& line, v1::Sample& s) {
  for (const std::string& cell : splitCsv(line)) {
    double v = 0;
    if (cell == "nan" || cell.empty()) {
      v = std::nan("");
    } else {
      const auto r = std::from_chars(cell.data(), cell.data() + cell.size(), v);
      if (r.ec != std::errc()) v = std::strtod(cell.c_str(), nullptr);  // inf, -inf
    }
    s.add_values(v);
  }
  if (s.values_size() == 0) return false;
  s.set_t_s(s.values(0));
  return true;
}

// The snapshot file as foamd stores snapshots: zlib-compressed SnapshotData and its info.
std::pair<v1::SnapshotInfo, std::string> loadSnapshot(const fs::path& file) {
  const auto text = readFile(file);
  if (!text) throw std::runtime_error("cannot read " + file.string());
  const VtkMesh m = readVtp(*text);
  v1::SnapshotData d;
  d.set_t_s(m.t_s);
  d.set_step(m.step);
  for (double x : m.points) d.add_x(x);
  for (const auto& t : m.tri)
    for (int v : t) d.add_tri(v);
  for (int c : m.vertex_cell) d.add_vertex_cell(c);
  for (double p : m.cell_pressure) d.add_cell_pressure(p);
  for (int l : m.cell_label) d.add_cell_label(l);
  const std::string raw = d.SerializeAsString();
  uLongf n = compressBound(raw.size());
  std::string z(n, '\0');
  if (compress2(reinterpret_cast<Bytef*>(z.data()), &n, reinterpret_cast<const Bytef*>(raw.data()),
                raw.size(), 6) != Z_OK)
    throw std::runtime_error("zlib compression failed");
  z.resize(n);
  v1::SnapshotInfo info;
  info.set_t_s(m.t_s);
  info.set_step(m.step);
  info.set_bytes(static_cast<std::int64_t>(raw.size()));
  info.set_vertices(static_cast<int>(m.points.size() / 3));
  info.set_triangles(static_cast<int>(m.tri.size()));
  return {info, z};
}

bool retryable(grpc::StatusCode c) {
  return c == grpc::StatusCode::UNAVAILABLE || c == grpc::StatusCode::DEADLINE_EXCEEDED ||
         c == grpc::StatusCode::RESOURCE_EXHAUSTED || c == grpc::StatusCode::ABORTED ||
         c == grpc::StatusCode::INTERNAL || c == grpc::StatusCode::UNKNOWN ||
         c == grpc::StatusCode::CANCELLED;
}

class Reporter {
 public:
  Reporter(v1::Foam::Stub& stub,
           const std::function<std::unique_ptr<grpc::ClientContext>()>& context,
           const ReportArgs& args)
      : stub_(stub), context_(context), args_(args), run_(args.run_dir) {}

  enum class Outcome { Ok, Stop, GaveUp, Refused };

  // Sends what the folder holds beyond what foamd holds, a batch at a time, until foamd holds
  // everything. With `finished`, then the outcome.
  Outcome sync(std::optional<int> exit_code) {
    const Folder f = scan(run_);
    for (;;) {
      v1::ReportTaskRequest req = base();
      for (const std::string& c : f.columns) req.add_columns(c);
      req.set_first_sample(held_samples_);
      std::size_t bytes = 0;
      for (std::int64_t k = held_samples_;
           k < static_cast<std::int64_t>(f.rows.size()) && bytes < (1u << 20); ++k) {
        v1::Sample s;
        if (!parseRow(f.rows[static_cast<std::size_t>(k)], s)) break;
        bytes += static_cast<std::size_t>(s.values_size()) * 8;
        *req.add_samples() = std::move(s);
      }
      req.set_first_snapshot(held_snapshots_);
      // Samples first; then snapshots one per request, alone: a snapshot can be megabytes and
      // foamd's message limit is 64 MiB with the Slurm executor.
      if (req.samples_size() == 0 && held_snapshots_ < f.snapshots) {
        char name[32];
        std::snprintf(name, sizeof name, "snap_%06d.vtp", held_snapshots_);
        auto [info, data] = loadSnapshot(run_ / "snapshots" / name);
        *req.add_snapshot_infos() = info;
        req.add_snapshots(std::move(data));
      }
      if (!f.rows.empty()) {
        v1::Sample last;
        if (parseRow(f.rows.back(), last)) {
          *req.mutable_progress() = progress(last);
          req.mutable_progress()->set_steps_rejected(rejectedSoFar(f.rows));
        }
      }
      const bool all_sent =
          held_samples_ + req.samples_size() >= static_cast<std::int64_t>(f.rows.size()) &&
          held_snapshots_ + req.snapshots_size() >= f.snapshots;
      if (all_sent && exit_code) finish(req, *exit_code);
      v1::ReportTaskResponse resp;
      const Outcome o = call(req, resp);
      if (o != Outcome::Ok) return o;
      held_samples_ = resp.samples_held();
      held_snapshots_ = resp.snapshots_held();
      if (resp.stop() && !req.finished()) return Outcome::Stop;
      if (req.finished()) return Outcome::Ok;
      const bool done = held_samples_ >= static_cast<std::int64_t>(f.rows.size()) &&
                        held_snapshots_ >= f.snapshots;
      if (done && !exit_code) return Outcome::Ok;
      // Nothing sendable now (a line that does not parse yet): the next round reads again.
      if (req.samples_size() == 0 && req.snapshots_size() == 0) return Outcome::Ok;
    }
  }

 private:
  v1::ReportTaskRequest base() const {
    v1::ReportTaskRequest r;
    r.set_job_id(args_.job_id);
    r.set_attempt(args_.attempt);
    return r;
  }

  // Sum of the samples' steps_rejected column (the seventh of every scene, run.h).
  static std::int64_t rejectedSoFar(const std::vector<std::string>& rows) {
    constexpr int kRejected = 6;
    double n = 0;
    for (const std::string& row : rows) {
      v1::Sample s;
      if (parseRow(row, s) && s.values_size() > kRejected && std::isfinite(s.values(kRejected)))
        n += s.values(kRejected);
    }
    return static_cast<std::int64_t>(n);
  }

  v1::Progress progress(const v1::Sample& last) {
    v1::Progress p;
    const double t = last.values(0);
    p.set_t_s(t);
    p.set_step(last.values_size() > 1 ? static_cast<std::int64_t>(last.values(1)) : 0);
    if (duration_s_ <= 0) {
      if (const auto spec = readFile(run_ / "spec.json")) {
        try {
          duration_s_ = nlohmann::json::parse(*spec).value("duration_s", 0.0);
        } catch (const std::exception&) {
        }
      }
    }
    const double f = duration_s_ > 0 ? std::clamp(t / duration_s_, 0.0, 1.0) : 0.0;
    p.set_fraction(f);
    const auto now = Clock::now();
    if (!pace_from_) pace_from_.emplace(now, t);
    const double wall = std::chrono::duration<double>(now - started_).count();
    p.set_wall_s(wall);
    const double done = t - pace_from_->second;
    const double pace = std::chrono::duration<double>(now - pace_from_->first).count();
    p.set_eta_s(done > 0 ? pace / done * std::max(0.0, duration_s_ - t) : -1);
    return p;
  }

  void finish(v1::ReportTaskRequest& req, int exit_code) {
    req.set_finished(true);
    req.set_exit_code(exit_code);
    if (const auto s = readFile(run_ / "summary.json")) req.set_summary_json(*s);
    if (exit_code != 0) {
      if (const auto log = readFile(run_.string() + ".log")) {
        std::string tail = log->size() > 2000 ? log->substr(log->size() - 2000) : *log;
        while (!tail.empty() && (tail.back() == '\n' || tail.back() == ' ')) tail.pop_back();
        req.set_message(tail);
      }
    }
  }

  Outcome call(const v1::ReportTaskRequest& req, v1::ReportTaskResponse& resp) {
    double backoff = 1;
    std::optional<Clock::time_point> failing_since;
    for (;;) {
      auto ctx = context_();
      const grpc::Status st = stub_.ReportTask(ctx.get(), req, &resp);
      if (st.ok()) {
        if (failing_since)
          std::cerr << "foam report: " << args_.job_id << ": foamd reachable again\n";
        return Outcome::Ok;
      }
      if (!retryable(st.error_code())) {
        std::cerr << "foam report: " << args_.job_id
                  << ": foamd refused the report: " << st.error_message() << " (" << st.error_code()
                  << ")\n";
        return st.error_code() == grpc::StatusCode::NOT_FOUND ? Outcome::Stop : Outcome::Refused;
      }
      const auto now = Clock::now();
      if (!failing_since) {
        failing_since = now;
        std::cerr << "foam report: " << args_.job_id << ": " << st.error_message()
                  << "; retrying for up to " << args_.give_up_after_s << " s\n";
      }
      if (std::chrono::duration<double>(now - *failing_since).count() > args_.give_up_after_s)
        return Outcome::GaveUp;
      std::this_thread::sleep_for(std::chrono::duration<double>(backoff));
      backoff = std::min(30.0, backoff * 2);
    }
  }

  v1::Foam::Stub& stub_;
  const std::function<std::unique_ptr<grpc::ClientContext>()>& context_;
  const ReportArgs& args_;
  fs::path run_;
  std::int64_t held_samples_ = 0;
  int held_snapshots_ = 0;
  double duration_s_ = 0;
  const Clock::time_point started_ = Clock::now();
  std::optional<std::pair<Clock::time_point, double>> pace_from_;
};

pid_t spawn(const std::vector<std::string>& command, const std::string& log) {
  posix_spawn_file_actions_t fa;
  posix_spawn_file_actions_init(&fa);
  posix_spawn_file_actions_addopen(&fa, 1, log.c_str(), O_WRONLY | O_CREAT | O_APPEND, 0644);
  posix_spawn_file_actions_adddup2(&fa, 1, 2);
  std::vector<char*> argv;
  for (const std::string& a : command) argv.push_back(const_cast<char*>(a.c_str()));
  argv.push_back(nullptr);
  pid_t pid = -1;
  const int rc = posix_spawnp(&pid, argv[0], &fa, nullptr, argv.data(), environ);
  posix_spawn_file_actions_destroy(&fa);
  if (rc != 0) {
    std::cerr << "foam report: cannot start " << command[0] << ": " << std::strerror(rc) << "\n";
    return -1;
  }
  return pid;
}

}  // namespace

int reportTask(v1::Foam::Stub& stub,
               const std::function<std::unique_ptr<grpc::ClientContext>()>& context,
               const ReportArgs& args) {
  if (args.command.empty()) {
    std::cerr << "foam report: no command to run (after --)\n";
    return 2;
  }
  struct sigaction sa {};
  sa.sa_handler = onSignal;
  sigemptyset(&sa.sa_mask);
  for (int sig : {SIGTERM, SIGINT, SIGHUP}) sigaction(sig, &sa, nullptr);

  std::error_code ec;
  fs::create_directories(fs::path(args.run_dir).parent_path(), ec);
  const pid_t child = spawn(args.command, args.run_dir + ".log");
  if (child < 0) return 127;
  Reporter reporter(stub, context, args);
  int forwarded = 0;
  std::optional<Clock::time_point> signalled_at;
  std::optional<int> exit_code;
  auto stopChild = [&](int sig) {
    kill(child, sig);
    forwarded = sig;
  };
  for (;;) {
    int status = 0;
    const pid_t r = waitpid(child, &status, WNOHANG);
    if (r == child) exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
    // Slurm signals every process of the task, foam-run too; foam-run treats a second signal as
    // "leave now, without the checkpoint". So forward only when foam-run has not stopped on its
    // own within a few seconds (the signal was ours alone, e.g. run by hand).
    if (!exit_code && g_signal && forwarded != g_signal) {
      if (!signalled_at) signalled_at = Clock::now();
      if (std::chrono::duration<double>(Clock::now() - *signalled_at).count() > 5)
        stopChild(g_signal);
    }
    Reporter::Outcome o = Reporter::Outcome::Ok;
    try {
      o = reporter.sync(exit_code);
    } catch (const std::exception& e) {
      std::cerr << "foam report: " << args.job_id << ": " << e.what() << "\n";
      o = exit_code ? Reporter::Outcome::Refused : Reporter::Outcome::Ok;  // retried next round
    }
    if (o == Reporter::Outcome::Stop || o == Reporter::Outcome::Refused ||
        o == Reporter::Outcome::GaveUp) {
      if (!exit_code) {
        // foamd no longer wants this run (cancelled, re-assigned) or cannot take it: stop
        // foam-run, which checkpoints on SIGTERM.
        if (o == Reporter::Outcome::Stop)
          std::cerr << "foam report: " << args.job_id << ": foamd says stop\n";
        stopChild(SIGTERM);
        waitpid(child, &status, 0);
      }
      if (o == Reporter::Outcome::Stop) return 143;
      if (o == Reporter::Outcome::GaveUp) {
        // For foamd, when it is back: the run is fine (finished or checkpointed), only its
        // report is missing; it re-queues the job instead of failing it.
        std::ofstream(args.run_dir + ".gave-up")
            << "foamd unreachable for " << args.give_up_after_s << " s\n";
        return 75;
      }
      return 1;
    }
    if (exit_code) return *exit_code;
    std::this_thread::sleep_for(std::chrono::duration<double>(args.every_s));
  }
}

}  // namespace activefoam::client
