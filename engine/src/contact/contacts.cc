#include "activefoam/contacts.h"

#include <algorithm>
#include <cmath>

#include "activefoam/rng.h"

namespace activefoam {

void detectContacts(const CellSet& cells, const Geometry& geo, const ContactLaw& law,
                    ContactQuadrature quadrature, ContactList& out) {
  const int nt = cells.numTriangles();
  out.pairs.clear();
  out.tri_contact_area.assign(nt, 0.0);
  out.tri_contact_fraction.assign(nt, 0.0);
  out.vertex_contact_area.assign(cells.numVertices(), 0.0);
  out.cell_contact_area.assign(cells.numCells(), 0.0);
  if (cells.numCells() < 2) return;
  const auto candidates = findContactCandidates(cells.x, cells.tri, cells.tri_cell, law.h0);
  auto corners = [&](int t) {
    const Tri& f = cells.tri[t];
    return std::array<Vec3, 3>{cells.x.col(f[0]), cells.x.col(f[1]), cells.x.col(f[2])};
  };
  for (const auto& [ta, tb] : candidates) {
    TriangleContact c = computeTriangleContact(corners(ta), corners(tb), law, quadrature);
    if (!c.active) continue;
    out.tri_contact_area[ta] += c.area;
    out.tri_contact_area[tb] += c.area;
    out.pairs.push_back({ta, tb, c});
  }
  for (int t = 0; t < nt; ++t) {
    if (out.tri_contact_area[t] <= 0) continue;
    const double f = std::min(1.0, out.tri_contact_area[t] / geo.tri_area[t]);
    out.tri_contact_fraction[t] = f;
    const double a = f * geo.tri_area[t];
    for (int k = 0; k < 3; ++k) out.vertex_contact_area[cells.tri[t][k]] += a / 3.0;
    out.cell_contact_area[cells.tri_cell[t]] += a;
  }
}

double ContactAdhesion::addForces(const StepContext& ctx, Eigen::Matrix3Xd& f) const {
  if (!ctx.contacts) return 0;
  double energy = 0;
  for (const ContactPair& p : ctx.contacts->pairs) {
    const Tri& a = ctx.cells.tri[p.ta];
    const Tri& b = ctx.cells.tri[p.tb];
    for (int k = 0; k < 3; ++k) {
      f.col(a[k]) += p.c.force_weight_a[k] * p.c.normal;
      f.col(b[k]) -= p.c.force_weight_b[k] * p.c.normal;
    }
    energy += p.c.energy;
  }
  return energy;
}

void ContactFriction::addFriction(const StepContext& ctx, BlockMatrix& gamma) const {
  if (!ctx.contacts) return;
  for (const ContactPair& p : ctx.contacts->pairs) {
    const Vec3& n = p.c.normal;
    const Eigen::Matrix3d nn = n * n.transpose();
    const Eigen::Matrix3d g =
        p.c.area * ((xi_n_ + implicit_dt_ * k_) * nn + xi_t_ * (Eigen::Matrix3d::Identity() - nn));
    const Tri& a = ctx.cells.tri[p.ta];
    const Tri& b = ctx.cells.tri[p.tb];
    for (int i = 0; i < 3; ++i)
      for (int k = 0; k < 3; ++k) {
        const double w = p.c.bary_a[i] * p.c.bary_b[k];
        if (w > 0) gamma.addCoupling(a[i], b[k], w * g);
      }
  }
}

double ActiveMigration::addForces(const StepContext& ctx, Eigen::Matrix3Xd& f) const {
  if (!ctx.contacts || p_a_ == 0) return 0;
  const CellSet& cells = ctx.cells;
  const ContactList& con = *ctx.contacts;
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

Vec3 ActiveMigration::diffuse(const Vec3& p, double d_r, double dt, std::uint64_t seed, int cell,
                              std::int64_t step) {
  // Stream 0 builds scenes; polarity streams are keyed by (cell, step).
  Rng rng(seed, (static_cast<std::uint64_t>(step) << 24) ^ static_cast<std::uint64_t>(cell + 1));
  // Tangent basis (e1, e2) ⟂ p; rotation vector ω = √(2 D_r dt) (ξ1 e1 + ξ2 e2), so that
  // ⟨p(t)·p(0)⟩ = exp(−2 D_r t) (to O((D_r dt)²)).
  const Vec3 e1 = p.unitOrthogonal(), e2 = p.cross(e1);
  const double s = std::sqrt(2 * d_r * dt);
  const Vec3 w = s * (rng.normal() * e1 + rng.normal() * e2);
  const double angle = w.norm();
  if (angle == 0) return p;
  return (std::cos(angle) * p + std::sin(angle) * (w / angle)).normalized();
}

void ActiveMigration::endStep(const StepContext& ctx, CellSet& cells) const {
  for (int c = 0; c < cells.numCells(); ++c)
    cells.polarity[c] = diffuse(cells.polarity[c], d_r_, ctx.dt, seed_, c, ctx.step);
}

}  // namespace activefoam
