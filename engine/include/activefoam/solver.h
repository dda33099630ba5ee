// The CG solve of Γ v = F (S20): Eigen's ConjugateGradient with a Jacobi or 3×3 block-Jacobi
// preconditioner, warm-started from the previous velocities.
#pragma once

#include <vector>

#include <Eigen/Core>
#include <Eigen/IterativeLinearSolvers>

#include "activefoam/block_matrix.h"
#include "activefoam/spec.h"

namespace activefoam {

// Inverts the 3×3 diagonal blocks of a block matrix (Eigen preconditioner concept).
class BlockJacobiPreconditioner {
 public:
  using Vector = Eigen::VectorXd;
  BlockJacobiPreconditioner() = default;
  template <typename MatType>
  explicit BlockJacobiPreconditioner(const MatType& m) {
    compute(m);
  }
  Eigen::Index rows() const { return 3 * static_cast<Eigen::Index>(inv_.size()); }
  Eigen::Index cols() const { return rows(); }
  template <typename MatType>
  BlockJacobiPreconditioner& analyzePattern(const MatType&) {
    return *this;
  }
  BlockJacobiPreconditioner& factorize(const SpMat& m);
  BlockJacobiPreconditioner& compute(const SpMat& m) { return factorize(m); }
  template <typename Rhs>
  Vector solve(const Rhs& b) const {
    Vector x(b.size());
    for (size_t i = 0; i < inv_.size(); ++i)
      x.template segment<3>(3 * i) = inv_[i] * b.template segment<3>(3 * i);
    return x;
  }
  Eigen::ComputationInfo info() const { return Eigen::Success; }

 private:
  std::vector<Eigen::Matrix3d> inv_;
};

struct SolveStats {
  int iterations = 0;
  double residual = 0;  // relative: |b − A x| / |b|
  bool converged = false;
};

class LinearSolver {
 public:
  LinearSolver(PreconditionerKind kind, double tol, int max_iter)
      : kind_(kind), tol_(tol), max_iter_(max_iter) {}
  // x holds the initial guess on entry and the solution on exit.
  SolveStats solve(const SpMat& a, const Eigen::VectorXd& b, Eigen::VectorXd& x);

 private:
  PreconditionerKind kind_;
  double tol_;
  int max_iter_;
  Eigen::ConjugateGradient<SpMat, Eigen::Lower | Eigen::Upper,
                           Eigen::DiagonalPreconditioner<double>>
      jacobi_;
  Eigen::ConjugateGradient<SpMat, Eigen::Lower | Eigen::Upper, BlockJacobiPreconditioner> block_;
};

}  // namespace activefoam
