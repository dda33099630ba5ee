// The study drivers that replay a job read its spec file (a resolved spec.json from `foam show
// --json` or foam-run's output) the same way.
#pragma once

#include <cstdio>
#include <optional>

#include "activefoam/spec_io.h"

namespace activefoam {

// The spec in `path`, validated and resolved; empty after printing its errors on stderr.
inline std::optional<SceneSpec> readResolvedSpec(const char* path) {
  SpecParseResult parsed = parseSpecFile(path);
  if (parsed.ok()) parsed = validateAndResolve(*parsed.spec);
  if (!parsed.ok()) {
    for (const auto& e : parsed.errors) std::fprintf(stderr, "%s\n", e.str().c_str());
    return std::nullopt;
  }
  return *parsed.spec;
}

}  // namespace activefoam
