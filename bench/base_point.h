// The reduced base point's fusion as the study drivers start it (study_dt_motion,
// study_dissipation): the supplement's Table 1/2 parameters with p_a r/2γ = 0.33, 320 triangles
// a cell, then foam-run's key=value settings; and its aggregate, prepared once into a cache.
#pragma once

#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <optional>
#include <string>

#include "activefoam/spec.h"
#include "activefoam/spec_io.h"
#include "activefoam/spheroid.h"

namespace activefoam::bench {

// What the drivers' common arguments give: CACHE_DIR n_cells seed T_s sample_s, then (after
// the driver's own arguments) key=value settings.
struct BasePoint {
  SceneSpec spec;      // unresolved: a configuration may change a key the resolution derives
  SceneSpec resolved;  // what the aggregate was prepared from
  CellSet cells;       // the two spheroids
  double duration_s = 0, sample_s = 0;
};

// argv[1..5] as above, argv[first_setting..argc) the settings; nullopt (the error printed) when
// a setting is malformed or out of range. Prepares the spheroids into CACHE_DIR, or loads them.
inline std::optional<BasePoint> basePoint(int argc, char** argv, int first_setting) {
  BasePoint b;
  SceneSpec& s = b.spec;
  s.scene = SceneKind::Fusion;
  s.scene_params.n_cells = std::atoi(argv[2]);
  s.seed = static_cast<std::uint64_t>(std::atoll(argv[3]));
  s.cells.pa_reduced = 0.33;
  s.numerics.triangles_per_cell = 320;
  b.duration_s = std::atof(argv[4]);
  b.sample_s = std::atof(argv[5]);
  for (int a = first_setting; a < argc; ++a)
    if (const auto error = applySetting(s, argv[a])) {  // as foam-run --set
      std::fprintf(stderr, "%s: %s\n", argv[a], error->str().c_str());
      return std::nullopt;
    }
  b.resolved = resolve(s);
  const SpheroidCache cache(argv[1]);
  b.cells = buildFusionCells(
      b.resolved, &cache, {[](const std::string& l) { std::fprintf(stderr, "%s\n", l.c_str()); }});
  return b;
}

}  // namespace activefoam::bench
