#include "activefoam/solver.h"

#include <Eigen/Cholesky>
#include <cmath>
#include <limits>

namespace activefoam {

void LinearSolver::setPreconditioner(int block, const Eigen::Matrix3d& d) {
  Eigen::Matrix3d inv = Eigen::Matrix3d::Zero();
  if (kind_ == PreconditionerKind::BlockJacobi) {
    // Diagonal blocks of an SPD matrix are SPD; LDLT stays safe if one is near singular.
    inv = d.ldlt().solve(Eigen::Matrix3d::Identity());
  } else {
    for (int k = 0; k < 3; ++k) inv(k, k) = d(k, k) != 0 ? 1 / d(k, k) : 1;
  }
  inv_[block] = inv;
}

template <typename Multiply>
SolveStats LinearSolver::pcg(const Multiply& mul, const Eigen::VectorXd& b, Eigen::VectorXd& x) {
  SolveStats s;
  const Eigen::Index n = b.size(), nb = n / 3;
  const double bnorm2 = b.squaredNorm();
  if (bnorm2 == 0) {
    x.setZero();
    s.converged = true;
    return s;
  }
  const double threshold = std::max(tol_ * tol_ * bnorm2, std::numeric_limits<double>::min());
  r_.resize(n);
  z_.resize(n);
  p_.resize(n);
  q_.resize(n);
  mul(x.data(), q_.data());
  r_ = b - q_;
  double rr = r_.squaredNorm();
  auto precondition = [&] {  // z = M⁻¹ r; returns r·z
    double rz = 0;
    for (Eigen::Index i = 0; i < nb; ++i) {
      const Eigen::Vector3d zi = inv_[i] * r_.segment<3>(3 * i);
      z_.segment<3>(3 * i) = zi;
      rz += zi.dot(r_.segment<3>(3 * i));
    }
    return rz;
  };
  if (rr >= threshold) {
    double rz = precondition();
    p_ = z_;
    while (s.iterations < max_iter_) {
      mul(p_.data(), q_.data());
      const double alpha = rz / p_.dot(q_);
      rr = 0;
      for (Eigen::Index k = 0; k < n; ++k) {
        x[k] += alpha * p_[k];
        r_[k] -= alpha * q_[k];
        rr += r_[k] * r_[k];
      }
      ++s.iterations;
      if (rr < threshold) break;
      const double rz_new = precondition();
      const double beta = rz_new / rz;
      rz = rz_new;
      for (Eigen::Index k = 0; k < n; ++k) p_[k] = z_[k] + beta * p_[k];
    }
  }
  s.residual = std::sqrt(rr / bnorm2);
  s.converged = rr < threshold;
  return s;
}

SolveStats LinearSolver::solve(const BlockMatrix& a, const Eigen::VectorXd& b, Eigen::VectorXd& x) {
  return solve([&](const double* in, double* out) { a.multiply(in, out); }, a, b, x);
}

SolveStats LinearSolver::solve(const Product& a, const BlockMatrix& diagonal,
                               const Eigen::VectorXd& b, Eigen::VectorXd& x) {
  inv_.resize(diagonal.numBlocks());
  for (int i = 0; i < diagonal.numBlocks(); ++i) setPreconditioner(i, diagonal.diagonalBlock(i));
  return pcg(a, b, x);
}

SolveStats LinearSolver::solve(const SpMat& a, const Eigen::VectorXd& b, Eigen::VectorXd& x) {
  const Eigen::Index nb = a.rows() / 3;
  inv_.resize(nb);
  for (Eigen::Index i = 0; i < nb; ++i) {
    Eigen::Matrix3d d = Eigen::Matrix3d::Zero();
    for (int r = 0; r < 3; ++r)
      for (SpMat::InnerIterator it(a, 3 * i + r); it; ++it)
        if (it.col() >= 3 * i && it.col() < 3 * i + 3) d(r, it.col() - 3 * i) = it.value();
    setPreconditioner(static_cast<int>(i), d);
  }
  return pcg(
      [&](const double* in, double* out) {
        Eigen::Map<Eigen::VectorXd>(out, a.rows()) =
            a * Eigen::Map<const Eigen::VectorXd>(in, a.cols());
      },
      b, x);
}

}  // namespace activefoam
