#include "activefoam/contacts.h"

#include <algorithm>

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

}  // namespace activefoam
