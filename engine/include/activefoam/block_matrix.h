// Symmetric 3×3-block sparse matrix with a fixed pattern, stored as an Eigen row-major sparse
// matrix whose values are overwritten each step (the pattern is rebuilt only when the topology
// or the contact set changes: setFromTriplets every step would cost more than the CG solve).
#pragma once

#include <cstddef>
#include <functional>
#include <utility>
#include <vector>

#include <Eigen/Core>
#include <Eigen/SparseCore>

namespace activefoam {

using SpMat = Eigen::SparseMatrix<double, Eigen::RowMajor>;

// Receives one block A_ij of a symmetric matrix (A_ji = A_ijᵀ is implied for i ≠ j).
using BlockSink = std::function<void(int i, int j, const Eigen::Matrix3d& m)>;

class BlockMatrix {
 public:
  // Pattern: every diagonal block plus the given off-diagonal block pairs (i, j), i != j, stored
  // symmetrically. Duplicates are fine.
  void setPattern(int num_blocks, std::vector<std::pair<int, int>> couplings);
  void setZero();
  void addDiagonal(int i, const Eigen::Matrix3d& m) {
    if (!diagonal_only_) return addDiagonalInPattern(i, m);
    // Inline: ~10⁶ calls a step on the 2 × 100 fusion (cortex edges, contact pairs' vertices).
    double* b = a_.valuePtr() + 9 * static_cast<std::ptrdiff_t>(i);
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 3; ++c) b[3 * r + c] += m(r, c);
  }
  // Dissipative coupling between nodes i and j: +m on (i,i), (j,j); −m on (i,j), (j,i).
  // m must be symmetric; positive semi-definite m keeps the whole matrix SPD.
  void addCoupling(int i, int j, const Eigen::Matrix3d& m);
  const SpMat& matrix() const { return a_; }
  int numBlocks() const { return n_; }
  // y = A x by 3×3 blocks: one column index per block instead of nine, and the three rows of a
  // block row streamed together (the CG solve is most of a step; this is its inner loop).
  void multiply(const double* x, double* y) const;
  Eigen::Matrix3d diagonalBlock(int i) const;
  // Every stored block A_ij with j ≤ i (the lower triangle, diagonal included), row by row.
  void forEachLowerBlock(const BlockSink& sink) const;

 private:
  // Offset of block k's first value in the scalar value array.
  double* blockValues(int k) { return a_.valuePtr() + offset_[k]; }
  int findBlock(int i, int j) const;
  void addDiagonalInPattern(int i, const Eigen::Matrix3d& m);
  int n_ = 0;
  // No off-diagonal block (a step's Γ): block i's 9 values are contiguous at 9 i, and addDiagonal
  // and multiply skip the pattern's index arrays (~4 % of a step of the 2 × 100 fusion).
  bool diagonal_only_ = false;
  std::vector<int> row_begin_;  // block CSR: blocks of block-row i are cols_[row_begin_[i]..]
  std::vector<int> cols_;
  std::vector<int> diag_;       // block index of (i, i)
  std::vector<int> transpose_;  // block index of (j, i) for block k = (i, j)
  std::vector<Eigen::Index> offset_;
  std::vector<int> width_;  // scalar row stride of block k's rows (3 × blocks in its row)
  SpMat a_;
};

}  // namespace activefoam
