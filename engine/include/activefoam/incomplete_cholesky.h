// Block incomplete Cholesky, IC(0) on 3×3 blocks: L Lᵀ ≈ P A Pᵀ with L restricted to A's own
// block pattern (no fill). The preconditioner for Γ v = F that sees the contact couplings: the
// stiffness that slows CG sits in the springs between cells (Δt k_AB S ≫ the friction), which
// Jacobi and per-cell blocks cannot see (on a reduced fusion: 51 CG iterations with Jacobi,
// 26 with exact per-cell blocks, ~9 with this factor).
//
// The factor is built from blocks handed to it in any order (duplicates summed in the order
// given), so a caller can add an operator's assembled part and its product-applied couplings
// without assembling the latter into a pattern.
//
// Threads: the rows may be split into groups (a cell's vertices). The groups are coloured
// greedily so that no block couples two groups of one colour, and ordered by colour (P); the
// groups of one colour are then independent in the factorisation and in both triangular solves
// and run in parallel, one group per task, each row computed in its one fixed order. The
// ordering depends only on the blocks, never on the threads: the same bits for any thread count.
#pragma once

#include <cstdint>
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
  // up to 1 worked, a diagonal block is missing, or the input is out of range.
  //
  // group_begin, if given, splits the rows into groups [group_begin[g], group_begin[g + 1])
  // (non-decreasing, from 0 to num_blocks); rows keep their order inside a group. Without it
  // (or with more than kMaxColouredGroups groups) the rows are one sequence in their own order.
  bool factor(int num_blocks, const BlockSource& blocks, const std::vector<int>& group_begin = {});
  // z = (L Lᵀ)⁻¹ r in the caller's numbering (r and z may not alias). Not reentrant: one
  // application at a time (it permutes through a buffer of the factor).
  void apply(const double* r, double* z) const;
  int numBlocks() const { return n_; }
  bool empty() const { return n_ == 0; }
  double shift() const { return shift_; }
  std::size_t numStoredBlocks() const { return stored_; }
  // Colours of the last factor: the parallel phases of each triangular solve.
  int numColours() const { return static_cast<int>(colour_begin_.size()) - 1; }
  // P of the last factor: the factor's row of each of the caller's rows.
  const std::vector<int>& permutation() const { return perm_; }
  // The colour of a factor row (rows of one colour are contiguous).
  int colourOfRow(int factor_row) const;

  // The colouring's adjacency is a dense bit matrix (G² bits): 4096 groups take 2 MiB.
  static constexpr int kMaxColouredGroups = 4096;

 private:
  bool assemble(int n, const BlockSource& blocks, const std::vector<int>& group_begin);
  void packValues();  // A's summed blocks from the assembly's slots into l_
  bool factorRows(int begin, int end, double shift);
  int n_ = 0;
  double shift_ = 0;
  bool threaded_ = false;
  std::size_t stored_ = 0;
  std::vector<int> perm_, iperm_;  // caller's row → factor's row, and back
  // Factor order: group k spans factor rows [group_row_[k], group_row_[k + 1]); the groups of
  // colour c are k ∈ [colour_begin_[c], colour_begin_[c + 1]).
  std::vector<int> group_row_, colour_begin_;
  // The lower triangle in factor numbering by 3×3 blocks (row-major), A's and then, in place,
  // L's: block CSR, row i's blocks [row_begin_[i], row_begin_[i + 1]) sorted by column, the
  // diagonal last; own_begin_[i]: the first inside its own group; and, for the backward solve's
  // gather, the transpose of the blocks before it (see assemble()).
  std::vector<int> row_begin_, col_, own_begin_;
  std::vector<int> cross_begin_, cross_row_, cross_block_;
  std::vector<double> l_;
  std::vector<double> dinv_;  // per row: L_ii⁻¹ (lower triangular, row-major)
  mutable std::vector<double> work_;
  // Assembly buffers, kept between factorisations.
  std::vector<int> group_of_, colour_of_, count_, slot_begin_, slot_end_, slot_col_;
  std::vector<double> slot_val_;
  std::vector<std::uint64_t> adjacent_;
};

}  // namespace activefoam
