// Counter-based random numbers: a stream is a pure function of (seed, stream id, counter), so a
// run is reproducible from (seed, spec) regardless of thread count or the order cells are
// visited. SplitMix64 finalizer on the mixed key; Box–Muller normals; Marsaglia–Tsang Gamma.
#pragma once

#include <cmath>
#include <cstdint>

namespace activefoam {

class Rng {
 public:
  Rng(std::uint64_t seed, std::uint64_t stream)
      : key_(mix(seed ^ mix(stream + 0x9E3779B97F4A7C15ULL))) {}
  std::uint64_t next() { return mix(key_ + 0x9E3779B97F4A7C15ULL * ++counter_); }
  // Uniform in (0, 1): never exactly 0 or 1.
  double uniform() { return (static_cast<double>(next() >> 11) + 0.5) * 0x1.0p-53; }
  double normal() {
    const double u1 = uniform(), u2 = uniform();
    return std::sqrt(-2.0 * std::log(u1)) * std::cos(2.0 * M_PI * u2);
  }
  // Gamma(k, 1) for k ≥ 1 (Marsaglia & Tsang 2000).
  double gamma(double k) {
    const double d = k - 1.0 / 3.0, c = 1.0 / std::sqrt(9.0 * d);
    for (;;) {
      double z, v;
      do {
        z = normal();
        v = 1.0 + c * z;
      } while (v <= 0);
      v = v * v * v;
      const double u = uniform();
      if (std::log(u) < 0.5 * z * z + d - d * v + d * std::log(v)) return d * v;
    }
  }
  std::uint64_t counter() const { return counter_; }

 private:
  static std::uint64_t mix(std::uint64_t z) {
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ULL;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBULL;
    return z ^ (z >> 31);
  }
  std::uint64_t key_;
  std::uint64_t counter_ = 0;
};

}  // namespace activefoam
