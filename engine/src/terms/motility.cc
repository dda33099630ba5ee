// S8–S11: active migration (ActiveMigration): the traction of each cell's protrusions on its
// contacts (the step's contact areas), and the rotational diffusion of its polarity along one
// Wiener path per cell.
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>

#include "activefoam/contacts.h"
#include "activefoam/motility.h"
#include "activefoam/rng.h"
#include "activefoam/threads.h"

namespace activefoam {

double ActiveMigration::addForces(const StepContext& ctx, Eigen::Matrix3Xd& f) const {
  if (!ctx.contacts || p_a_ == 0) return 0;
  const CellSet& cells = ctx.cells;
  const ContactList& con = *ctx.contacts;
  // Each cell writes only its own vertices.
#pragma omp parallel for schedule(static) if (cells.numVertices() > grain().min_items)
  for (int c = 0; c < cells.numCells(); ++c) {
    const double sc = con.cell_contact_area[c];
    if (sc <= 0) continue;  // migration needs a substrate: no contact, no traction
    const double scale = p_a_ * sc / ctx.geo.cell_area[c];
    const Vec3& p = cells.polarity[c];
    const Vec3& xc = ctx.geo.cell_centroid[c];
    Vec3 total = Vec3::Zero();
    const int v0 = cells.cell_vertex_begin[c], v1 = cells.cell_vertex_begin[c + 1];
    for (int i = v0; i < v1; ++i) {
      const Vec3 r = cells.x.col(i) - xc;
      const double rn = r.norm();
      if (rn == 0) continue;
      const Vec3 fi = scale * (r.dot(p) / rn) * ctx.geo.vertex_area[i] * ctx.geo.vertex_normal[i];
      f.col(i) += fi;
      total += fi;
    }
    for (int i = v0; i < v1; ++i)
      if (con.vertex_contact_area[i] > 0) f.col(i) -= con.vertex_contact_area[i] / sc * total;
  }
  return 0;
}

namespace {

// Grid coordinate of a time: times the engine reaches are sums of dyadic fractions of Δt, so a
// time meant to sit on the grid can be off it by roundoff (0.1 · 3 / 0.01 = 30.000000000000004).
double gridCoordinate(double t) {
  const double u = t / ActiveMigration::kNoiseGridS;
  const double r = std::round(u);
  return std::abs(u - r) < 1e-7 * std::max(1.0, std::abs(u)) ? r : u;
}

}  // namespace

Vec3 ActiveMigration::wienerIncrement(std::uint64_t seed, int cell, double t0, double t1) {
  const double u0 = gridCoordinate(t0), u1 = gridCoordinate(t1);
  Vec3 dw = Vec3::Zero();
  if (!(u1 > u0)) return dw;
  const auto k_begin = static_cast<std::int64_t>(std::floor(u0));
  const auto k_end = static_cast<std::int64_t>(std::ceil(u1));
  std::int64_t block = -1;
  std::array<Vec3, kNoiseBlock> xi;
  for (std::int64_t k = k_begin; k < k_end; ++k) {
    if (k / kNoiseBlock != block) {
      block = k / kNoiseBlock;
      // Stream 0 builds scenes; the noise streams have bit 63 set, the block in bits 24–62.
      Rng rng(seed, (std::uint64_t{1} << 63) | (static_cast<std::uint64_t>(block) << 24) |
                        static_cast<std::uint64_t>(cell + 1));
      for (Vec3& x : xi) x = Vec3(rng.normal(), rng.normal(), rng.normal());
    }
    const double covered = std::min(u1, double(k + 1)) - std::max(u0, double(k));
    dw += covered * xi[k % kNoiseBlock];
  }
  return std::sqrt(kNoiseGridS) * dw;
}

Vec3 ActiveMigration::diffuse(const Vec3& p, double d_r, double t0, double t1, std::uint64_t seed,
                              int cell) {
  // Rotation vector ω = √(2 D_r) P⊥ ΔW, P⊥ the projection onto the tangent plane of p (the
  // part of ω along p does not turn p): an isotropic tangent step of variance 2 D_r Δt per
  // axis, so that ⟨p(t)·p(0)⟩ = exp(−2 D_r t) (to O((D_r Δt)²)).
  const Vec3 dw = wienerIncrement(seed, cell, t0, t1);
  const Vec3 w = std::sqrt(2 * d_r) * (dw - dw.dot(p) * p);
  const double angle = w.norm();
  if (angle == 0) return p;
  return (std::cos(angle) * p + std::sin(angle) * (w / angle)).normalized();
}

void ActiveMigration::endStep(const StepContext& ctx, CellSet& cells) const {
  for (int c = 0; c < cells.numCells(); ++c)
    cells.polarity[c] = diffuse(cells.polarity[c], d_r_, ctx.t, ctx.endTime(), seed_, c);
}

}  // namespace activefoam
