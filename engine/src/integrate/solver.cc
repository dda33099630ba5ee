#include "activefoam/solver.h"

#include <Eigen/Cholesky>
#include <cmath>
#include <cstdint>
#include <limits>
#include <map>
#include <stdexcept>

#include "activefoam/threads.h"

namespace activefoam {

void LinearSolver::setPreconditioner(int block, const Eigen::Matrix3d& d) {
  Eigen::Matrix3d inv = Eigen::Matrix3d::Zero();
  if (kind_ == PreconditionerKind::BlockJacobi) {
    // Diagonal blocks of an SPD matrix are SPD: the symmetric adjugate over the determinant (a
    // step inverts every vertex's block; Eigen's LDLT cost ~1.5 % of a step of the 2 × 100
    // fusion). LDLT where the determinant is not safely positive (a near-singular block).
    const double a = d(0, 0), b = d(0, 1), c = d(0, 2), e = d(1, 1), f = d(1, 2), i = d(2, 2);
    const double ca = e * i - f * f, cb = c * f - b * i, cc = b * f - c * e;
    const double det = a * ca + b * cb + c * cc;
    const double scale = std::abs(a) * std::abs(e) * std::abs(i);
    if (det > 1e-12 * scale && std::isfinite(det)) {
      const double s = 1 / det;
      const double ce = a * i - c * c, cf = b * c - a * f, ci = a * e - b * b;
      inv << ca * s, cb * s, cc * s, cb * s, ce * s, cf * s, cc * s, cf * s, ci * s;
    } else {
      inv = d.ldlt().solve(Eigen::Matrix3d::Identity());
    }
  } else {
    for (int k = 0; k < 3; ++k) inv(k, k) = d(k, k) != 0 ? 1 / d(k, k) : 1;
  }
  inv_[block] = inv;
}

namespace {

// Σ a_k b_k over [begin, end) with four accumulators by k mod 4 (the order is fixed by k, not by
// alignment or threads; four chains instead of one keep the adds pipelined).
inline double dotRange(const double* a, const double* b, std::int64_t begin, std::int64_t end) {
  double s0 = 0, s1 = 0, s2 = 0, s3 = 0;
  std::int64_t k = begin;
  for (; k + 4 <= end; k += 4) {
    s0 += a[k] * b[k];
    s1 += a[k + 1] * b[k + 1];
    s2 += a[k + 2] * b[k + 2];
    s3 += a[k + 3] * b[k + 3];
  }
  for (; k < end; ++k) s0 += a[k] * b[k];
  return (s0 + s1) + (s2 + s3);
}

inline double dot(const double* a, const double* b, std::int64_t n, std::int64_t chunk,
                  bool threaded) {
  return deterministicSum(n, chunk, threaded, [&](std::int64_t begin, std::int64_t end) {
    return dotRange(a, b, begin, end);
  });
}

// Elementwise loops: no reduction, so any split gives the same bits; threads only where the
// vector is long enough to pay for the team.
template <class Body>
inline void forEach(std::int64_t n, bool threaded, const Body& body) {
#pragma omp parallel for schedule(static) if (threaded)
  for (std::int64_t k = 0; k < n; ++k) body(k);
}

}  // namespace

template <typename Multiply>
SolveStats LinearSolver::pcg(const Multiply& mul, const Eigen::VectorXd& b, Eigen::VectorXd& x) {
  SolveStats s;
  const Eigen::Index n = b.size(), nb = n / 3;
  const Grain g = grain();
  const std::int64_t chunk = g.reduce_chunk;
  const bool threaded = n > g.min_items;
  // The preconditioner works on 3×3 blocks, so its chunks are whole blocks.
  const std::int64_t block_chunk = std::max<std::int64_t>(1, chunk / 3);
  const double bnorm2 = dot(b.data(), b.data(), n, chunk, threaded);
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
  double *xd = x.data(), *r = r_.data(), *z = z_.data(), *p = p_.data(), *q = q_.data();
  const double* bd = b.data();
  mul(xd, q);
  forEach(n, threaded, [&](std::int64_t k) { r[k] = bd[k] - q[k]; });
  double rr = dot(r, r, n, chunk, threaded);
  auto precondition = [&] {  // z = M⁻¹ r; returns r·z
    if (factor_) {
      factor_->apply(r, z);
      return dot(r, z, n, chunk, threaded);
    }
    return deterministicSum(nb, block_chunk, threaded, [&](std::int64_t begin, std::int64_t end) {
      double rz = 0;
      for (std::int64_t i = begin; i < end; ++i) {
        const Eigen::Vector3d ri(r[3 * i], r[3 * i + 1], r[3 * i + 2]);
        const Eigen::Vector3d zi = inv_[i] * ri;
        z[3 * i] = zi[0];
        z[3 * i + 1] = zi[1];
        z[3 * i + 2] = zi[2];
        rz += zi.dot(ri);
      }
      return rz;
    });
  };
  if (rr >= threshold) {
    double rz = precondition();
    forEach(n, threaded, [&](std::int64_t k) { p[k] = z[k]; });
    while (s.iterations < max_iter_) {
      mul(p, q);
      const double alpha = rz / dot(p, q, n, chunk, threaded);
      rr = deterministicSum(n, chunk, threaded, [&](std::int64_t begin, std::int64_t end) {
        for (std::int64_t k = begin; k < end; ++k) {
          xd[k] += alpha * p[k];
          r[k] -= alpha * q[k];
        }
        return dotRange(r, r, begin, end);
      });
      ++s.iterations;
      if (rr < threshold) break;
      const double rz_new = precondition();
      const double beta = rz_new / rz;
      rz = rz_new;
      forEach(n, threaded, [&](std::int64_t k) { p[k] = z[k] + beta * p[k]; });
    }
  }
  s.residual = std::sqrt(rr / bnorm2);
  s.converged = rr < threshold;
  return s;
}

template <typename Multiply>
SolveStats LinearSolver::pcgWith(const IncompleteCholesky* factor, const Multiply& mul,
                                 const Eigen::VectorXd& b, Eigen::VectorXd& x) {
  factor_ = factor;  // read by pcg's preconditioner step; never kept past the solve
  const SolveStats s = pcg(mul, b, x);
  factor_ = nullptr;
  return s;
}

SolveStats LinearSolver::solve(const BlockMatrix& a, const Eigen::VectorXd& b, Eigen::VectorXd& x) {
  const IncompleteCholesky* factor = nullptr;
  if (kind_ == PreconditionerKind::IncompleteCholesky) {
    if (!own_factor_.factor(a.numBlocks(), [&](const BlockSink& s) { a.forEachLowerBlock(s); }))
      throw std::invalid_argument("incomplete Cholesky: the matrix is not SPD");
    factor = &own_factor_;
  }
  return solve([&](const double* in, double* out) { a.multiply(in, out); }, a, b, x, factor);
}

SolveStats LinearSolver::solve(const Product& a, const BlockMatrix& diagonal,
                               const Eigen::VectorXd& b, Eigen::VectorXd& x,
                               const IncompleteCholesky* factor) {
  if (kind_ == PreconditionerKind::IncompleteCholesky) {
    if (!factor || factor->numBlocks() != diagonal.numBlocks())
      throw std::invalid_argument("incomplete Cholesky: no factor of this matrix");
    return pcgWith(factor, a, b, x);
  }
  inv_.resize(diagonal.numBlocks());
  for (int i = 0; i < diagonal.numBlocks(); ++i) setPreconditioner(i, diagonal.diagonalBlock(i));
  return pcg(a, b, x);
}

SolveStats LinearSolver::solve(const SpMat& a, const Eigen::VectorXd& b, Eigen::VectorXd& x) {
  const Eigen::Index nb = a.rows() / 3;
  const auto product = [&](const double* in, double* out) {
    Eigen::Map<Eigen::VectorXd>(out, a.rows()) =
        a * Eigen::Map<const Eigen::VectorXd>(in, a.cols());
  };
  if (kind_ == PreconditionerKind::IncompleteCholesky) {
    // The lower triangle's blocks, one block row at a time.
    const bool ok = own_factor_.factor(static_cast<int>(nb), [&](const BlockSink& sink) {
      std::map<Eigen::Index, Eigen::Matrix3d> row;
      for (Eigen::Index i = 0; i < nb; ++i) {
        row.clear();
        for (int r = 0; r < 3; ++r)
          for (SpMat::InnerIterator it(a, 3 * i + r); it; ++it) {
            const Eigen::Index j = it.col() / 3;
            if (j > i) continue;
            row.try_emplace(j, Eigen::Matrix3d::Zero()).first->second(r, it.col() % 3) = it.value();
          }
        for (const auto& [j, m] : row) sink(static_cast<int>(i), static_cast<int>(j), m);
      }
    });
    if (!ok) throw std::invalid_argument("incomplete Cholesky: the matrix is not SPD");
    return pcgWith(&own_factor_, product, b, x);
  }
  inv_.resize(nb);
  for (Eigen::Index i = 0; i < nb; ++i) {
    Eigen::Matrix3d d = Eigen::Matrix3d::Zero();
    for (int r = 0; r < 3; ++r)
      for (SpMat::InnerIterator it(a, 3 * i + r); it; ++it)
        if (it.col() >= 3 * i && it.col() < 3 * i + 3) d(r, it.col() - 3 * i) = it.value();
    setPreconditioner(static_cast<int>(i), d);
  }
  return pcg(product, b, x);
}

}  // namespace activefoam
