// Shared helpers for engine tests.
#pragma once

#include <gtest/gtest.h>
#include <cstdint>
#include <cstring>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "activefoam/rng.h"
#include "activefoam/run.h"
#include "activefoam/simulation.h"

namespace activefoam::testing {

// The numerics the engine's unit tests were written at (the defaults before `standard` became
// the figure studies' step): contact-implicit, Δt 0.1 s, ε_CG 1e-3, the supplement's contact
// law, no remesh repairs, the 5 % volume guard. The tests of a mechanism keep the step they
// measured it at; the default step has its own tests (tests/scenes/test_default_step.cc).
inline void earlierNumerics(SceneSpec& s) {
  s.numerics.integrator = IntegratorKind::ContactImplicit;
  s.numerics.dt_s = 0.1;
  s.numerics.cg_tol = 1e-3;
  s.numerics.contact_law = ContactLawKind::Supplement;
  s.numerics.remesh_repair = RemeshRepair::None;
  s.numerics.max_volume_error = 0.05;
  s.scene_params.polarity_from_preparation = false;
}

// A resolved `cell` spec with a fixed radius r (no Gamma spread), no motility (p_a = 0: passive
// mechanics, so contact angles are the Young–Dupré ones) and the other Table 1 defaults.
inline SceneSpec cellSpec(double axes_ratio = 1.0, int triangles = 320) {
  SceneSpec s;
  earlierNumerics(s);
  s.scene = SceneKind::Cell;
  s.cells.radius_gamma_k = 0;
  s.cells.p_a = 0;
  s.scene_params.axes_ratio = axes_ratio;
  s.numerics.triangles_per_cell = triangles;
  s.cells.tau_k_s = defaultTauKS(s.cells);
  s.numerics.remesh_every_s = defaultRemeshEveryS(s.cells);
  return s;
}

// Two such cells of 80 triangles, sampled every `sample_every_s`, no snapshots.
inline SceneSpec doubletSpec(double duration_s, double sample_every_s) {
  SceneSpec s = cellSpec(1.0, 80);
  s.scene = SceneKind::Doublet;
  s.duration_s = duration_s;
  s.sample_every_s = sample_every_s;
  s.snapshot_every_s = 0;
  return s;
}

// A fusion of two tiny spheroids (by default 3 + 4 cells of 80 triangles, 10 s at Δt 0.5 s,
// sampled every second), relaxed for 10 s only: fast enough for the sanitizer passes. Unresolved:
// for keys that resolve() derives from (smallFusionSpec is it resolved).
inline SceneSpec smallFusionBase(std::uint64_t seed = 5, int n_cells_a = 3, int n_cells_b = 4,
                                 double duration_s = 10, double sample_every_s = 1) {
  SceneSpec s;
  earlierNumerics(s);
  s.scene = SceneKind::Fusion;
  s.seed = seed;
  s.scene_params.n_cells_a = n_cells_a;
  s.scene_params.n_cells_b = n_cells_b;
  s.scene_params.prep_max_s = 10;  // not compact: a few steps of relaxation suffice here
  s.scene_params.allow_uncompacted = true;
  s.numerics.triangles_per_cell = 80;
  s.numerics.dt_s = 0.5;
  s.duration_s = duration_s;
  s.sample_every_s = sample_every_s;
  s.snapshot_every_s = 0;
  return s;
}

inline SceneSpec smallFusionSpec(std::uint64_t seed = 5, int n_cells_a = 3, int n_cells_b = 4,
                                 double duration_s = 10, double sample_every_s = 1) {
  const SceneSpec s = smallFusionBase(seed, n_cells_a, n_cells_b, duration_s, sample_every_s);
  EXPECT_TRUE(validate(s).empty());
  return resolve(s);
}

// The figure studies' step: the one-stage consistent stiffness at Δt 1 s with
// ε_CG 1e-2 and the contact's overlapping part kept within the triangles' prisms.
inline SceneSpec studiesStep(SceneSpec s) {
  s.numerics.integrator = IntegratorKind::ContactImplicitConsistent;
  s.numerics.dt_s = 1.0;
  s.numerics.cg_tol = 1e-2;
  s.numerics.contact_law = ContactLawKind::PrismsOverlap;
  EXPECT_TRUE(validate(s).empty());
  return resolve(s);
}

// Moves every vertex by a random vector of the given size (seeded): a generic, non-symmetric
// configuration for force tests.
inline void jiggle(CellSet& cells, double size, std::uint64_t seed) {
  Rng rng(seed, 99);
  for (int i = 0; i < cells.numVertices(); ++i)
    for (int k = 0; k < 3; ++k) cells.x(k, i) += size * (2 * rng.uniform() - 1);
}

// Samples without the wall-clock column (index 2): what a reproducible run must repeat exactly.
inline std::vector<std::vector<double>> physicsColumns(const std::vector<Sample>& samples) {
  std::vector<std::vector<double>> out;
  for (const Sample& s : samples) {
    auto v = s.values;
    v.erase(v.begin() + 2);
    out.push_back(v);
  }
  return out;
}

// The values' bits, for comparing runs whose samples hold NaN (a probe's columns at t = 0).
inline std::vector<std::vector<std::uint64_t>> bits(const std::vector<std::vector<double>>& rows) {
  std::vector<std::vector<std::uint64_t>> out;
  for (const auto& r : rows) {
    std::vector<std::uint64_t> b(r.size());
    if (!r.empty())
      std::memcpy(b.data(), r.data(), sizeof(double) * r.size());  // (empty: no data())
    out.push_back(std::move(b));
  }
  return out;
}

// A summary's curves, the MSRD's and the probes' (RunSummary::curves), as name and bits of x
// then y: what a reproducible run must repeat.
inline std::vector<std::pair<std::string, std::vector<std::uint64_t>>> curveBits(
    const RunSummary& s) {
  std::vector<std::pair<std::string, std::vector<double>>> curves;
  curves.emplace_back("msrd", std::vector<double>{});
  for (const auto& [x, y] : s.msrd) curves.back().second.insert(curves.back().second.end(), {x, y});
  for (const RunSummary::Curve& c : s.curves) {
    curves.emplace_back(c.name, c.x);
    curves.back().second.insert(curves.back().second.end(), c.y.begin(), c.y.end());
  }
  std::vector<std::pair<std::string, std::vector<std::uint64_t>>> out;
  for (const auto& [name, v] : curves) out.emplace_back(name, bits({v}).front());
  return out;
}

// A cell mesh written as OBJ (tests/engine/data/*.obj), with its radius from a "# radius_um R"
// line.
struct ObjCell {
  TriMesh mesh;
  double radius = 0;
};

inline ObjCell readObjCell(const std::string& path) {
  std::ifstream in(path);
  EXPECT_TRUE(in) << path;
  ObjCell cell;
  std::vector<Vec3> xs;
  std::string line;
  while (std::getline(in, line)) {
    std::istringstream ss(line);
    std::string k;
    ss >> k;
    if (k == "#") {
      std::string w;
      if (ss >> w && w == "radius_um") ss >> cell.radius;
    } else if (k == "v") {
      Vec3 x;
      ss >> x[0] >> x[1] >> x[2];
      xs.push_back(x);
    } else if (k == "f") {
      Tri f;
      ss >> f[0] >> f[1] >> f[2];
      for (int& q : f) --q;
      cell.mesh.tri.push_back(f);
    }
  }
  cell.mesh.x.resize(3, static_cast<Eigen::Index>(xs.size()));
  for (std::size_t i = 0; i < xs.size(); ++i) cell.mesh.x.col(static_cast<Eigen::Index>(i)) = xs[i];
  cell.mesh.v = Eigen::Matrix3Xd::Zero(3, cell.mesh.x.cols());
  return cell;
}

}  // namespace activefoam::testing
