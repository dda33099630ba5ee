// The CG solve of Γ v = F (S20): preconditioned conjugate gradients with a Jacobi, 3×3
// block-Jacobi or block incomplete-Cholesky preconditioner, warm-started from the previous
// velocities. Our own loop rather than Eigen's ConjugateGradient because a step's Γ is not one
// assembled matrix: the contact couplings are applied pair by pair
// (FrictionOperator, friction_operator.h). On an assembled matrix the two loops cost within 10 % of
// each other (2 × 100-cell reference scene).
#pragma once

#include <functional>
#include <vector>

#include <Eigen/Core>

#include "activefoam/block_matrix.h"
#include "activefoam/incomplete_cholesky.h"
#include "activefoam/spec_enums.h"

namespace activefoam {

struct SolveStats {
  int iterations = 0;
  double residual = 0;  // relative: |b − A x| / |b|
  bool converged = false;
};

class LinearSolver {
 public:
  LinearSolver(PreconditionerKind kind, double tol, int max_iter)
      : kind_(kind), tol_(tol), max_iter_(max_iter) {}
  // x holds the initial guess on entry and the solution on exit. Converged when
  // |b − A x| ≤ tol |b| (the same criterion as Eigen's ConjugateGradient).
  SolveStats solve(const BlockMatrix& a, const Eigen::VectorXd& b, Eigen::VectorXd& x);
  // A matrix given as a product y = A x whose diagonal blocks are those of `diagonal`. With
  // the incomplete-Cholesky kind, `factor` (built by the caller, who knows the couplings the
  // product applies) is the preconditioner and must be given.
  using Product = std::function<void(const double* x, double* y)>;
  SolveStats solve(const Product& a, const BlockMatrix& diagonal, const Eigen::VectorXd& b,
                   Eigen::VectorXd& x, const IncompleteCholesky* factor = nullptr);
  // The same on a plain symmetric sparse matrix of 3×3 blocks (tests, tools).
  SolveStats solve(const SpMat& a, const Eigen::VectorXd& b, Eigen::VectorXd& x);

 private:
  template <typename Multiply>
  SolveStats pcg(const Multiply& mul, const Eigen::VectorXd& b, Eigen::VectorXd& x);
  template <typename Multiply>
  SolveStats pcgWith(const IncompleteCholesky* factor, const Multiply& mul,
                     const Eigen::VectorXd& b, Eigen::VectorXd& x);
  void setPreconditioner(int block, const Eigen::Matrix3d& d);
  PreconditionerKind kind_;
  const IncompleteCholesky* factor_ = nullptr;  // during a solve with the IC kind
  IncompleteCholesky own_factor_;               // for the assembled-matrix overloads
  double tol_;
  int max_iter_;
  // Per 3×3 block: the inverse of the diagonal block (block-Jacobi) or of its diagonal (Jacobi).
  std::vector<Eigen::Matrix3d> inv_;
  Eigen::VectorXd r_, z_, p_, q_;
};

}  // namespace activefoam
