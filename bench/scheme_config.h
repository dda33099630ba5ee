// A study driver's step configuration, "integrator:Δt:preconditioner[:ε_CG]", applied to a spec.
// The integrator is any of numerics.integrator, or "ros2-centroid": ros2 with contact-implicit's
// one spring per pair in W instead of the consistent stiffness, a variant no spec can name
// (docs/science/motion-convergence.md measures it).
#pragma once

#include <cstdlib>
#include <memory>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include "activefoam/spec.h"
#include "activefoam/time_scheme.h"

namespace activefoam::bench {

struct SchemeConfig {
  bool ros2_centroid = false;
  // The scheme the configuration asks for (the spec's, unless ros2-centroid).
  std::unique_ptr<TimeScheme> scheme(const SceneSpec& resolved) const {
    return ros2_centroid ? makeRos2(resolved.numerics, false) : makeTimeScheme(resolved.numerics);
  }
};

// Sets the configuration's keys on `spec` (not resolved); returns the error text, empty if none.
inline std::string applySchemeConfig(const std::string& config, SceneSpec& spec,
                                     SchemeConfig& out) {
  std::string integrator, dt, pre, tol;
  std::stringstream parts(config);
  std::getline(parts, integrator, ':');
  std::getline(parts, dt, ':');
  std::getline(parts, pre, ':');
  std::getline(parts, tol, ':');
  out.ros2_centroid = integrator == "ros2-centroid";
  if (out.ros2_centroid) integrator = "ros2";
  std::vector<std::pair<std::string, std::string>> fields = {
      {"numerics.integrator", integrator}, {"numerics.dt_s", dt}, {"numerics.preconditioner", pre}};
  if (!tol.empty()) fields.emplace_back("numerics.cg_tol", tol);
  for (const auto& [key, text] : fields) {
    const bool number = key != "numerics.integrator" && key != "numerics.preconditioner";
    if (const auto error =
            setField(spec, key, number ? SpecValue(std::atof(text.c_str())) : SpecValue(text)))
      return error->str();
  }
  return {};
}

// The reduced fusion of the study drivers (seed 1, 2 × n cells of 320 triangles, preparation
// up to prep_max_s) at a configuration, resolved; returns the error text, empty if none.
inline std::string fusionSpec(const std::string& config, int n, double prep_max_s, SceneSpec& out,
                              SchemeConfig& scheme) {
  SceneSpec s;
  s.scene = SceneKind::Fusion;
  s.seed = 1;
  s.scene_params.n_cells = n;
  s.scene_params.prep_max_s = prep_max_s;
  s.numerics.triangles_per_cell = 320;
  if (std::string error = applySchemeConfig(config, s, scheme); !error.empty()) return error;
  out = s;
  return {};
}

}  // namespace activefoam::bench
