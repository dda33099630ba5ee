#include "activefoam/solver.h"

#include <Eigen/Cholesky>

namespace activefoam {

BlockJacobiPreconditioner& BlockJacobiPreconditioner::factorize(const SpMat& m) {
  const Eigen::Index n = m.rows() / 3;
  inv_.assign(n, Eigen::Matrix3d::Zero());
  for (Eigen::Index i = 0; i < n; ++i) {
    Eigen::Matrix3d d = Eigen::Matrix3d::Zero();
    for (int r = 0; r < 3; ++r)
      for (SpMat::InnerIterator it(m, 3 * i + r); it; ++it)
        if (it.col() >= 3 * i && it.col() < 3 * i + 3) d(r, it.col() - 3 * i) = it.value();
    // Diagonal blocks of an SPD matrix are SPD; LDLT keeps this safe if one is near singular.
    inv_[i] = d.ldlt().solve(Eigen::Matrix3d::Identity());
  }
  return *this;
}

SolveStats LinearSolver::solve(const SpMat& a, const Eigen::VectorXd& b, Eigen::VectorXd& x) {
  SolveStats s;
  const double bnorm = b.norm();
  if (bnorm == 0) {
    x.setZero();
    s.converged = true;
    return s;
  }
  auto run = [&](auto& cg) {
    cg.setTolerance(tol_);
    cg.setMaxIterations(max_iter_);
    cg.compute(a);
    x = cg.solveWithGuess(b, x);
    s.iterations = static_cast<int>(cg.iterations());
    s.residual = cg.error();
    s.converged = cg.info() == Eigen::Success;
  };
  if (kind_ == PreconditionerKind::BlockJacobi)
    run(block_);
  else
    run(jacobi_);
  return s;
}

}  // namespace activefoam
