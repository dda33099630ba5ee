#include <cmath>
#include <stdexcept>
#include <string>

#include "activefoam/rng.h"
#include "activefoam/simulation.h"
#include "activefoam/spheroid.h"

namespace activefoam {
namespace {

// Radii ~ Gamma(k, θ = r/k) (mean r); k = 0 means every cell has radius r. Stream 0 of the
// seed is reserved for scene construction.
double drawRadius(const CellParams& p, Rng& rng) {
  if (p.radius_gamma_k <= 0) return p.radius_mean_um;
  return rng.gamma(p.radius_gamma_k) * p.radius_mean_um / p.radius_gamma_k;
}

// Uniform on the unit sphere.
Vec3 randomUnitVector(Rng& rng) {
  const double z = 2 * rng.uniform() - 1, phi = 2 * M_PI * rng.uniform();
  const double s = std::sqrt(1 - z * z);
  return {s * std::cos(phi), s * std::sin(phi), z};
}

}  // namespace

TriMesh ellipsoidCell(double radius, double axes_ratio, int triangles, const Vec3& centre) {
  const int level = icosphereLevelForTriangles(triangles);
  if (level < 0) throw std::invalid_argument("triangles_per_cell must be 80, 320 or 1280");
  TriMesh m = icosphere(level);
  // Scale so the polyhedron (not the circumscribed sphere) holds V* = 4/3 π r³: the cell then
  // starts with zero volume error and P = 2γ/r.
  const double vstar = 4.0 / 3.0 * M_PI * radius * radius * radius;
  m.x *= std::cbrt(vstar / meshVolume(m));
  const Eigen::Vector3d axes(axes_ratio, 1.0, 1.0 / axes_ratio);  // det = 1: volume kept
  m.x = axes.asDiagonal() * m.x;
  m.x.colwise() += centre;
  return m;
}

std::vector<Vec3> packSpheres(const std::vector<double>& radii, std::uint64_t seed) {
  const int n = static_cast<int>(radii.size());
  double mean = 0;
  for (double r : radii) mean += r / n;
  Rng rng(seed, 0x5053ULL);  // its own stream: scene stream 0 draws radii and polarities
  // Start loose: uniform in a ball at packing fraction ~0.2.
  const double r0 = mean * std::cbrt(n / 0.2);
  std::vector<Vec3> x(n);
  for (Vec3& p : x) {
    do p = Vec3(2 * rng.uniform() - 1, 2 * rng.uniform() - 1, 2 * rng.uniform() - 1);
    while (p.squaredNorm() > 1);
    p *= r0;
  }
  std::vector<Vec3> f(n);
  // pull: a constant-magnitude step towards the centre (gravity-like: overlaps stay small
  // everywhere, unlike a spring pull that crushes the core).
  auto relax = [&](double pull, int iterations, double tol) {
    for (int it = 0; it < iterations; ++it) {
      Vec3 c = Vec3::Zero();
      for (const Vec3& p : x) c += p / n;
      for (int i = 0; i < n; ++i) {
        const Vec3 d = c - x[i];
        const double dn = d.norm();
        f[i] = dn > pull ? Vec3(pull * d / dn) : Vec3::Zero();
      }
      double worst = 0;
      for (int i = 0; i < n; ++i)
        for (int j = i + 1; j < n; ++j) {
          const Vec3 d = x[j] - x[i];
          const double dist = d.norm(), overlap = radii[i] + radii[j] - dist;
          if (overlap <= 0 || dist == 0) continue;
          worst = std::max(worst, overlap);
          const Vec3 push = 0.25 * overlap * d / dist;
          f[i] -= push;
          f[j] += push;
        }
      if (pull == 0 && worst < tol) return;
      for (int i = 0; i < n; ++i) x[i] += f[i];
    }
  };
  relax(0.01 * mean, 5000, 0);      // compact
  relax(0.0, 200000, 1e-3 * mean);  // remove the overlaps the pull held
  return x;
}

CellSet buildScene(const SceneSpec& spec) {
  CellSet cells;
  Rng rng(spec.seed, 0);
  const int tris = static_cast<int>(spec.numerics.triangles_per_cell);
  switch (spec.scene) {
    case SceneKind::Cell: {
      const double r = drawRadius(spec.cells, rng);
      cells.addCell(ellipsoidCell(r, spec.scene_params.axes_ratio, tris, Vec3::Zero()), r);
      return cells;
    }
    case SceneKind::Doublet: {
      // Two cells along x, the gap measured between the meshes' facing extremes.
      const double ra = drawRadius(spec.cells, rng), rb = drawRadius(spec.cells, rng);
      TriMesh a = ellipsoidCell(ra, 1.0, tris, Vec3::Zero());
      TriMesh b = ellipsoidCell(rb, 1.0, tris, Vec3::Zero());
      const double shift = a.x.row(0).maxCoeff() - b.x.row(0).minCoeff() + initialGapUm(spec);
      b.x.row(0).array() += shift;
      cells.addCell(a, ra);
      cells.addCell(b, rb);
      for (Vec3& p : cells.polarity) p = randomUnitVector(rng);
      return cells;
    }
    case SceneKind::Spheroid: {
      const int n = static_cast<int>(spec.scene_params.n_cells);
      std::vector<double> radii(n);
      for (double& r : radii) r = drawRadius(spec.cells, rng);
      const std::vector<Vec3> centres = packSpheres(radii, spec.seed);
      for (int c = 0; c < n; ++c)
        cells.addCell(ellipsoidCell(radii[c], 1.0, tris, centres[c]), radii[c]);
      for (Vec3& p : cells.polarity) p = randomUnitVector(rng);
      return cells;
    }
    case SceneKind::Fusion:
      return buildFusionCells(spec, nullptr);  // runScene passes the spheroid cache
  }
  throw std::invalid_argument("unknown scene");
}

}  // namespace activefoam
