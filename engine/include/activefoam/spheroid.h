// Prepared spheroids (docs/model.md §7.3): N cells packed into a ball, then relaxed with the full
// model (adhesion, motility) until the aggregate is compact; cached by everything that shapes them,
// so that a parameter study pays the preparation once per (N, seed, parameters), not per run.
#pragma once

#include <atomic>
#include <cstdint>
#include <functional>
#include <limits>
#include <optional>
#include <string>
#include <vector>

#include "activefoam/cellset.h"
#include "activefoam/spec.h"

namespace activefoam {

struct PreparedSpheroid {
  CellSet cells;                  // labels 0, centred on the aggregate's volume centroid
  double relaxed_s = 0;           // simulated time of the relaxation
  bool compact = false;           // the compaction criterion was met (else stopped at prep_max_s)
  double radius_gyration_um = 0;  // at the end of the relaxation
  // |dRg/dt|/Rg over the last 60 s window (1/s); NaN before the first window, and for spheroids
  // cached by versions that did not store it.
  double compaction_rate_per_s = std::numeric_limits<double>::quiet_NaN();
  bool from_cache = false;
  std::string key;  // the cache key (16 hex digits)
};

// The relaxation run that prepares one spheroid of `spec` (a spheroid or fusion spec): scene
// spheroid with n_cells cells and the given seed, the spec's cell parameters and mesh settings
// (or the values its [prepare] table gives instead), at scene.prep_dt_s, for at most
// scene.prep_max_s; every key the table marks Fixed (SpecField::prep: the solver, the contact
// law, the repairs, failure limits, fusion-only keys) at the preparation's value, so that it does
// not change the cache key; the mesh settings do. buildFusionCells may loosen the volume limit
// (see there).
SceneSpec spheroidPrepSpec(const SceneSpec& spec, std::int64_t n_cells, std::uint64_t seed);

// The seeds of a fusion spec's spheroids A (0) and B (1): derived from its seed.
std::uint64_t spheroidSeed(std::uint64_t seed, int which);

// 16 hex digits of a 64-bit FNV-1a hash of the engine version and the prep spec's full
// fingerprint (every key).
std::string spheroidCacheKey(const SceneSpec& prep);

// A directory of prepared spheroids, one file per key. A file stores the prep spec's
// fingerprint, so a hash collision or a file from another engine version reads as absent.
// Writes are atomic (temporary file, then rename): concurrent writers of one key are harmless.
class SpheroidCache {
 public:
  explicit SpheroidCache(std::string dir) : dir_(std::move(dir)) {}
  const std::string& dir() const { return dir_; }
  std::optional<PreparedSpheroid> load(const SceneSpec& prep) const;
  // Whether a file for `prep` is there (not read: load() still checks it).
  bool holds(const SceneSpec& prep) const;
  // Throws std::runtime_error if the directory cannot be created or written.
  void store(const SceneSpec& prep, const PreparedSpheroid& s) const;

 private:
  std::string dir_;
};

struct PrepObserver {
  std::function<void(const std::string&)> on_log;  // one line per stage
  const std::atomic<bool>* cancel = nullptr;       // polled every step
};

// Thrown when a relaxation fails (the reason names the failure) or is cancelled.
struct PrepFailed : std::runtime_error {
  using std::runtime_error::runtime_error;
  bool cancelled = false;
  bool volume_drift = false;  // a cell's volume error crossed the preparation's limit
};

// The compaction criterion: the run is compact at time t (≥ 120 s) when
// |Rg(t) − Rg(t − 60 s)| / Rg(t) < rate × 60 s.
// Prepares (or loads from `cache`, which may be null) the spheroid of `prep`.
PreparedSpheroid prepareSpheroid(const SceneSpec& prep, const SpheroidCache* cache,
                                 const PrepObserver& observer = {});

// The fusion scene's cells: spheroid A (n_cells_a or n_cells, label 0) at the origin and B
// (label 1) along +x, the facing extremes gap_um apart; polarities drawn from the spec's seed.
// A spheroid whose preparation fails on the default volume limit is prepared again under the
// run's numerics.max_volume_error when that is looser (a run that tolerates larger volume
// errors tolerates them in its preparation too); the spheroids that pass keep their bits.
// `info` (optional) receives the two preparations.
CellSet buildFusionCells(const SceneSpec& spec, const SpheroidCache* cache,
                         const PrepObserver& observer = {},
                         std::vector<PreparedSpheroid>* info = nullptr);

// Cells of the right count and sizes for a fusion run that is about to load a checkpoint (the
// checkpoint replaces them): no preparation is repeated.
CellSet placeholderCells(const SceneSpec& spec);

// Radius of gyration of the cells' volume centroids (volume-weighted), µm.
double radiusOfGyration(const CellSet& cells, const std::vector<double>& volumes,
                        const std::vector<Vec3>& centroids);

// A CellSet as bytes and back (positions, triangles, per-cell state; not velocities).
std::string serializeCells(const CellSet& cells);
CellSet deserializeCells(const std::string& bytes);

}  // namespace activefoam
