// The motion of one velocity solve taken apart (probe.h): each cell's affine part, the
// vertex-scale jitter and the cells' speeds (observe.dissipation).
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

}  // namespace activefoam
