// The reduced base point's fusion as the study drivers start it (study_dissipation,
// study_shape): the supplement's Table 1/2 parameters with p_a r/2γ = 0.33,
// 320 triangles a cell, then foam-run's key=value settings; and its aggregate, prepared once into
// a cache. And the configurations study_dissipation and study_shape run from it.
#pragma once

#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <optional>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include "activefoam/spec.h"
#include "activefoam/spec_io.h"
#include "activefoam/spheroid.h"
#include "scheme_config.h"

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

// One configuration of a driver's list "l_eta[:key=value…][,l_eta…]": an L_η/r and the
// settings that apply to it alone (0.5:cells.eta_m=0.1); the aggregate is the same for all.
struct Config {
  double l_eta;
  std::vector<std::string> settings;
  std::string label;  // as written in the list
};

inline std::vector<Config> parseConfigs(const char* list) {
  std::vector<Config> configs;
  std::stringstream items(list);
  for (std::string item; std::getline(items, item, ',');) {
    Config c{std::atof(item.c_str()), {}, item};
    std::stringstream parts(item);
    std::string part;
    std::getline(parts, part, ':');
    while (std::getline(parts, part, ':')) c.settings.push_back(part);
    configs.push_back(c);
  }
  return configs;
}

// The resolved spec a configuration runs: the base point's (unresolved: L_η/r derives ξ, and
// ξ⊥, ξ∥ where not set) with its L_η/r and settings, then the step "integrator:Δt:…"; nullopt
// (the error printed) when a setting or the step is malformed.
inline std::optional<SceneSpec> configSpec(const BasePoint& point, const Config& config,
                                           const char* step, SchemeConfig& scheme) {
  SceneSpec s = point.spec;
  s.cells.l_eta_reduced = config.l_eta;
  for (const std::string& setting : config.settings)
    if (const auto error = applySetting(s, setting)) {
      std::fprintf(stderr, "%s: %s\n", setting.c_str(), error->str().c_str());
      return std::nullopt;
    }
  if (const std::string error = applySchemeConfig(step, s, scheme); !error.empty()) {
    std::fprintf(stderr, "%s: %s\n", step, error.c_str());
    return std::nullopt;
  }
  return resolve(s);
}

// The common command line of study_dissipation and study_shape: CACHE_DIR n_cells seed T_s
// sample_s STEP CONFIGS [key=value …]; nullopt (the usage or the error printed) when it is
// wrong, any configuration's settings included.
struct ConfigDriver {
  BasePoint point;
  std::vector<Config> configs;
  const char* step;
};

inline std::optional<ConfigDriver> configDriver(int argc, char** argv, const char* name) {
  if (argc < 8) {
    std::fprintf(stderr,
                 "usage: %s CACHE_DIR n_cells seed T_s sample_s "
                 "integrator:dt:preconditioner[:cg_tol] l_eta[:key=value...][,l_eta...] "
                 "[key=value ...]\n",
                 name);
    return std::nullopt;
  }
  auto point = basePoint(argc, argv, 8);
  if (!point) return std::nullopt;
  ConfigDriver d{std::move(*point), parseConfigs(argv[7]), argv[6]};
  // Every configuration's keys checked now: a typo in the last one is not found an hour in.
  for (const Config& c : d.configs) {
    SchemeConfig scheme;
    if (!configSpec(d.point, c, d.step, scheme)) return std::nullopt;
  }
  return d;
}

}  // namespace activefoam::bench
