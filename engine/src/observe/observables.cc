#include "activefoam/observables.h"

#include <algorithm>
#include <cmath>

#include <Eigen/Dense>

namespace activefoam {

double aspectRatio(const CellSet& cells, int c) {
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es(cellCovariance(cells, c));
  const auto ev = es.eigenvalues();  // ascending
  return std::sqrt(ev(2) / std::max(ev(0), 1e-300));
}

SphereFit fitSphere(const Eigen::Matrix3Xd& p) {
  SphereFit fit;
  const Eigen::Index n = p.cols();
  if (n < 4) return fit;
  // |x − o|² = 2 c'·(x − o) + k with c' = c − o: linear in (c', k); o = mean for conditioning.
  const Vec3 o = p.rowwise().mean();
  Eigen::MatrixXd a(n, 4);
  Eigen::VectorXd b(n);
  for (Eigen::Index i = 0; i < n; ++i) {
    const Vec3 d = p.col(i) - o;
    a.row(i) << 2 * d.x(), 2 * d.y(), 2 * d.z(), 1.0;
    b(i) = d.squaredNorm();
  }
  const Eigen::Vector4d s = a.colPivHouseholderQr().solve(b);
  const Vec3 c = s.head<3>();
  const double r2 = s(3) + c.squaredNorm();
  if (!(r2 > 0)) return fit;
  fit.centre = o + c;
  fit.radius = std::sqrt(r2);
  double ss = 0;
  for (Eigen::Index i = 0; i < n; ++i) {
    const double e = (p.col(i) - fit.centre).norm() - fit.radius;
    ss += e * e;
  }
  fit.rms = std::sqrt(ss / static_cast<double>(n));
  fit.ok = true;
  return fit;
}

double doubletContactAngleDeg(const CellSet& cells, const ContactList& contacts) {
  if (cells.numCells() < 2 || contacts.pairs.empty()) return 0;
  SphereFit fit[2];
  Vec3 contact_sum = Vec3::Zero();
  int contact_n = 0;
  for (int c = 0; c < 2; ++c) {
    std::vector<int> free;
    for (int i = cells.cell_vertex_begin[c]; i < cells.cell_vertex_begin[c + 1]; ++i) {
      if (contacts.vertex_contact_area[i] > 0) {
        contact_sum += cells.x.col(i);
        ++contact_n;
      } else {
        free.push_back(i);
      }
    }
    Eigen::Matrix3Xd pts(3, static_cast<Eigen::Index>(free.size()));
    for (size_t k = 0; k < free.size(); ++k)
      pts.col(static_cast<Eigen::Index>(k)) = cells.x.col(free[k]);
    fit[c] = fitSphere(pts);
    if (!fit[c].ok) return 0;
  }
  if (contact_n == 0) return 0;
  const Vec3 p = contact_sum / contact_n;
  const Vec3 axis = (fit[1].centre - fit[0].centre).normalized();
  const double h0 = (p - fit[0].centre).dot(axis);  // towards cell 1
  const double h1 = (fit[1].centre - p).dot(axis);  // towards cell 0
  auto angle = [](double h, double r) { return std::acos(std::clamp(h / r, -1.0, 1.0)); };
  return 0.5 * (angle(h0, fit[0].radius) + angle(h1, fit[1].radius)) * 180.0 / M_PI;
}

}  // namespace activefoam
