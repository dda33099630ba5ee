// The motion of one velocity solve taken apart (probe.h): each cell's affine part and the
// vertex-scale jitter (observe.dissipation), the cells' speeds, and the aggregate as a body
// with the torques its friction terms exert (observe.torque).
#include <cmath>
#include <limits>
#include <set>

#include "activefoam/contacts.h"
#include "activefoam/motility.h"
#include "activefoam/probe.h"
#include "activefoam/terms.h"

namespace activefoam {
namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

// Each cell's area-weighted mean velocity (its centroid's: the translation of its affine part).
std::vector<Vec3> cellVelocities(const CellSet& cells, const Geometry& geo,
                                 const Eigen::VectorXd& v) {
  const int nc = cells.numCells();
  std::vector<Vec3> vm(nc, Vec3::Zero());
  std::vector<double> w(nc, 0.0);
  for (int i = 0; i < cells.numVertices(); ++i) {
    const int c = cells.vertex_cell[i];
    vm[c] += geo.vertex_area[i] * v.segment<3>(3 * i);
    w[c] += geo.vertex_area[i];
  }
  for (int c = 0; c < nc; ++c) vm[c] /= w[c];
  return vm;
}

// The torque about `about` of a term's friction forces on v, Σ (x_i − about) × (Γ_term v)_i.
Vec3 frictionTorque(const ForceTerm& term, const StepContext& ctx, const Eigen::VectorXd& v,
                    const Vec3& about) {
  const Eigen::VectorXd y = frictionForce(term, ctx, v);
  Vec3 t = Vec3::Zero();
  for (int i = 0; i < ctx.cells.numVertices(); ++i)
    t += (Vec3(ctx.cells.x.col(i)) - about).cross(Vec3(y.segment<3>(3 * i)));
  return t;
}

}  // namespace

Eigen::VectorXd affinePart(const CellSet& cells, const Geometry& geo, const Eigen::VectorXd& v) {
  const int nc = cells.numCells(), nv = cells.numVertices();
  std::vector<Vec3> xm(nc, Vec3::Zero()), vm(nc, Vec3::Zero());
  std::vector<double> sw(nc, 0.0);
  for (int i = 0; i < nv; ++i) {
    const int c = cells.vertex_cell[i];
    const double w = geo.vertex_area[i];
    xm[c] += w * cells.x.col(i);
    vm[c] += w * v.segment<3>(3 * i);
    sw[c] += w;
  }
  for (int c = 0; c < nc; ++c) {
    xm[c] /= sw[c];
    vm[c] /= sw[c];
  }
  std::vector<Eigen::Matrix3d> xx(nc, Eigen::Matrix3d::Zero()), vx(nc, Eigen::Matrix3d::Zero());
  for (int i = 0; i < nv; ++i) {
    const int c = cells.vertex_cell[i];
    const double w = geo.vertex_area[i];
    const Vec3 dx = cells.x.col(i) - xm[c];
    xx[c] += w * dx * dx.transpose();
    vx[c] += w * (v.segment<3>(3 * i) - vm[c]) * dx.transpose();
  }
  std::vector<Eigen::Matrix3d> b(nc);
  for (int c = 0; c < nc; ++c) b[c] = vx[c] * xx[c].inverse();
  Eigen::VectorXd out(3 * nv);
  for (int i = 0; i < nv; ++i) {
    const int c = cells.vertex_cell[i];
    out.segment<3>(3 * i) = vm[c] + b[c] * (cells.x.col(i) - xm[c]);
  }
  return out;
}

Eigen::VectorXd ringJitter(const Topology& topo, const Eigen::VectorXd& v) {
  const Eigen::Index nv = v.size() / 3;
  Eigen::VectorXd sum = Eigen::VectorXd::Zero(v.size()), out = v;
  std::vector<int> count(static_cast<std::size_t>(nv), 0);
  for (const Edge& e : topo.edges) {
    sum.segment<3>(3 * e.i) += v.segment<3>(3 * e.j);
    sum.segment<3>(3 * e.j) += v.segment<3>(3 * e.i);
    ++count[e.i];
    ++count[e.j];
  }
  for (Eigen::Index i = 0; i < nv; ++i)
    if (count[i]) out.segment<3>(3 * i) -= sum.segment<3>(3 * i) / count[i];
  return out;
}

CellSpeeds cellSpeeds(const CellSet& cells, const Geometry& geo, const ContactList* contacts,
                      const Eigen::VectorXd& v) {
  const int nc = cells.numCells();
  const std::vector<Vec3> vc = cellVelocities(cells, geo, v);
  std::vector<std::set<int>> nb(nc);
  if (contacts)
    for (const ContactPair& p : contacts->pairs) {
      const int a = cells.tri_cell[p.ta], b = cells.tri_cell[p.tb];
      if (a == b) continue;
      nb[a].insert(b);
      nb[b].insert(a);
    }
  double v2 = 0, rel2 = 0;
  int rel_n = 0;
  for (int c = 0; c < nc; ++c) {
    v2 += vc[c].squaredNorm();
    if (nb[c].empty()) continue;
    Vec3 mean = Vec3::Zero();
    for (const int d : nb[c]) mean += vc[d];
    rel2 += (vc[c] - mean / static_cast<double>(nb[c].size())).squaredNorm();
    ++rel_n;
  }
  CellSpeeds s;
  s.rms_um_min = nc ? 60 * std::sqrt(v2 / nc) : kNaN;
  s.relative_rms_um_min = rel_n ? 60 * std::sqrt(rel2 / rel_n) : kNaN;
  return s;
}

CellScaleDissipation cellScaleDissipation(const StartSolve& s) {
  CellScaleDissipation d;
  const StepContext& ctx = s.ctx;
  const Eigen::VectorXd affine = affinePart(ctx.cells, ctx.geo, s.v);
  const Eigen::VectorXd jitter = ringJitter(ctx.topo, s.v);
  for (const auto& term : s.terms) {
    const ForceTerm& t = *term;
    if (dynamic_cast<const MediumDrag*>(&t)) {
      d.medium_affine += frictionPower(t, ctx, affine);
    } else if (dynamic_cast<const CortexViscosity*>(&t)) {
      d.cortex_affine += frictionPower(t, ctx, affine);
      d.cortex_jitter += frictionPower(t, ctx, jitter);
    } else if (const auto* cf = dynamic_cast<const ContactFriction*>(&t)) {
      using Part = ContactFriction::Part;
      d.friction_t_affine += frictionPower(cf->part(Part::Tangential), ctx, affine);
      d.friction_n_affine += frictionPower(cf->part(Part::Normal), ctx, affine);
    }
  }
  d.speeds = cellSpeeds(ctx.cells, ctx.geo, ctx.contacts, s.v);
  return d;
}

RigidPart rigidPart(const CellSet& cells, const Geometry& geo, const Eigen::VectorXd& v) {
  RigidPart r;
  double wsum = 0;
  const int nv = cells.numVertices();
  for (int i = 0; i < nv; ++i) {
    const double w = geo.vertex_area[i];
    r.centroid += w * cells.x.col(i);
    r.velocity += w * v.segment<3>(3 * i);
    wsum += w;
  }
  r.centroid /= wsum;
  r.velocity /= wsum;
  Eigen::Matrix3d inertia = Eigen::Matrix3d::Zero();
  Vec3 ang = Vec3::Zero();
  for (int i = 0; i < nv; ++i) {
    const double w = geo.vertex_area[i];
    const Vec3 rx = cells.x.col(i) - r.centroid;
    inertia += w * (rx.squaredNorm() * Eigen::Matrix3d::Identity() - rx * rx.transpose());
    ang += w * rx.cross(Vec3(v.segment<3>(3 * i)) - r.velocity);
  }
  r.spin = inertia.ldlt().solve(ang);
  return r;
}

BodyTorques bodyTorques(const StartSolve& s) {
  BodyTorques b;
  const StepContext& ctx = s.ctx;
  const RigidPart rigid = rigidPart(ctx.cells, ctx.geo, s.v);
  Vec3 force = Vec3::Zero(), torque = Vec3::Zero();
  for (int i = 0; i < ctx.cells.numVertices(); ++i) {
    force += s.f.col(i);
    torque += (Vec3(ctx.cells.x.col(i)) - rigid.centroid).cross(Vec3(s.f.col(i)));
  }
  b.net_force_nn = force.norm();
  b.net_torque_nnum = torque.norm();
  b.rigid_speed_um_h = 3600 * rigid.velocity.norm();
  b.rigid_spin_deg_h = 3600 * rigid.spin.norm() * 180 / M_PI;
  Vec3 medium = Vec3::Zero(), cortex = Vec3::Zero(), friction = Vec3::Zero(),
       springs = Vec3::Zero();
  for (const auto& term : s.terms) {
    const ForceTerm& t = *term;
    if (dynamic_cast<const MediumDrag*>(&t)) {
      medium += frictionTorque(t, ctx, s.v, rigid.centroid);
    } else if (dynamic_cast<const CortexViscosity*>(&t)) {
      cortex += frictionTorque(t, ctx, s.v, rigid.centroid);
    } else if (const auto* cf = dynamic_cast<const ContactFriction*>(&t)) {
      using Part = ContactFriction::Part;
      friction += frictionTorque(cf->part(Part::Tangential), ctx, s.v, rigid.centroid) +
                  frictionTorque(cf->part(Part::Normal), ctx, s.v, rigid.centroid);
      if (ctx.contact_stiffness_dt > 0)
        springs += frictionTorque(cf->part(Part::Springs), ctx, s.v, rigid.centroid);
    } else if (dynamic_cast<const SurfaceTension*>(&t) && ctx.tension_stiffness_dt > 0) {
      springs += frictionTorque(t, ctx, s.v, rigid.centroid);
    }
  }
  b.torque_medium_nnum = medium.norm();
  if (b.torque_medium_nnum > 0) {
    const Vec3 axis = medium / b.torque_medium_nnum;
    b.share_cortex = -cortex.dot(axis) / b.torque_medium_nnum;
    b.share_friction = -friction.dot(axis) / b.torque_medium_nnum;
    b.share_springs = -springs.dot(axis) / b.torque_medium_nnum;
  } else {
    b.share_cortex = b.share_friction = b.share_springs = kNaN;
  }
  return b;
}

}  // namespace activefoam
