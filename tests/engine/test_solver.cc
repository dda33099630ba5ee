// The assembled friction matrix and the CG solve.
#include <gtest/gtest.h>

#include <numeric>
#include <random>

#include <Eigen/Dense>
#include <Eigen/SparseCholesky>

#include "activefoam/threads.h"
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
    // A step's Γ: the diagonal blocks assembled, the mesh edges' couplings applied edge by edge
    // (CortexViscosity's product); together the same operator.
    sim.prepareFriction();
    Rng rng(3, tris);
    Eigen::VectorXd v(a.rows()), y(a.rows());
    for (Eigen::Index k = 0; k < v.size(); ++k) v[k] = rng.uniform() - 0.5;
    sim.applyFriction(v.data(), y.data());
    EXPECT_LT((y - a * v).norm(), 1e-13 * (a * v).norm()) << tris << " triangles";
    EXPECT_EQ(sim.frictionMatrix().matrix().nonZeros(), 9 * sim.cells().numVertices());
    for (int i = 0; i < sim.cells().numVertices(); ++i)
      ASSERT_LT((sim.frictionMatrix().diagonalBlock(i) - a.block<3, 3>(3 * i, 3 * i)).norm(),
                1e-13 * a.norm())
          << "vertex " << i;
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
      // The step's product (Γ's diagonal blocks, the mesh edges' couplings edge by edge) takes
      // the same path to the same answer.
      Eigen::VectorXd w = Eigen::VectorXd::Zero(b.size());
      const auto product = [&](const double* in, double* out) { sim.applyFriction(in, out); };
      const SolveStats sb = cg.solve(product, sim.frictionMatrix(), b, w);
      EXPECT_EQ(sb.iterations, st.iterations);
      EXPECT_LT((w - v).norm(), 1e-9 * v.norm());
    }
  }
}

// Block-Jacobi inverts each 3×3 diagonal block: on a block-diagonal SPD matrix the
// preconditioned operator is the identity and CG converges in one iteration. The blocks span a
// condition number of 1e8; a near-singular block (cond 1e14, inverted through LDLT instead of
// the adjugate, to ~1e-2 relative) costs one iteration more.
TEST(Solver, BlockJacobiInvertsTheDiagonalBlocks) {
  for (const bool singular : {false, true}) {
    std::mt19937 rng(5);
    std::normal_distribution<double> g(0, 1);
    const int nb = 40;
    BlockMatrix a;
    a.setPattern(nb, {});
    for (int i = 0; i < nb; ++i) {
      Eigen::Matrix3d q;
      for (int k = 0; k < 9; ++k) q(k / 3, k % 3) = g(rng);
      q = Eigen::HouseholderQR<Eigen::Matrix3d>(q).householderQ();
      const double spread = singular && i == 7 ? 1e-14 : std::pow(10.0, -8.0 * i / nb);
      const Eigen::Vector3d lambda(1.0 + i, 0.5 * (1.0 + i), spread * (1.0 + i));
      const Eigen::Matrix3d m = q * lambda.asDiagonal() * q.transpose();
      a.addDiagonal(i, 0.5 * (m + m.transpose()));
    }
    Eigen::VectorXd b(3 * nb);
    for (Eigen::Index k = 0; k < b.size(); ++k) b[k] = g(rng);
    const auto product = [&](const double* in, double* out) { a.multiply(in, out); };
    LinearSolver cg(PreconditionerKind::BlockJacobi, 1e-6, 100);
    Eigen::VectorXd v = Eigen::VectorXd::Zero(b.size());
    const SolveStats st = cg.solve(product, a, b, v);
    EXPECT_TRUE(st.converged);
    EXPECT_EQ(st.iterations, singular ? 2 : 1);
    // Jacobi, which sees only the blocks' diagonals, needs many.
    LinearSolver jacobi(PreconditionerKind::Jacobi, 1e-6, 1000);
    Eigen::VectorXd w = Eigen::VectorXd::Zero(b.size());
    EXPECT_GT(jacobi.solve(product, a, b, w).iterations, 5);
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
  const SolveStats blocked = block.solve(a, b, w);
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

namespace {

// An SPD matrix of `groups` groups of 2–6 rows (a cell's vertices): a chain inside each group,
// and couplings between random pairs of groups (contacts), each a dissipative block +c on the
// two diagonals and −c across.
struct GroupedMatrix {
  int n = 0;
  std::vector<int> group_begin{0};
  Eigen::MatrixXd a;
  std::vector<std::pair<int, int>> pairs;  // coupled rows (i > j)
};

GroupedMatrix groupedMatrix(int groups, Rng& rng) {
  GroupedMatrix g;
  for (int k = 0; k < groups; ++k)
    g.group_begin.push_back(g.group_begin.back() + 2 + static_cast<int>(5 * rng.uniform()) % 5);
  g.n = g.group_begin.back();
  g.a = Eigen::MatrixXd::Zero(3 * g.n, 3 * g.n);
  auto couple = [&](int i, int j) {
    Eigen::Matrix3d m;
    for (int k = 0; k < 9; ++k) m(k) = rng.uniform() - 0.5;
    const Eigen::Matrix3d c = m * m.transpose() + 0.2 * Eigen::Matrix3d::Identity();
    g.a.block<3, 3>(3 * i, 3 * i) += c;
    g.a.block<3, 3>(3 * j, 3 * j) += c;
    g.a.block<3, 3>(3 * i, 3 * j) -= c;
    g.a.block<3, 3>(3 * j, 3 * i) -= c;
    g.pairs.emplace_back(std::max(i, j), std::min(i, j));
  };
  for (int k = 0; k < groups; ++k)
    for (int r = g.group_begin[k]; r + 1 < g.group_begin[k + 1]; ++r) couple(r + 1, r);
  for (int e = 0; e < 3 * groups; ++e) {
    const int p = static_cast<int>(groups * rng.uniform()) % groups;
    const int q = static_cast<int>(groups * rng.uniform()) % groups;
    if (p == q) continue;
    const int i = g.group_begin[p] +
                  static_cast<int>(8 * rng.uniform()) % (g.group_begin[p + 1] - g.group_begin[p]);
    const int j = g.group_begin[q] +
                  static_cast<int>(8 * rng.uniform()) % (g.group_begin[q + 1] - g.group_begin[q]);
    couple(i, j);
  }
  for (int i = 0; i < g.n; ++i) g.a.block<3, 3>(3 * i, 3 * i) += 0.05 * Eigen::Matrix3d::Identity();
  return g;
}

// Emits g's blocks in the row numbering `at` (identity if empty): diagonals, then the pairs.
void emitGrouped(const GroupedMatrix& g, const std::vector<int>& at, const BlockSink& sink) {
  auto id = [&](int i) { return at.empty() ? i : at[i]; };
  for (int i = 0; i < g.n; ++i) sink(id(i), id(i), g.a.block<3, 3>(3 * i, 3 * i));
  for (auto [i, j] : g.pairs) sink(id(i), id(j), g.a.block<3, 3>(3 * i, 3 * j));
}

}  // namespace

// With groups, the factor is IC(0) of P A Pᵀ, P ordering the groups by a colouring in which no
// two groups of one colour are coupled: the plain factor of the renumbered matrix, rows kept
// together and in order inside their group.
TEST(IncompleteCholesky, GroupsAreFactoredColourByColour) {
  Rng rng(17, 3);
  const GroupedMatrix g = groupedMatrix(30, rng);
  IncompleteCholesky grouped, plain;
  ASSERT_TRUE(grouped.factor(
      g.n, [&](const BlockSink& s) { emitGrouped(g, {}, s); }, g.group_begin));
  const std::vector<int>& p = grouped.permutation();
  ASSERT_EQ(static_cast<int>(p.size()), g.n);
  std::vector<int> seen(g.n, 0);
  for (int i = 0; i < g.n; ++i) ++seen[p[i]];
  EXPECT_EQ(std::count(seen.begin(), seen.end(), 1), g.n);
  for (std::size_t k = 0; k + 1 < g.group_begin.size(); ++k)
    for (int r = g.group_begin[k]; r + 1 < g.group_begin[k + 1]; ++r) EXPECT_EQ(p[r + 1], p[r] + 1);
  EXPECT_GT(grouped.numColours(), 1);
  EXPECT_LT(grouped.numColours(), 12);  // greedy: at most the largest degree + 1
  for (auto [i, j] : g.pairs) {         // coupled rows of two groups are never of one colour
    const auto group = [&](int r) {
      return std::upper_bound(g.group_begin.begin(), g.group_begin.end(), r) -
             g.group_begin.begin();
    };
    if (group(i) != group(j)) {
      EXPECT_NE(grouped.colourOfRow(p[i]), grouped.colourOfRow(p[j]));
    }
  }
  ASSERT_TRUE(plain.factor(g.n, [&](const BlockSink& s) { emitGrouped(g, p, s); }));
  EXPECT_EQ(plain.numStoredBlocks(), grouped.numStoredBlocks());
  Eigen::VectorXd r(3 * g.n), rp(3 * g.n), z(3 * g.n), zp(3 * g.n);
  for (Eigen::Index k = 0; k < r.size(); ++k) r[k] = rng.uniform() - 0.5;
  for (int i = 0; i < g.n; ++i) rp.segment<3>(3 * p[i]) = r.segment<3>(3 * i);
  grouped.apply(r.data(), z.data());
  plain.apply(rp.data(), zp.data());
  Eigen::VectorXd zback(3 * g.n);  // the plain solution in the caller's numbering
  for (int i = 0; i < g.n; ++i) zback.segment<3>(3 * i) = zp.segment<3>(3 * p[i]);
  // Not the same bits: the grouped backward solve gathers the couplings between groups that the
  // plain one scatters.
  EXPECT_LT((z - zback).norm(), 1e-13 * z.norm());
  // And it preconditions CG to the solution.
  const SpMat sparse = g.a.sparseView();
  LinearSolver cg(PreconditionerKind::IncompleteCholesky, 1e-12, 200);
  Eigen::VectorXd v = Eigen::VectorXd::Zero(3 * g.n);
  LinearSolver jacobi(PreconditionerKind::Jacobi, 1e-12, 2000);
  Eigen::VectorXd w = Eigen::VectorXd::Zero(3 * g.n);
  BlockMatrix diagonal;  // the Jacobi preconditioner's blocks
  diagonal.setPattern(g.n, {});
  for (int i = 0; i < g.n; ++i) diagonal.addDiagonal(i, g.a.block<3, 3>(3 * i, 3 * i));
  const auto product = [&](const double* in, double* out) {
    Eigen::Map<Eigen::VectorXd>(out, 3 * g.n) =
        g.a * Eigen::Map<const Eigen::VectorXd>(in, 3 * g.n);
  };
  const SolveStats s = cg.solve(product, diagonal, r, v, &grouped);
  const SolveStats sj = jacobi.solve(product, diagonal, r, w);
  EXPECT_TRUE(s.converged);
  EXPECT_LT((g.a * v - r).norm(), 1e-10 * r.norm());
  EXPECT_LT(s.iterations, sj.iterations);
}

// The groups of one colour run in parallel: factor and application give the same bits on 1, 2
// and 3 threads (a fine grain so that every parallel path is taken).
TEST(IncompleteCholesky, GroupedFactorIsTheSameForAnyThreadCount) {
  Rng rng(17, 4);
  const GroupedMatrix g = groupedMatrix(60, rng);
  Eigen::VectorXd r(3 * g.n);
  for (Eigen::Index k = 0; k < r.size(); ++k) r[k] = rng.uniform() - 0.5;
  const int saved_threads = threads();
  const Grain saved_grain = grain();
  setGrain(Grain{64, 0});
  std::vector<Eigen::VectorXd> z;
  for (int t : {1, 2, 3}) {
    setThreads(t);
    IncompleteCholesky ic;
    ASSERT_TRUE(ic.factor(
        g.n, [&](const BlockSink& s) { emitGrouped(g, {}, s); }, g.group_begin));
    z.emplace_back(3 * g.n);
    ic.apply(r.data(), z.back().data());
  }
  setThreads(saved_threads);
  setGrain(saved_grain);
  for (std::size_t k = 1; k < z.size(); ++k)
    for (Eigen::Index i = 0; i < r.size(); ++i) ASSERT_EQ(z[0][i], z[k][i]) << "entry " << i;
}

TEST(IncompleteCholesky, RefusesGroupsThatDoNotTileTheRows) {
  IncompleteCholesky ic;
  const auto diagonal = [](const BlockSink& sink) {
    for (int i = 0; i < 4; ++i) sink(i, i, Eigen::Matrix3d::Identity());
  };
  EXPECT_TRUE(ic.factor(4, diagonal, {0, 1, 4}));
  EXPECT_FALSE(ic.factor(4, diagonal, {0, 3}));        // row 3 in no group
  EXPECT_FALSE(ic.factor(4, diagonal, {0, 3, 2, 4}));  // decreasing
  EXPECT_FALSE(ic.factor(4, diagonal, {1, 4}));        // row 0 in no group
  EXPECT_TRUE(ic.empty());
}

// A breakdown is retried on A + α diag(A), α doubling from 1e-3: here the second pivot,
// (1 + α) − 1.5² / (1 + α), first turns positive at α = 1e-3 · 2⁹ = 0.512. The retry starts
// from A again (the failed try overwrote it), so the factor is exactly that of the shifted A.
TEST(IncompleteCholesky, RetriesABreakdownWithAShiftedDiagonal) {
  const Eigen::Matrix3d id = Eigen::Matrix3d::Identity();
  for (const std::vector<int>& groups : {std::vector<int>{}, std::vector<int>{0, 1, 2}}) {
    IncompleteCholesky ic;
    ASSERT_TRUE(ic.factor(
        2,
        [&](const BlockSink& sink) {
          sink(0, 0, id);
          sink(1, 0, 1.5 * id);
          sink(1, 1, id);
        },
        groups));
    EXPECT_DOUBLE_EQ(ic.shift(), 0.512);
    Eigen::MatrixXd shifted = Eigen::MatrixXd::Zero(6, 6);
    shifted.topLeftCorner(3, 3) = shifted.bottomRightCorner(3, 3) = 1.512 * id;
    shifted.topRightCorner(3, 3) = shifted.bottomLeftCorner(3, 3) = 1.5 * id;
    Eigen::VectorXd x(6), z(6);
    x << 1, -2, 0.5, 3, 0.25, -1;
    const Eigen::VectorXd r = shifted * x;
    ic.apply(r.data(), z.data());  // no fill to drop: the exact inverse of the shifted matrix
    EXPECT_LT((z - x).norm(), 1e-9 * x.norm());
  }
}

// Beyond kMaxColouredGroups the colouring's bit matrix would grow too large: the rows are then
// one sequence in their own order — exactly the plain factor.
TEST(IncompleteCholesky, TooManyGroupsAreOneSequence) {
  const int n = IncompleteCholesky::kMaxColouredGroups + 1;
  std::vector<int> groups(n + 1);
  std::iota(groups.begin(), groups.end(), 0);  // a group per row
  const auto chain = [&](const BlockSink& sink) {
    for (int i = 0; i < n; ++i) {
      sink(i, i, (2.5 + 0.1 * (i % 7)) * Eigen::Matrix3d::Identity());
      if (i > 0) sink(i, i - 1, -Eigen::Matrix3d::Identity());
    }
  };
  IncompleteCholesky grouped, plain;
  ASSERT_TRUE(grouped.factor(n, chain, groups));
  ASSERT_TRUE(plain.factor(n, chain));
  EXPECT_EQ(grouped.numColours(), 1);
  for (int i = 0; i < n; ++i) ASSERT_EQ(grouped.permutation()[i], i);
  Eigen::VectorXd r(3 * n), z1(3 * n), z2(3 * n);
  for (Eigen::Index k = 0; k < r.size(); ++k) r[k] = std::sin(0.3 * static_cast<double>(k));
  grouped.apply(r.data(), z1.data());
  plain.apply(r.data(), z2.data());
  EXPECT_EQ(z1, z2);
}
