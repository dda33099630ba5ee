// The output folder of one run (docs/usage.md): spec.json, samples.csv, snapshots/, summary.json.
// Used by foam-run; kept apart from main() so it can be tested without running the engine.
#pragma once

#include <cstdint>
#include <filesystem>
#include <fstream>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include <nlohmann/json.hpp>

#include "activefoam/run.h"
#include "activefoam/spec.h"
#include "activefoam/vtk.h"

namespace activefoam {

// Writes `content` to a temporary file beside `path`, then renames it over `path`, so readers
// see the old file or the whole new one. Throws std::runtime_error naming the file.
void writeFileAtomic(const std::filesystem::path& path, std::string_view content);

// Empty when `dir` may receive a run's output: missing, or an empty directory, or (with
// `force`) any directory. Otherwise a one-line reason.
std::string checkOutputDir(const std::filesystem::path& dir, bool force);

// One CSV line (no newline): values in shortest round-trip form, "nan"/"inf" as such.
std::string csvLine(const std::vector<double>& values);
std::string csvLine(const std::vector<std::string>& names);

// The reduced parameters (docs/model.md §9.2, Table 2) of a resolved spec: tau_gamma_s = η/γ,
// pa_reduced = p_a r/2γ, alpha, l_eta_reduced = √(η/ξ)/r (null when ξ = 0), tau_p_s, and the
// cell count.
nlohmann::json reducedParameters(const SceneSpec& resolved);

// summary.json. `failure_override` (e.g. "exception", "output_error") replaces the engine's
// failure kind when the runner itself failed; `reason_override` its reason.
struct SummaryContext {
  std::string failure_override;
  std::string reason_override;
  std::int64_t samples_written = 0;
  std::int64_t snapshots_written = 0;
  double runner_wall_s = 0;
  std::string started_utc;
  std::string finished_utc;
  double resumed_from_t_s = -1;  // ≥ 0: this invocation continued a checkpoint of that time
};
nlohmann::json summaryToJson(const RunSummary& summary, const SceneSpec& resolved,
                             const SummaryContext& context);

// A run's results as foamd stores them, from its summary.json (summaryToJson): the final
// values, the cost counters (t_s, steps, wall_s, cg_iters_mean, remesh_ops, steps_rejected,
// dt_min_s), per fit "<model>_ok" and, when ok, "<model>_r2" and each parameter (fitResultName)
// with "<name>_se"; null reads as NaN; the curves: "msrd", then those under "curves" (the
// probes', RunSummary::curves) by name. One definition for the pool (its own summary) and the
// Slurm executor (a task's file), so the two cannot drift apart. Throws nlohmann::json's
// exceptions on a summary that is not an object.
struct FlatCurve {
  std::string name;  // "msrd": x lag (s), y MSRD (µm²); or a probe's (RunSummary::curves)
  std::vector<double> x, y;
};
struct FlatResults {
  std::vector<std::pair<std::string, double>> values;
  std::string outcome;  // fusion: fused | arrested | separated | no-contact; else empty
  std::vector<FlatCurve> curves;
};
FlatResults flattenSummary(const nlohmann::json& summary);

// An engine snapshot as the VTK writer's plain data.
VtkMesh toVtkMesh(const Snapshot& snap);

// ISO 8601 UTC time of now, e.g. "2026-11-22T10:53:26Z".
std::string utcNow();

// checkpoint.bin: what a run needs to continue after an interruption: the engine's state
// (runScene's checkpoint) and how much of the output folder belongs to it.
struct RunCheckpoint {
  double t_s = 0;
  std::int64_t samples = 0;                               // rows of samples.csv, header aside
  std::vector<std::pair<double, std::string>> snapshots;  // series.pvd entries
  std::string state;
};
std::string encodeRunCheckpoint(const RunCheckpoint& c);
// Throws std::runtime_error naming the file when it is damaged.
RunCheckpoint decodeRunCheckpoint(const std::string& bytes, const std::string& what);

// Streams one run's files into a prepared (existing, empty) directory. Write errors do not
// throw: the first one is kept in error() and later writes are skipped.
class RunOutput {
 public:
  RunOutput(std::filesystem::path dir, const SceneSpec& resolved);

  void start();                                      // spec.json, and samples.csv with its header
  void onSample(const Sample& sample);               // a row of samples.csv, flushed
  void onSnapshot(const Snapshot& snap);             // snapshots/snap_NNNNNN.vtp + series.pvd
  void writeSummary(const nlohmann::json& summary);  // summary.json (atomic)
  // Continue a run from a checkpoint: samples.csv keeps its header and the checkpoint's rows
  // (later ones, written after the checkpoint, are dropped: the resumed run writes them again),
  // snapshots after it are removed, and summary.json of the interrupted run is removed.
  void resume(const RunCheckpoint& c);
  // checkpoint.bin (atomic), recording the rows and snapshots written so far.
  void writeCheckpoint(double t_s, const std::string& state);
  void removeCheckpoint();

  const std::string& error() const { return error_; }
  // Set when a sample did not have one value per column (the row was padded with nan or cut).
  const std::string& warning() const { return warning_; }
  std::int64_t samplesWritten() const { return samples_; }
  std::int64_t snapshotsWritten() const { return static_cast<std::int64_t>(series_.size()); }
  const std::filesystem::path& dir() const { return dir_; }

 private:
  void fail(std::string message);

  std::filesystem::path dir_;
  SceneSpec spec_;
  std::ofstream csv_;
  std::size_t columns_ = 0;
  std::int64_t samples_ = 0;
  std::vector<std::pair<double, std::string>> series_;
  std::string error_;
  std::string warning_;
};

}  // namespace activefoam
