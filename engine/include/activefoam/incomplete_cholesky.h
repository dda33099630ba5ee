// Block incomplete Cholesky, IC(0) on 3×3 blocks: L Lᵀ ≈ A with L restricted to A's own block
// pattern (no fill). The preconditioner for Γ v = F that sees the contact couplings: the
// stiffness that slows CG sits in the springs between cells (Δt k_AB S ≫ the friction), which
// Jacobi and per-cell blocks cannot see (issue 15's measurements: 51 CG iterations with Jacobi,
// 26 with exact per-cell blocks, ~9 with this factor).
//
// The factor is built from blocks handed to it in any order (duplicates summed in the order
// given), so a caller can add an operator's assembled part and its product-applied couplings
// without assembling the latter into a pattern. Factor and apply are sequential loops in a
// fixed order: the same bits for any thread count.
#pragma once

#include <vector>

#include "activefoam/block_matrix.h"

namespace activefoam {

// Calls the sink for blocks of the matrix; must emit the same blocks in the same order each
// time it is called (the factor walks them twice: to count, then to fill).
using BlockSource = std::function<void(const BlockSink&)>;

class IncompleteCholesky {
 public:
  // Factors the SPD matrix of num_blocks 3×3 block rows whose blocks `blocks` emits: each
  // unordered pair once, the diagonal blocks at least once (duplicates are summed). If the
  // incomplete factorisation breaks down (a pivot block not positive definite), it is retried
  // on A + α diag(A) with α doubling from 1e-3 (Manteuffel's shift). Returns false if no shift
  // up to 1 worked or a diagonal block is missing.
  bool factor(int num_blocks, const BlockSource& blocks);
  // z = (L Lᵀ)⁻¹ r (r and z may not alias).
  void apply(const double* r, double* z) const;
  int numBlocks() const { return n_; }
  bool empty() const { return n_ == 0; }
  double shift() const { return shift_; }
  std::size_t numStoredBlocks() const { return col_.size(); }

 private:
  int n_ = 0;
  double shift_ = 0;
  // Block CSR of the lower triangle, each row sorted by column with the diagonal last.
  std::vector<int> row_begin_, col_;
  std::vector<double> a_;     // A's blocks (row-major 3×3), kept for retries with a shift
  std::vector<double> l_;     // L's blocks
  std::vector<double> dinv_;  // per row: L_ii⁻¹ (lower triangular, row-major)
  // Assembly buffers, kept between factorisations.
  std::vector<int> scratch_, begin_, fill_, cols_, slot_of_, slots_;
  std::vector<double> vals_, sums_;
};

}  // namespace activefoam
