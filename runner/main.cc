// foam-run: runs one scene spec to an output folder (docs/usage.md).
//
//   foam-run SPEC --out DIR [--set KEY=VALUE]... [--force | --resume] [--quiet] [--threads N]
//
// Exit codes: 0 the run reached duration_s; 2 invalid spec or usage (nothing is written);
// 3 the run failed (reason on stderr and in summary.json); 130 interrupted (SIGINT/SIGTERM).
#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <optional>
#include <sstream>
#include <stdexcept>
#include <string>
#include <string_view>
#include <type_traits>
#include <vector>

#include <unistd.h>

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include "activefoam/run.h"
#include "activefoam/run_output.h"
#include "activefoam/spec.h"
#include "activefoam/spec_io.h"
#include "activefoam/threads.h"

namespace {

namespace fs = std::filesystem;
using namespace activefoam;

constexpr int kExitOk = 0;
constexpr int kExitUsage = 2;
constexpr int kExitRunFailed = 3;
constexpr int kExitInterrupted = 130;

// The engine polls g_cancel every step. Set by SIGINT/SIGTERM, and by an output error.
std::atomic<bool> g_cancel{false};
std::atomic<int> g_signals{0};
static_assert(std::atomic<bool>::is_always_lock_free && std::atomic<int>::is_always_lock_free,
              "used from a signal handler");

extern "C" void onSignal(int) {
  // First signal: ask the engine to stop at the next step and write a summary. Second: leave now.
  if (g_signals.fetch_add(1) > 0) _exit(kExitInterrupted);
  g_cancel.store(true);
}

void installSignalHandlers() {
  struct sigaction sa {};
  sa.sa_handler = onSignal;
  sigemptyset(&sa.sa_mask);
  sigaction(SIGINT, &sa, nullptr);
  sigaction(SIGTERM, &sa, nullptr);
}

constexpr const char* kUsage =
    "usage: foam-run SPEC --out DIR [--set KEY=VALUE]... [--force | --resume] [--quiet]\n"
    "                [--checkpoint-every SECONDS] [--spheroid-cache DIR | --no-cache]\n"
    "                [--threads N]\n"
    "       foam-run --keys | --help | --version\n";

void printHelp() {
  std::cout
      << kUsage
      << "\n"
         "Runs one scene spec (TOML or JSON; '-' reads standard input) to DIR:\n"
         "  spec.json     the resolved spec (every default filled in)\n"
         "  samples.csv   one row per sample (sample_every_s)\n"
         "  snapshots/    snap_NNNNNN.vtp and series.pvd (snapshot_every_s > 0)\n"
         "  summary.json  outcome, failure reason, cost, final values\n"
         "  checkpoint.bin  the state to continue from (until the run has finished)\n"
         "\n"
         "options:\n"
         "  --out DIR        output folder; created; must be empty unless --force\n"
         "  --set KEY=VALUE  override a spec key, e.g. --set numerics.dt_s=0.05 (repeatable)\n"
         "  --force          write into a non-empty DIR (replaces earlier outputs)\n"
         "  --resume         continue the run in DIR from its checkpoint.bin (same SPEC and\n"
         "                   --set); without a checkpoint, start it over; a finished run is\n"
         "                   left alone (exit 0)\n"
         "  --checkpoint-every SECONDS\n"
         "                   write checkpoint.bin after a sample once this much wall-clock time\n"
         "                   has passed since the last (default 300; 0: only when interrupted)\n"
         "  --spheroid-cache DIR\n"
         "                   fusion: prepared spheroids are kept here and reused (default\n"
         "                   $ACTIVEFOAM_CACHE, $XDG_CACHE_HOME/activefoam/spheroids or\n"
         "                   ~/.cache/activefoam/spheroids)\n"
         "  --no-cache       fusion: prepare the spheroids for this run only\n"
         "  --threads N      threads of the engine's kernels (default: $SLURM_CPUS_PER_TASK if\n"
         "                   set, else 1); results are bit-identical for any N\n"
         "  --quiet, -q      no progress lines on stderr\n"
         "  --keys           list every spec key with its range, unit and default\n"
         "  --help, -h       this text\n"
         "  --version        engine version\n"
         "\n"
         "exit status: 0 done, 2 invalid spec or usage (nothing written), 3 run failed,\n"
         "130 interrupted (SIGINT/SIGTERM; summary.json says cancelled; checkpoint.bin\n"
         "written: continue with --resume)\n";
}

// A value as a spec file writes it: 0.1, 3, "ros2", true.
std::string specText(const SpecValue& v) {
  return std::visit(
      [](const auto& x) -> std::string {
        using T = std::decay_t<decltype(x)>;
        if constexpr (std::is_same_v<T, double>)
          return formatNumber(x);
        else if constexpr (std::is_same_v<T, std::int64_t>)
          return std::to_string(x);
        else if constexpr (std::is_same_v<T, std::string>)
          return "\"" + x + "\"";
        else
          return x ? "true" : "false";
      },
      v);
}

// Every key with its default, range and meaning, and what the key table knows of its history:
// the value that reproduces runs made before it existed, what the spheroids' preparation runs
// it at, and the scenes that read it.
void printKeys() {
  const SceneSpec defaults;
  for (const SpecField& f : specFields()) {
    const auto v = getField(defaults, f.key);
    std::cout << f.key << " = " << (v ? specText(*v) : "(derived)") << "  " << f.range()
              << (f.unit.empty() ? "" : " ") << f.unit << "\n    " << f.help << "\n";
    std::string notes;
    if (f.label) notes += "names other keys' values; ";
    if (f.before) notes += "before it existed: " + specText(*f.before) + "; ";
    if (f.since_unset) notes += "before it existed: unset; ";
    if (f.prep == SpecField::Prep::Fixed)
      notes += "spheroid preparation: " + (f.prep_value ? specText(*f.prep_value) : "unset") + "; ";
    if (f.prep == SpecField::Prep::Kept) notes += "[prepare] may give the preparation its own; ";
    if (f.scenes != 0xF) {
      std::string list;
      for (SceneKind k :
           {SceneKind::Cell, SceneKind::Doublet, SceneKind::Spheroid, SceneKind::Fusion})
        if (f.readBy(k)) list += (list.empty() ? "" : ", ") + std::string(toString(k));
      notes += "read by: " + list + "; ";
    }
    if (!notes.empty()) std::cout << "    (" << notes.substr(0, notes.size() - 2) << ")\n";
  }
  std::cout << "\n[prepare] (fusion): values the spheroids' preparation runs with instead of the "
               "run's,\n    e.g. [prepare.cells] l_eta_reduced = 0.5 (docs/scenes.md)\n";
}

std::string formatDuration(double s) {
  char buf[64];
  if (s < 10)
    std::snprintf(buf, sizeof buf, "%.1f s", s);
  else if (s < 120)
    std::snprintf(buf, sizeof buf, "%.0f s", s);
  else if (s < 7200)
    std::snprintf(buf, sizeof buf, "%.0f min", s / 60);
  else
    std::snprintf(buf, sizeof buf, "%.0f h %02.0f min", std::floor(s / 3600),
                  std::floor(std::fmod(s, 3600) / 60));
  return buf;
}

// A time for people: 6 significant digits ("2.4", not "2.4000000000000004").
std::string human(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.6g", v);
  return buf;
}

struct Args {
  std::string spec;
  std::string out;
  std::vector<std::string> settings;
  bool force = false;
  bool resume = false;
  double checkpoint_every_s = 300;
  bool quiet = false;
  std::optional<std::string> cache;  // --spheroid-cache; "" disables
  int threads = 0;                   // --threads; 0: the default below
};

// One thread unless told otherwise: the studies and users run many foam-run side by side (one
// per core), where OpenMP's default of every core per process would
// oversubscribe the machine, and its spinning barriers then slow every run down many times
// (measured: 25 s instead of 1 s for two 3-thread tests on 2 cores). A Slurm task owns exactly
// its --cpus-per-task, so there the allocation is the right default.
int defaultThreads() {
  if (const char* s = std::getenv("SLURM_CPUS_PER_TASK")) {
    char* end = nullptr;
    const long n = std::strtol(s, &end, 10);
    if (end != s && *end == '\0' && n >= 1 && n <= 1024) return static_cast<int>(n);
  }
  return 1;
}

// Prepared spheroids are shared by every run of a user: $ACTIVEFOAM_CACHE, else
// $XDG_CACHE_HOME/activefoam/spheroids, else ~/.cache/activefoam/spheroids.
std::string defaultCacheDir() {
  if (const char* d = std::getenv("ACTIVEFOAM_CACHE"); d && *d) return d;
  if (const char* d = std::getenv("XDG_CACHE_HOME"); d && *d)
    return (fs::path(d) / "activefoam" / "spheroids").string();
  if (const char* d = std::getenv("HOME"); d && *d)
    return (fs::path(d) / ".cache" / "activefoam" / "spheroids").string();
  return "";
}

std::string readWholeFile(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  if (!in) throw std::runtime_error("cannot read " + p.string());
  std::ostringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

bool finishedRun(const fs::path& summary) {
  try {
    const auto j = nlohmann::json::parse(readWholeFile(summary));
    return j.value("ok", false);
  } catch (const std::exception&) {
    return false;
  }
}

// Empty when `path` (a run's spec.json) holds `spec`; else the first keys that differ.
std::string specDifference(const fs::path& path, const SceneSpec& spec) {
  nlohmann::json was;
  try {
    was = nlohmann::json::parse(readWholeFile(path));
  } catch (const std::exception& e) {
    return path.string() + " is missing or damaged (" + e.what() + ")";
  }
  const nlohmann::json now = specToJson(spec);
  const nlohmann::json patch = nlohmann::json::diff(was, now);
  if (patch.empty()) return {};
  std::string keys;
  for (std::size_t k = 0; k < patch.size() && k < 5; ++k) {
    std::string key = patch[k].value("path", "");
    std::replace(key.begin(), key.end(), '/', '.');
    if (!key.empty() && key[0] == '.') key.erase(0, 1);
    keys += (k ? ", " : "") + key;
  }
  return "the spec differs from the run's " + path.string() + " (" + keys +
         "); give the same SPEC and --set as the interrupted run";
}

int usageError(const std::string& msg) {
  std::cerr << "foam-run: " << msg << " (see foam-run --help)\n";
  return kExitUsage;
}

}  // namespace

int main(int argc, char** argv) {
  installSignalHandlers();

  Args args;
  // CLI11 as in foam and foamd; the help text is ours (printHelp), and every usage error is one
  // line naming the option, exit 2.
  CLI::App app{"foam-run"};
  app.set_help_flag();
  bool help = false, version = false, keys = false, no_cache = false;
  std::vector<std::string> specs;
  std::string checkpoint_every, threads, cache;
  app.add_flag("-h,--help", help);
  app.add_flag("--version", version);
  app.add_flag("--keys", keys);
  app.add_flag("-q,--quiet", args.quiet);
  app.add_flag("--force", args.force);
  app.add_flag("--resume", args.resume);
  app.add_option("--checkpoint-every", checkpoint_every);
  app.add_option("--threads", threads);
  app.add_option("-o,--out", args.out);
  auto* cache_opt = app.add_option("--spheroid-cache", cache);
  app.add_flag("--no-cache", no_cache)->excludes(cache_opt);
  app.add_option("--set", args.settings)
      ->allow_extra_args(false)
      ->multi_option_policy(CLI::MultiOptionPolicy::TakeAll);
  app.add_option("SPEC", specs);
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return usageError(e.what());
  }
  if (help) {
    printHelp();
    return kExitOk;
  }
  if (version) {
    std::cout << "foam-run " << ACTIVEFOAM_VERSION << "\n";
    return kExitOk;
  }
  if (keys) {
    printKeys();
    return kExitOk;
  }
  if (!checkpoint_every.empty()) {
    char* end = nullptr;
    const double x = std::strtod(checkpoint_every.c_str(), &end);
    if (*end != '\0' || !std::isfinite(x) || x < 0)
      return usageError("--checkpoint-every: '" + checkpoint_every +
                        "' is not a number of seconds in [0, inf)");
    args.checkpoint_every_s = x;
  }
  if (!threads.empty()) {
    char* end = nullptr;
    const long n = std::strtol(threads.c_str(), &end, 10);
    if (*end != '\0' || n < 1 || n > 1024)
      return usageError("--threads: '" + threads + "' is not a thread count in [1, 1024]");
    args.threads = static_cast<int>(n);
  }
  if (no_cache) args.cache = "";
  if (cache_opt->count() > 0) args.cache = cache;  // "" disables, as --no-cache
  if (specs.size() > 1)
    return usageError("more than one SPEC given ('" + specs[0] + "', '" + specs[1] + "')");
  if (specs.empty()) return usageError("no SPEC given");
  args.spec = specs[0];
  if (args.out.empty()) return usageError("no output directory given (--out DIR)");
  if (args.force && args.resume) return usageError("--force and --resume exclude each other");
  setThreads(args.threads > 0 ? args.threads : defaultThreads());

  // ---- parse → validate → resolve; nothing is written before this succeeds
  SpecParseOptions opts;
  opts.require_scene = false;  // may come from --set
  SpecParseResult parsed = parseSpecFile(args.spec, SceneSpec{}, opts);
  std::vector<SpecError> errors = parsed.errors;
  SpecParseResult set = applySettings(parsed.spec.value_or(SceneSpec{}), args.settings);
  errors.insert(errors.end(), set.errors.begin(), set.errors.end());
  if (errors.empty() && !parsed.scene_given && !set.scene_given)
    errors.push_back({"scene", "missing: the spec must name its scene, " +
                                   findField("scene")->range() +
                                   " (scene = \"...\", or kind = \"...\" in [scene])"});
  SceneSpec spec;
  if (errors.empty()) {
    SpecParseResult ready = validateAndResolve(*set.spec);
    errors = ready.errors;
    if (ready.spec) spec = *ready.spec;
    std::vector<std::string> keys = parsed.keys;
    keys.insert(keys.end(), set.keys.begin(), set.keys.end());
    if (errors.empty()) errors = checkSceneKeys(spec, keys);
  }
  if (!errors.empty()) {
    for (const SpecError& e : errors) std::cerr << "foam-run: invalid spec: " << e.str() << "\n";
    return kExitUsage;
  }
  // foamd refuses these; foam-run runs them (measuring where methods fail is a study's job).
  for (const SpecError& e : measuredUnstable(spec))
    std::cerr << "foam-run: warning: " << e.str() << "; running anyway\n";
  for (const SpecError& e : silentlyWrong(spec))
    std::cerr << "foam-run: warning: " << e.str() << "; running anyway\n";

  // ---- the output folder
  const fs::path dir = args.out;
  std::optional<RunCheckpoint> checkpoint;
  bool start_over = false;
  if (args.resume) {
    std::error_code ec;
    if (fs::exists(dir / "checkpoint.bin", ec)) {
      try {
        checkpoint = decodeRunCheckpoint(readWholeFile(dir / "checkpoint.bin"),
                                         (dir / "checkpoint.bin").string());
      } catch (const std::exception& e) {
        std::cerr << "foam-run: " << e.what() << "\n";
        return kExitUsage;
      }
      // The engine refuses a checkpoint of another spec; say which keys differ first.
      if (std::string diff = specDifference(dir / "spec.json", spec); !diff.empty()) {
        std::cerr << "foam-run: cannot resume: " << diff << "\n";
        return kExitUsage;
      }
    } else if (finishedRun(dir / "summary.json")) {
      std::cerr << "foam-run: " << dir.string() << " holds a finished run; nothing to resume\n";
      return kExitOk;
    } else {
      start_over = fs::exists(dir, ec) && !fs::is_empty(dir, ec);
      if (!args.quiet && start_over)
        std::cerr << "foam-run: no checkpoint in " << dir.string() << ": starting over\n";
    }
  }
  if (std::string why = checkOutputDir(dir, args.force || args.resume); !why.empty()) {
    std::cerr << "foam-run: " << why << "\n";
    return kExitUsage;
  }
  {
    std::error_code ec;
    fs::create_directories(dir, ec);
    if (ec) {
      std::cerr << "foam-run: cannot create '" << dir.string() << "': " << ec.message() << "\n";
      return kExitUsage;
    }
    if (args.force || start_over) {  // outputs of an earlier run must not mix with this one's
      for (const char* name : {"spec.json", "samples.csv", "summary.json", "checkpoint.bin"})
        fs::remove(dir / name, ec);
      fs::remove_all(dir / "snapshots", ec);
    }
  }

  RunOutput out(dir, spec);
  if (checkpoint)
    out.resume(*checkpoint);
  else
    out.start();
  if (!out.error().empty()) {
    std::cerr << "foam-run: " << out.error() << "\n";
    return kExitRunFailed;
  }

  // ---- run
  using Clock = std::chrono::steady_clock;
  const auto t0 = Clock::now();
  const std::string started = utcNow();
  auto last_progress = t0;
  auto last_checkpoint = t0;
  bool output_failed = false;
  // ETA from the pace since the first progress report: spheroid preparation and a resumed
  // run's earlier part are not in it.
  std::optional<std::pair<Clock::time_point, double>> pace_from;

  RunObserver obs;
  obs.cancel = &g_cancel;
  obs.spheroid_cache_dir = args.cache.value_or(defaultCacheDir());
  obs.on_log = [&](const std::string& line) {
    if (!args.quiet) std::cerr << "foam-run: " << line << "\n" << std::flush;
  };
  auto checkOutput = [&] {
    if (!out.error().empty() && !output_failed) {
      output_failed = true;
      g_cancel = true;  // no point in running on without a place to write to
    }
  };
  obs.on_sample = [&](const Sample& s) {
    out.onSample(s);
    checkOutput();
  };
  obs.on_snapshot = [&](const Snapshot& s) {
    out.onSnapshot(s);
    checkOutput();
  };
  // The engine offers a checkpoint after every sample (and when cancelled); we keep one every
  // checkpoint_every_s of wall-clock time, and always the one of an interruption.
  obs.checkpoint_every_s = args.checkpoint_every_s > 0 ? spec.sample_every_s : 0;
  obs.on_checkpoint = [&](double t_s, const std::string& state) {
    const auto now = Clock::now();
    if (!g_cancel.load() &&
        std::chrono::duration<double>(now - last_checkpoint).count() < args.checkpoint_every_s)
      return;
    last_checkpoint = now;
    out.writeCheckpoint(t_s, state);
    checkOutput();
  };
  obs.on_progress = [&](double t_s, std::int64_t step, std::int64_t rejected) {
    if (args.quiet) return;
    const auto now = Clock::now();
    if (!pace_from) pace_from.emplace(now, t_s);
    if (now - last_progress < std::chrono::seconds(2)) return;
    last_progress = now;
    const double elapsed = std::chrono::duration<double>(now - t0).count();
    const double f = spec.duration_s > 0 ? std::clamp(t_s / spec.duration_s, 0.0, 1.0) : 0.0;
    const double done = t_s - pace_from->second;
    const double pace = std::chrono::duration<double>(now - pace_from->first).count();
    const std::string eta =
        done > 0 ? formatDuration(pace / done * std::max(0.0, spec.duration_s - t_s)) : "?";
    char rejected_text[48] = "";
    if (rejected > 0)
      std::snprintf(rejected_text, sizeof rejected_text, " (%lld rejected)",
                    static_cast<long long>(rejected));
    char line[256];
    std::snprintf(line, sizeof line,
                  "foam-run: %5.1f%%  t = %s / %s s  step %lld%s  elapsed %s  ETA %s\n", 100 * f,
                  human(t_s).c_str(), human(spec.duration_s).c_str(), static_cast<long long>(step),
                  rejected_text, formatDuration(elapsed).c_str(), eta.c_str());
    std::cerr << line << std::flush;
  };

  RunSummary summary;
  SummaryContext ctx;
  ctx.started_utc = started;
  try {
    if (checkpoint && !args.quiet)
      std::cerr << "foam-run: resuming from the checkpoint at t = " << human(checkpoint->t_s)
                << " s\n";
    summary = runScene(spec, obs, checkpoint ? &checkpoint->state : nullptr);
  } catch (const std::exception& e) {
    ctx.failure_override = "exception";
    ctx.reason_override = std::string("engine error: ") + e.what();
  }
  if (output_failed) {
    ctx.failure_override = "output_error";
    ctx.reason_override = out.error();
  }
  ctx.samples_written = out.samplesWritten();
  ctx.snapshots_written = out.snapshotsWritten();
  ctx.runner_wall_s = std::chrono::duration<double>(Clock::now() - t0).count();
  ctx.finished_utc = utcNow();
  if (checkpoint) ctx.resumed_from_t_s = checkpoint->t_s;
  out.writeSummary(summaryToJson(summary, spec, ctx));
  // A finished run needs no checkpoint; a failed one keeps it (resuming reproduces the failure
  // bit for bit, which is what one wants to inspect it).
  if (summary.ok() && ctx.failure_override.empty() && out.error().empty()) out.removeCheckpoint();

  if (!out.warning().empty()) std::cerr << "foam-run: warning: " << out.warning() << "\n";
  if (!out.error().empty() && !output_failed)  // summary.json itself could not be written
    std::cerr << "foam-run: " << out.error() << "\n";

  if (!ctx.failure_override.empty()) {
    std::cerr << "foam-run: run failed at t = " << human(summary.t_s)
              << " s: " << ctx.failure_override << ": " << ctx.reason_override << "\n";
    return kExitRunFailed;
  }
  if (summary.failure == FailureKind::Cancelled) {
    std::cerr << "foam-run: interrupted at t = " << human(summary.t_s) << " s (step "
              << summary.steps << "); partial output and checkpoint in " << dir.string()
              << " (continue with --resume)\n";
    return kExitInterrupted;
  }
  if (!summary.ok()) {
    std::cerr << "foam-run: run failed at t = " << human(summary.t_s) << " s (step "
              << summary.steps << "): " << toString(summary.failure) << ": " << summary.reason
              << "\n";
    return kExitRunFailed;
  }
  if (!out.error().empty()) return kExitRunFailed;
  if (!args.quiet) {
    std::cerr << "foam-run: done, t = " << human(summary.t_s) << " s, " << summary.steps
              << " steps in " << formatDuration(ctx.runner_wall_s) << "\n";
    if (!summary.outcome.empty())
      std::cerr << "foam-run: outcome " << summary.outcome << ": " << summary.outcome_why << "\n";
    for (const auto& [model, f] : summary.fits) {
      std::cerr << "foam-run: fit " << model << ": ";
      if (!f.ok) {
        std::cerr << "failed: " << f.why << "\n";
        continue;
      }
      for (std::size_t k = 0; k < f.names.size(); ++k)
        std::cerr << (k ? ", " : "") << f.names[k] << " = " << human(f.value[k]) << " ± "
                  << human(f.std_error[k]);
      std::cerr << " (R² = " << human(f.r2) << ")\n";
    }
  }
  return kExitOk;
}
