// observe.shape's measures of the cells (probe.h): the shape index at the cells' scale, the
// elongation, and the shape index's regression on the contact fraction over the cells.
#include <Eigen/Eigenvalues>
#include <cmath>
#include <limits>
#include <stdexcept>

#include "activefoam/observables.h"
#include "activefoam/probe.h"

namespace activefoam {

CellSet taubinSmoothed(const CellSet& cells, const Topology& topo, int passes) {
  CellSet out = cells;
  const int nv = cells.numVertices();
  Eigen::Matrix3Xd sum(3, nv);
  std::vector<int> count(static_cast<std::size_t>(nv));
  for (int p = 0; p < 2 * passes; ++p) {
    const double f = (p % 2 == 0) ? kTaubinLambda : kTaubinMu;
    sum.setZero();
    std::fill(count.begin(), count.end(), 0);
    for (const Edge& e : topo.edges) {
      sum.col(e.i) += out.x.col(e.j);
      sum.col(e.j) += out.x.col(e.i);
      ++count[e.i];
      ++count[e.j];
    }
    for (int i = 0; i < nv; ++i)
      if (count[i]) out.x.col(i) += f * (sum.col(i) / count[i] - out.x.col(i));
  }
  return out;
}

double surfaceElongation(const CellSet& cells, const Geometry& geo, int c) {
  Eigen::Matrix3d m = Eigen::Matrix3d::Zero();
  double w = 0;
  for (int i = cells.cell_vertex_begin[c]; i < cells.cell_vertex_begin[c + 1]; ++i) {
    const Vec3 d = cells.x.col(i) - geo.cell_centroid[c];
    m += geo.vertex_area[i] * d * d.transpose();
    w += geo.vertex_area[i];
  }
  const Eigen::Vector3d ev = Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(m / w).eigenvalues();
  return std::sqrt(ev(2) / ev(0));
}

LineFit lineFit(const std::vector<double>& x, const std::vector<double>& y) {
  if (x.size() != y.size()) throw std::invalid_argument("lineFit: as many x as y");
  constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
  LineFit fit{kNaN, kNaN, kNaN};
  const double n = static_cast<double>(x.size());
  if (x.size() < 2) return fit;
  double mx = 0, my = 0;
  for (std::size_t k = 0; k < x.size(); ++k) {
    mx += x[k];
    my += y[k];
  }
  mx /= n;
  my /= n;
  double sxx = 0, syy = 0, sxy = 0;
  for (std::size_t k = 0; k < x.size(); ++k) {
    sxx += (x[k] - mx) * (x[k] - mx);
    syy += (y[k] - my) * (y[k] - my);
    sxy += (x[k] - mx) * (y[k] - my);
  }
  if (!(sxx > 0)) return fit;  // one x: no line
  fit.slope = sxy / sxx;
  fit.intercept = my - fit.slope * mx;
  if (syy > 0) fit.r = sxy / std::sqrt(sxx * syy);
  return fit;
}

CellShapes cellShapes(const CellSet& cells, const Geometry& geo, const ContactList& contacts,
                      const Topology& topo) {
  const int nc = cells.numCells();
  CellShapes out;
  Geometry smooth_geo;
  computeGeometry(taubinSmoothed(cells, topo), smooth_geo);
  const std::vector<double> free = freeFractions(geo, contacts);
  for (int c = 0; c < nc; ++c) {
    out.shape_index.push_back(shapeIndex(geo, c));
    out.shape_index_smoothed.push_back(shapeIndex(smooth_geo, c));
    out.elongation.push_back(surfaceElongation(cells, geo, c));
    out.contact_fraction.push_back(1.0 - free[c]);
  }
  return out;
}

}  // namespace activefoam
