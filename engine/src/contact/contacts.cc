#include "activefoam/contacts.h"

#include <algorithm>
#include <cmath>

#include "activefoam/rng.h"

namespace activefoam {

void detectContacts(const CellSet& cells, const Geometry& geo, const ContactLaw& law,
                    ContactQuadrature quadrature, ContactList& out, CandidateCache* cache) {
  const int nt = cells.numTriangles();
  out.pairs.clear();
  out.tri_contact_area.assign(nt, 0.0);
  out.tri_contact_fraction.assign(nt, 0.0);
  out.vertex_contact_area.assign(cells.numVertices(), 0.0);
  out.cell_contact_area.assign(cells.numCells(), 0.0);
  if (cells.numCells() < 2) return;
  const auto candidates = cache ? cache->find(cells, law.h0)
                                : findContactCandidates(cells.x, cells.tri, cells.tri_cell, law.h0);
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

Eigen::Matrix3d ContactFriction::pairMatrix(const ContactPair& p, double stiffness_dt) const {
  const Vec3& n = p.c.normal;
  const Eigen::Matrix3d nn = n * n.transpose();
  return p.c.area * ((xi_n_ + stiffness_dt * k_) * nn + xi_t_ * (Eigen::Matrix3d::Identity() - nn));
}

void ContactFriction::addFrictionDiagonal(const StepContext& ctx, BlockMatrix& gamma) const {
  ops_.clear();
  if (!ctx.contacts) return;
  ops_.reserve(ctx.contacts->pairs.size());
  for (const ContactPair& p : ctx.contacts->pairs) {
    // Σ_k w_ik G = λ_i^A (Σ_k λ_k^B) G on vertex i of A, and the same for B.
    const Eigen::Matrix3d g = pairMatrix(p, ctx.contact_stiffness_dt);
    const Tri& a = ctx.cells.tri[p.ta];
    const Tri& b = ctx.cells.tri[p.tb];
    const double sa = p.c.bary_a[0] + p.c.bary_a[1] + p.c.bary_a[2];
    const double sb = p.c.bary_b[0] + p.c.bary_b[1] + p.c.bary_b[2];
    PairOp op;
    for (int i = 0; i < 3; ++i) {
      op.a[i] = a[i];
      op.b[i] = b[i];
      op.wa[i] = p.c.bary_a[i];
      op.wb[i] = p.c.bary_b[i];
      if (op.wa[i] > 0) gamma.addDiagonal(a[i], (op.wa[i] * sb) * g);
      if (op.wb[i] > 0) gamma.addDiagonal(b[i], (op.wb[i] * sa) * g);
    }
    op.s = p.c.area * xi_t_;
    op.d = p.c.area * (xi_n_ + ctx.contact_stiffness_dt * k_ - xi_t_);
    for (int k = 0; k < 3; ++k) op.n[k] = p.c.normal[k];
    ops_.push_back(op);
  }
}

void ContactFriction::addCouplingProduct(const double* v, double* y) const {
  // The off-diagonal blocks −w_ik G: vertex i of A gets −λ_i^A G u_B with u_B = Σ_k λ_k^B v_k.
  for (const PairOp& op : ops_) {
    double ua[3] = {0, 0, 0}, ub[3] = {0, 0, 0};
    for (int i = 0; i < 3; ++i)
      for (int c = 0; c < 3; ++c) {
        ua[c] += op.wa[i] * v[3 * op.a[i] + c];
        ub[c] += op.wb[i] * v[3 * op.b[i] + c];
      }
    const double na = op.n[0] * ua[0] + op.n[1] * ua[1] + op.n[2] * ua[2];
    const double nb = op.n[0] * ub[0] + op.n[1] * ub[1] + op.n[2] * ub[2];
    double ga[3], gb[3];  // G u_A, G u_B
    for (int c = 0; c < 3; ++c) {
      ga[c] = op.s * ua[c] + op.d * na * op.n[c];
      gb[c] = op.s * ub[c] + op.d * nb * op.n[c];
    }
    for (int i = 0; i < 3; ++i)
      for (int c = 0; c < 3; ++c) {
        y[3 * op.a[i] + c] -= op.wa[i] * gb[c];
        y[3 * op.b[i] + c] -= op.wb[i] * ga[c];
      }
  }
}

void ContactFriction::addFriction(const StepContext& ctx, BlockMatrix& gamma) const {
  if (!ctx.contacts) return;
  for (const ContactPair& p : ctx.contacts->pairs) {
    const Eigen::Matrix3d g = pairMatrix(p, ctx.contact_stiffness_dt);
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
