// The assembled friction matrix and the CG solve.
#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <Eigen/SparseCholesky>

#include "test_support.h"

using namespace activefoam;
using activefoam::testing::cellSpec;
using activefoam::testing::jiggle;

TEST(BlockMatrix, MatchesDenseAssembly) {
  BlockMatrix b;
  b.setPattern(4, {{0, 1}, {1, 2}, {2, 3}, {3, 0}, {1, 0}});
  Eigen::MatrixXd dense = Eigen::MatrixXd::Zero(12, 12);
  Rng rng(3, 1);
  auto randm = [&] {
    Eigen::Matrix3d m;
    for (int i = 0; i < 9; ++i) m(i) = rng.uniform();
    return Eigen::Matrix3d(m * m.transpose());
  };
  for (auto [i, j] : std::vector<std::pair<int, int>>{{0, 1}, {1, 2}, {3, 0}}) {
    const Eigen::Matrix3d m = randm();
    b.addCoupling(i, j, m);
    dense.block<3, 3>(3 * i, 3 * i) += m;
    dense.block<3, 3>(3 * j, 3 * j) += m;
    dense.block<3, 3>(3 * i, 3 * j) -= m;
    dense.block<3, 3>(3 * j, 3 * i) -= m;
  }
  const Eigen::Matrix3d d = randm();
  b.addDiagonal(2, d);
  dense.block<3, 3>(6, 6) += d;
  EXPECT_LT((Eigen::MatrixXd(b.matrix()) - dense).norm(), 1e-14);
  // The block product and the diagonal blocks the preconditioner reads.
  Eigen::VectorXd x(12), y(12);
  for (int i = 0; i < 12; ++i) x[i] = rng.uniform() - 0.5;
  b.multiply(x.data(), y.data());
  EXPECT_LT((y - dense * x).norm(), 1e-14 * (dense * x).norm());
  for (int i = 0; i < 4; ++i)
    EXPECT_EQ(b.diagonalBlock(i), Eigen::Matrix3d(dense.block<3, 3>(3 * i, 3 * i)));
  EXPECT_THROW(b.addCoupling(0, 2, d), std::logic_error);  // outside the pattern
  b.setZero();
  EXPECT_EQ(Eigen::MatrixXd(b.matrix()).norm(), 0.0);
}

TEST(FrictionMatrix, IsSymmetricPositiveDefinite) {
  for (int tris : {80, 320}) {
    SceneSpec s = cellSpec(1.3, tris);
    CellSet cells = buildScene(s);
    jiggle(cells, 0.3, 11);
    Simulation sim(s, cells);
    const Eigen::MatrixXd a = Eigen::MatrixXd(sim.assembleFriction());
    EXPECT_LT((a - a.transpose()).norm(), 1e-12 * a.norm());
    Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> es(a, Eigen::EigenvaluesOnly);
    EXPECT_GT(es.eigenvalues().minCoeff(), 0.0) << tris << " triangles";
    // The smallest eigenvalue comes from the medium drag on rigid motions: a genuine lower bound.
    const double drag = 1.5 * s.cells.eta_m / s.cells.radius_mean_um;
    const double smin_area =
        *std::min_element(sim.geometry().vertex_area.begin(), sim.geometry().vertex_area.end());
    EXPECT_GE(es.eigenvalues().minCoeff(), 0.99 * drag * smin_area);
  }
}

TEST(Solver, ConjugateGradientMatchesDirectSolve) {
  SceneSpec s = cellSpec(1.3, 80);
  CellSet cells = buildScene(s);
  jiggle(cells, 0.3, 12);
  for (auto pre : {PreconditionerKind::Jacobi, PreconditionerKind::BlockJacobi}) {
    s.numerics.preconditioner = pre;
    Simulation sim(s, cells);
    Eigen::Matrix3Xd f;
    sim.computeForces(f);
    const SpMat a = sim.assembleFriction();
    sim.prepareFriction();
    const Eigen::VectorXd b = Eigen::Map<const Eigen::VectorXd>(f.data(), f.size());
    Eigen::SimplicialLDLT<SpMat> ldlt(a);
    ASSERT_EQ(ldlt.info(), Eigen::Success);
    const Eigen::VectorXd direct = ldlt.solve(b);
    for (double tol : {1e-3, 1e-10}) {
      LinearSolver cg(pre, tol, 10000);
      Eigen::VectorXd v = Eigen::VectorXd::Zero(b.size());
      const SolveStats st = cg.solve(a, b, v);
      EXPECT_TRUE(st.converged);
      // CG's contract: the relative residual is within the tolerance ...
      EXPECT_LE((a * v - b).norm() / b.norm(), tol * 1.0001);
      // ... and the error in the energy norm is bounded by it (cond(Γ) times the residual).
      if (tol < 1e-6) {
        EXPECT_LT((v - direct).norm() / direct.norm(), 1e-7);
      }
      // The block-wise product (what a step uses) takes the same path to the same answer.
      Eigen::VectorXd w = Eigen::VectorXd::Zero(b.size());
      const SolveStats sb = cg.solve(sim.frictionMatrix(), b, w);
      EXPECT_EQ(sb.iterations, st.iterations);
      EXPECT_LT((w - v).norm(), 1e-9 * v.norm());
    }
  }
}

TEST(Solver, WarmStartFromTheSolutionNeedsNoIterations) {
  SceneSpec s = cellSpec(1.3, 80);
  Simulation sim(s);
  Eigen::Matrix3Xd f;
  sim.computeForces(f);
  const SpMat a = sim.assembleFriction();
  sim.prepareFriction();
  const Eigen::VectorXd b = Eigen::Map<const Eigen::VectorXd>(f.data(), f.size());
  LinearSolver cg(PreconditionerKind::Jacobi, 1e-6, 1000);
  Eigen::VectorXd v = Eigen::VectorXd::Zero(b.size());
  const SolveStats cold = cg.solve(a, b, v);
  const SolveStats warm = cg.solve(a, b, v);
  EXPECT_GT(cold.iterations, 3);
  EXPECT_EQ(warm.iterations, 0);
  // Block-Jacobi is exact on the 3×3 diagonal blocks, so it needs fewer iterations than Jacobi.
  LinearSolver block(PreconditionerKind::BlockJacobi, 1e-6, 1000);
  Eigen::VectorXd w = Eigen::VectorXd::Zero(b.size());
  const SolveStats blocked = block.solve(sim.frictionMatrix(), b, w);
  EXPECT_TRUE(blocked.converged);
  EXPECT_LT(blocked.iterations, cold.iterations);
}

namespace {

// A random SPD block-tridiagonal matrix (a chain of n vertices): IC(0) has no fill to drop on
// it in the natural order, so the incomplete factor is the exact Cholesky factor.
Eigen::MatrixXd blockChain(int n, Rng& rng) {
  Eigen::MatrixXd a = Eigen::MatrixXd::Zero(3 * n, 3 * n);
  for (int i = 0; i < n; ++i) {
    Eigen::Matrix3d m;
    for (int k = 0; k < 9; ++k) m(k) = rng.uniform() - 0.5;
    a.block<3, 3>(3 * i, 3 * i) += m * m.transpose() + 0.1 * Eigen::Matrix3d::Identity();
    if (i + 1 < n) {
      Eigen::Matrix3d c;
      for (int k = 0; k < 9; ++k) c(k) = 0.3 * (rng.uniform() - 0.5);
      a.block<3, 3>(3 * i, 3 * i + 3) = c;
      a.block<3, 3>(3 * i + 3, 3 * i) = c.transpose();
      a.block<3, 3>(3 * i, 3 * i) += 0.5 * Eigen::Matrix3d::Identity();
      a.block<3, 3>(3 * i + 3, 3 * i + 3) += 0.5 * Eigen::Matrix3d::Identity();
    }
  }
  return a;
}

}  // namespace

TEST(IncompleteCholesky, IsTheExactFactorWhereNothingFillsIn) {
  Rng rng(17, 1);
  const int n = 40;
  const Eigen::MatrixXd a = blockChain(n, rng);
  ASSERT_EQ(Eigen::LLT<Eigen::MatrixXd>(a).info(), Eigen::Success);
  IncompleteCholesky ic;
  // Upper blocks given as (i, i+1), i.e. above the diagonal: the factor transposes them.
  ASSERT_TRUE(ic.factor(n, [&](const BlockSink& sink) {
    for (int i = 0; i < n; ++i) {
      sink(i, i, a.block<3, 3>(3 * i, 3 * i));
      if (i + 1 < n) sink(i, i + 1, a.block<3, 3>(3 * i, 3 * i + 3));
    }
  }));
  EXPECT_EQ(ic.shift(), 0);
  Eigen::VectorXd x(3 * n), z(3 * n);
  for (Eigen::Index k = 0; k < x.size(); ++k) x[k] = rng.uniform() - 0.5;
  const Eigen::VectorXd r = a * x;
  ic.apply(r.data(), z.data());
  EXPECT_LT((z - x).norm(), 1e-12 * x.norm());
  // One CG iteration then solves the system exactly.
  const SpMat sparse = a.sparseView();
  Eigen::VectorXd v = Eigen::VectorXd::Zero(3 * n);
  const SolveStats s =
      LinearSolver(PreconditionerKind::IncompleteCholesky, 1e-10, 100).solve(sparse, r, v);
  EXPECT_TRUE(s.converged);
  EXPECT_LE(s.iterations, 2);
}

TEST(IncompleteCholesky, SumsRepeatedBlocksAndDropsOnlyTheFill) {
  // A cycle of 6 vertices: eliminating vertex 0 fills (1, 5), outside the pattern, so the
  // factor is approximate — but split and repeated blocks must give the same factor as whole
  // ones, and it must still precondition CG to the exact solution.
  Rng rng(17, 2);
  const int n = 6;
  Eigen::MatrixXd a = Eigen::MatrixXd::Zero(3 * n, 3 * n);
  for (int i = 0; i < n; ++i) {
    const int j = (i + 1) % n;
    Eigen::Matrix3d m;
    for (int k = 0; k < 9; ++k) m(k) = rng.uniform() - 0.5;
    const Eigen::Matrix3d c = m * m.transpose() + 0.2 * Eigen::Matrix3d::Identity();
    a.block<3, 3>(3 * i, 3 * i) += c;
    a.block<3, 3>(3 * j, 3 * j) += c;
    a.block<3, 3>(3 * i, 3 * j) -= c;
    a.block<3, 3>(3 * j, 3 * i) -= c;
    a.block<3, 3>(3 * i, 3 * i) += 0.05 * Eigen::Matrix3d::Identity();
  }
  IncompleteCholesky whole, split;
  ASSERT_TRUE(whole.factor(n, [&](const BlockSink& sink) {
    for (int i = 0; i < n; ++i)
      for (int j = 0; j <= i; ++j)
        if (a.block<3, 3>(3 * i, 3 * j).norm() > 0) sink(i, j, a.block<3, 3>(3 * i, 3 * j));
  }));
  ASSERT_TRUE(split.factor(n, [&](const BlockSink& sink) {
    for (int i = n - 1; i >= 0; --i)  // another order, halves (exact in binary), transposes
      for (int j = i; j < n; ++j)
        if (a.block<3, 3>(3 * i, 3 * j).norm() > 0) {
          const Eigen::Matrix3d half = 0.5 * a.block<3, 3>(3 * i, 3 * j);
          sink(i, j, half);
          sink(j, i, half.transpose());
        }
  }));
  EXPECT_EQ(whole.numStoredBlocks(), static_cast<std::size_t>(2 * n));  // 6 diagonal + 6 edges
  Eigen::VectorXd r(3 * n), z1(3 * n), z2(3 * n);
  for (Eigen::Index k = 0; k < r.size(); ++k) r[k] = rng.uniform() - 0.5;
  whole.apply(r.data(), z1.data());
  split.apply(r.data(), z2.data());
  EXPECT_LT((z1 - z2).norm(), 1e-13 * z1.norm());
  EXPECT_GT((a * z1 - r).norm(), 1e-6 * r.norm());  // the dropped fill: not an exact inverse
  const SpMat sparse = a.sparseView();
  Eigen::VectorXd v = Eigen::VectorXd::Zero(3 * n);
  const SolveStats s =
      LinearSolver(PreconditionerKind::IncompleteCholesky, 1e-12, 100).solve(sparse, r, v);
  EXPECT_TRUE(s.converged);
  EXPECT_LT((a * v - r).norm(), 1e-11 * r.norm());
}

TEST(IncompleteCholesky, RefusesWhatIsNotPositiveDefinite) {
  IncompleteCholesky ic;
  const Eigen::Matrix3d neg = -Eigen::Matrix3d::Identity();
  EXPECT_FALSE(ic.factor(2, [&](const BlockSink& sink) {
    sink(0, 0, Eigen::Matrix3d::Identity());
    sink(1, 1, neg);
  }));
  EXPECT_TRUE(ic.empty());
  EXPECT_FALSE(ic.factor(2, [&](const BlockSink& sink) {  // vertex 1 has no diagonal block
    sink(0, 0, Eigen::Matrix3d::Identity());
    sink(1, 0, 0.1 * Eigen::Matrix3d::Identity());
  }));
  EXPECT_FALSE(ic.factor(1, [&](const BlockSink& sink) { sink(0, 3, neg); }));  // out of range
}
