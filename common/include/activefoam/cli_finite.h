// A CLI11 check that a number option holds a finite number. CLI11's Range and PositiveNumber
// compare, and every comparison with NaN is false: `--fps nan` passed Range(0.1, 120) and
// reached ffmpeg, `foamd --checkpoint-every-s nan` started with a NaN interval. Give it before
// the range check: CLI11 reports the first check that fails.
#pragma once

#include <cmath>
#include <cstdlib>
#include <string>

#include <CLI/CLI.hpp>

namespace activefoam {

inline CLI::Validator finiteNumber() {
  return CLI::Validator(
      [](std::string& s) {
        char* end = nullptr;
        const double v = std::strtod(s.c_str(), &end);
        return end != s.c_str() && !std::isfinite(v) ? "'" + s + "' is not a finite number"
                                                     : std::string();
      },
      "FINITE");
}

}  // namespace activefoam
