#include "activefoam/incomplete_cholesky.h"

#include <algorithm>
#include <cmath>
#include <numeric>

#include "activefoam/threads.h"

namespace activefoam {

namespace {

// 3×3 blocks are row-major double[9].

// s −= a bᵀ
inline void subtractABt(double* s, const double* a, const double* b) {
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c)
      s[3 * r + c] -=
          a[3 * r] * b[3 * c] + a[3 * r + 1] * b[3 * c + 1] + a[3 * r + 2] * b[3 * c + 2];
}

// out = a bᵀ
inline void multiplyABt(double* out, const double* a, const double* b) {
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c)
      out[3 * r + c] =
          a[3 * r] * b[3 * c] + a[3 * r + 1] * b[3 * c + 1] + a[3 * r + 2] * b[3 * c + 2];
}

// The inverse of the lower Cholesky factor of the symmetric block s (its lower part is read);
// false if s is not positive definite.
inline bool invertedCholesky(const double* s, double* inv) {
  const double l00 = s[0];
  if (!(l00 > 0)) return false;
  const double d0 = std::sqrt(l00);
  const double l10 = s[3] / d0, l20 = s[6] / d0;
  const double p1 = s[4] - l10 * l10;
  if (!(p1 > 0)) return false;
  const double d1 = std::sqrt(p1);
  const double l21 = (s[7] - l20 * l10) / d1;
  const double p2 = s[8] - l20 * l20 - l21 * l21;
  if (!(p2 > 0) || !std::isfinite(p2)) return false;
  const double d2 = std::sqrt(p2);
  const double i00 = 1 / d0, i11 = 1 / d1, i22 = 1 / d2;
  const double i10 = -i11 * l10 * i00;
  const double i21 = -i22 * l21 * i11;
  const double i20 = -i22 * (l20 * i00 + l21 * i10);
  inv[0] = i00, inv[1] = 0, inv[2] = 0;
  inv[3] = i10, inv[4] = i11, inv[5] = 0;
  inv[6] = i20, inv[7] = i21, inv[8] = i22;
  return true;
}

}  // namespace

bool IncompleteCholesky::factor(int num_blocks, const BlockSource& blocks,
                                const std::vector<int>& group_begin) {
  n_ = 0;
  shift_ = 0;
  if (!assemble(num_blocks, blocks, group_begin)) return false;
  const int colours = numColours();
  std::vector<char> failed(static_cast<std::size_t>(colours));
  for (double shift = 0; shift <= 1; shift = shift == 0 ? 1e-3 : 2 * shift) {
    // A failed try has overwritten A's blocks with part of L: copy them again from the
    // assembly's slots. (Assembling again instead doubled ros2's solve phase on the 2 × 30
    // fusion: with its consistent contact stiffness, breakdowns are frequent.)
    if (shift > 0) packValues();
    std::fill(failed.begin(), failed.end(), 0);
#pragma omp parallel if (threaded_)
    {
      for (int c = 0; c < colours; ++c) {
#pragma omp for schedule(dynamic, 1)
        for (int k = colour_begin_[c]; k < colour_begin_[c + 1]; ++k)
          if (!factorRows(group_row_[k], group_row_[k + 1], shift)) {
#pragma omp atomic write
            failed[c] = 1;
          }
        // After the loop's barrier: every thread reads the same flag and leaves together.
        char f;
#pragma omp atomic read
        f = failed[c];
        if (f) break;
      }
    }
    if (std::find(failed.begin(), failed.end(), 1) == failed.end()) {
      n_ = num_blocks;
      shift_ = shift;
      work_.resize(3 * static_cast<std::size_t>(n_));
      return true;
    }
  }
  return false;
}

bool IncompleteCholesky::assemble(int n, const BlockSource& blocks,
                                  const std::vector<int>& group_begin) {
  stored_ = 0;
  if (n < 0) return false;
  const std::vector<int> whole{0, n};
  const std::vector<int>& gb = group_begin.empty() ? whole : group_begin;
  if (gb.size() < 2 || gb.front() != 0 || gb.back() != n) return false;
  const int num_groups = static_cast<int>(gb.size()) - 1;
  group_of_.resize(static_cast<std::size_t>(n));
  for (int g = 0; g < num_groups; ++g) {
    if (gb[g + 1] < gb[g]) return false;
    std::fill(group_of_.begin() + gb[g], group_of_.begin() + gb[g + 1], g);
  }
  const bool coloured = num_groups > 1 && num_groups <= kMaxColouredGroups;
  const std::size_t words = coloured ? (static_cast<std::size_t>(num_groups) + 63) / 64 : 0;
  adjacent_.assign(words * static_cast<std::size_t>(coloured ? num_groups : 0), 0);

  // Pass 1: count each row's blocks (in the caller's numbering) and note which groups are
  // coupled. Which row of a block between two groups comes later depends on the colouring, not
  // known yet: such a block is counted in both rows (one slot stays unused). The buffers are
  // members: a step's ~10⁵ blocks are tens of MB, which freshly allocated (and zeroed, and
  // faulted in) every step cost more than their reuse.
  std::vector<int>& count = count_;
  count.assign(static_cast<std::size_t>(n), 0);
  bool in_range = true;
  blocks([&](int i, int j, const Eigen::Matrix3d&) {
    if (i < 0 || j < 0 || i >= n || j >= n) {
      in_range = false;
      return;
    }
    const int gi = group_of_[i], gj = group_of_[j];
    if (gi == gj || !coloured) {
      ++count[std::max(i, j)];
      return;
    }
    ++count[i];
    ++count[j];
    adjacent_[gi * words + gj / 64] |= std::uint64_t{1} << (gj % 64);
    adjacent_[gj * words + gi / 64] |= std::uint64_t{1} << (gi % 64);
  });
  if (!in_range) return false;

  // Greedy colouring in group order (each group takes the least colour none of its lower
  // neighbours has), then the factor order: colour by colour, groups in their order within a
  // colour, rows in their order within a group.
  colour_of_.assign(static_cast<std::size_t>(num_groups), 0);
  int colours = 1;
  if (coloured) {
    std::vector<char> used;
    for (int g = 0; g < num_groups; ++g) {
      used.assign(static_cast<std::size_t>(colours) + 1, 0);
      const std::uint64_t* row = adjacent_.data() + g * words;
      for (int w = 0; w <= g / 64; ++w) {
        std::uint64_t bits = row[w];
        if (w == g / 64) bits &= (std::uint64_t{1} << (g % 64)) - 1;  // neighbours h < g
        while (bits) {
          used[colour_of_[64 * w + __builtin_ctzll(bits)]] = 1;
          bits &= bits - 1;
        }
      }
      int c = 0;
      while (used[c]) ++c;
      colour_of_[g] = c;
      colours = std::max(colours, c + 1);
    }
  }
  const int factor_groups = coloured ? num_groups : 1;
  colour_begin_.assign(static_cast<std::size_t>(colours) + 1, 0);
  for (int g = 0; g < factor_groups; ++g) ++colour_begin_[colour_of_[g] + 1];
  std::partial_sum(colour_begin_.begin(), colour_begin_.end(), colour_begin_.begin());
  std::vector<int> next(colour_begin_.begin(), colour_begin_.end() - 1), by_colour(factor_groups);
  for (int g = 0; g < factor_groups; ++g) by_colour[next[colour_of_[g]]++] = g;
  group_row_.resize(static_cast<std::size_t>(factor_groups) + 1);
  perm_.resize(static_cast<std::size_t>(n));
  iperm_.resize(static_cast<std::size_t>(n));
  int row = 0;
  for (int k = 0; k < factor_groups; ++k) {
    group_row_[k] = row;
    const int g = by_colour[k];
    const int first = coloured ? gb[g] : 0, last = coloured ? gb[g + 1] : n;
    for (int r = first; r < last; ++r, ++row) {
      perm_[r] = row;
      iperm_[row] = r;
    }
  }
  group_row_[factor_groups] = n;

  // Pass 2: each row's blocks into its slots (rows laid out in factor order), columns in factor
  // numbering, each block stored as A_(row, col): the block itself when i is the later row, its
  // transpose otherwise.
  std::vector<int>& slot_begin = slot_begin_;
  std::vector<int>& slot_end = slot_end_;
  slot_begin.resize(static_cast<std::size_t>(n));
  slot_end.resize(static_cast<std::size_t>(n));
  int total = 0;
  for (int r = 0; r < n; ++r) {
    slot_begin[r] = slot_end[r] = total;
    total += count[iperm_[r]];
  }
  slot_col_.resize(static_cast<std::size_t>(total));
  slot_val_.resize(9 * static_cast<std::size_t>(total));
  blocks([&](int i, int j, const Eigen::Matrix3d& m) {
    if (i < 0 || j < 0 || i >= n || j >= n) return;
    const bool i_row = perm_[i] >= perm_[j];
    const int pos = slot_end[i_row ? perm_[i] : perm_[j]]++;
    slot_col_[pos] = i_row ? perm_[j] : perm_[i];
    double* v = slot_val_.data() + 9 * static_cast<std::size_t>(pos);
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 3; ++c) v[3 * r + c] = i_row ? m(r, c) : m(c, r);
  });

  // A row's blocks repeat (a vertex pair is in many contact pairs): sum them into one slot per
  // column in the order given and write the few distinct columns back sorted, compacted at the
  // start of the row's slots. Rows are independent. The work is per block (~6 stored per row
  // with the contacts, ~15 given): that is what is measured against the grain.
  threaded_ = threads() > 1 && total > grain().min_items;
  int missing_diagonal = 0, stored = 0;
#pragma omp parallel if (threaded_)
  {
    std::vector<int> slot_of(static_cast<std::size_t>(n), -1), slots, order;
    std::vector<double> sums;
#pragma omp for schedule(static) reduction(| : missing_diagonal) reduction(+ : stored)
    for (int r = 0; r < n; ++r) {
      slots.clear();
      sums.clear();
      for (int p = slot_begin[r]; p < slot_end[r]; ++p) {
        const double* v = slot_val_.data() + 9 * static_cast<std::size_t>(p);
        int& s = slot_of[slot_col_[p]];
        if (s < 0) {
          s = static_cast<int>(slots.size());
          slots.push_back(slot_col_[p]);
          sums.insert(sums.end(), v, v + 9);
        } else {
          double* w = sums.data() + 9 * static_cast<std::size_t>(s);
          for (int k = 0; k < 9; ++k) w[k] += v[k];
        }
      }
      order.resize(slots.size());
      std::iota(order.begin(), order.end(), 0);
      std::sort(order.begin(), order.end(), [&](int p, int q) { return slots[p] < slots[q]; });
      int q = slot_begin[r];
      for (int s : order) {
        slot_col_[q] = slots[s];
        std::copy_n(sums.data() + 9 * static_cast<std::size_t>(s), 9,
                    slot_val_.data() + 9 * static_cast<std::size_t>(q));
        slot_of[slots[s]] = -1;
        ++q;
      }
      slot_end[r] = q;
      stored += q - slot_begin[r];
      if (q == slot_begin[r] || slot_col_[q - 1] != r) missing_diagonal |= 1;
    }
  }
  if (missing_diagonal) return false;
  stored_ = stored;
  // Packed: the solves stream L once per CG iteration, and the unused slots would more than
  // double what they read.
  row_begin_.resize(static_cast<std::size_t>(n) + 1);
  row_begin_[0] = 0;
  for (int r = 0; r < n; ++r) row_begin_[r + 1] = row_begin_[r] + slot_end[r] - slot_begin[r];
  col_.resize(static_cast<std::size_t>(stored));
#pragma omp parallel for schedule(static) if (threaded_)
  for (int r = 0; r < n; ++r)
    std::copy(slot_col_.begin() + slot_begin[r], slot_col_.begin() + slot_end[r],
              col_.begin() + row_begin_[r]);
  packValues();

  // Each row's blocks split at its group's first row: those before couple it to groups of
  // earlier colours (cross), those after to its own group (own). The backward solve scatters a
  // row's own blocks into its group's earlier rows (streaming L as the forward solve does) and
  // gathers the cross ones from the later groups that reference it, which another task of the
  // same colour could otherwise scatter into at the same time. cross_begin_ lists, per row i,
  // the later rows j of other groups with a block L_ji (increasing j) and that block.
  own_begin_.resize(static_cast<std::size_t>(n));
  cross_begin_.assign(static_cast<std::size_t>(n) + 1, 0);
  for (int k = 0; k < factor_groups; ++k)
    for (int r = group_row_[k]; r < group_row_[k + 1]; ++r) {
      int kk = row_begin_[r];
      while (col_[kk] < group_row_[k]) ++cross_begin_[col_[kk++] + 1];
      own_begin_[r] = kk;
    }
  std::partial_sum(cross_begin_.begin(), cross_begin_.end(), cross_begin_.begin());
  cross_row_.resize(static_cast<std::size_t>(cross_begin_[n]));
  cross_block_.resize(static_cast<std::size_t>(cross_begin_[n]));
  std::vector<int>& fill = count;  // reused: no longer needed
  fill.assign(cross_begin_.begin(), cross_begin_.end() - 1);
  for (int r = 0; r < n; ++r)
    for (int kk = row_begin_[r]; kk < own_begin_[r]; ++kk) {
      const int p = fill[col_[kk]]++;
      cross_row_[p] = r;
      cross_block_[p] = kk;
    }
  dinv_.assign(9 * static_cast<std::size_t>(n), 0.0);
  return true;
}

void IncompleteCholesky::packValues() {
  const int n = static_cast<int>(row_begin_.size()) - 1;
  l_.resize(9 * stored_);
#pragma omp parallel for schedule(static) if (threaded_)
  for (int r = 0; r < n; ++r)
    std::copy(slot_val_.begin() + 9 * static_cast<std::ptrdiff_t>(slot_begin_[r]),
              slot_val_.begin() + 9 * static_cast<std::ptrdiff_t>(slot_end_[r]),
              l_.begin() + 9 * static_cast<std::ptrdiff_t>(row_begin_[r]));
}

int IncompleteCholesky::colourOfRow(int factor_row) const {
  int c = 0;
  while (c + 1 < numColours() && group_row_[colour_begin_[c + 1]] <= factor_row) ++c;
  return c;
}

bool IncompleteCholesky::factorRows(int begin, int end, double shift) {
  for (int i = begin; i < end; ++i) {
    const int di = row_begin_[i + 1] - 1;
    if (shift > 0)
      for (int k = 0; k < 3; ++k) l_[9 * static_cast<std::size_t>(di) + 4 * k] *= 1 + shift;
    for (int kk = row_begin_[i]; kk <= di; ++kk) {
      const int k = col_[kk];
      double* s = l_.data() + 9 * static_cast<std::size_t>(kk);
      // S = A_ik − Σ_j L_ij L_kjᵀ over the columns j < k that rows i and k share.
      int p = row_begin_[i], q = row_begin_[k];
      const int qe = row_begin_[k + 1] - 1;
      while (p < kk && q < qe) {
        if (col_[p] == col_[q]) {
          subtractABt(s, l_.data() + 9 * static_cast<std::size_t>(p),
                      l_.data() + 9 * static_cast<std::size_t>(q));
          ++p, ++q;
        } else if (col_[p] < col_[q]) {
          ++p;
        } else {
          ++q;
        }
      }
      if (kk < di) {
        double t[9];
        std::copy(s, s + 9, t);
        multiplyABt(s, t, dinv_.data() + 9 * static_cast<std::size_t>(k));  // S L_kk⁻ᵀ
      } else if (!invertedCholesky(s, dinv_.data() + 9 * static_cast<std::size_t>(i))) {
        return false;
      }
    }
  }
  return true;
}

void IncompleteCholesky::apply(const double* r, double* z) const {
  const int colours = numColours();
  double* w = work_.data();
#pragma omp parallel if (threaded_)
  {
    // L y = P r, row by row.
    for (int c = 0; c < colours; ++c) {
#pragma omp for schedule(dynamic, 1)
      for (int g = colour_begin_[c]; g < colour_begin_[c + 1]; ++g)
        for (int i = group_row_[g]; i < group_row_[g + 1]; ++i) {
          const double* ri = r + 3 * static_cast<std::ptrdiff_t>(iperm_[i]);
          double s0 = ri[0], s1 = ri[1], s2 = ri[2];
          const int di = row_begin_[i + 1] - 1;
          for (int kk = row_begin_[i]; kk < di; ++kk) {
            const double* l = l_.data() + 9 * static_cast<std::size_t>(kk);
            const double* wj = w + 3 * static_cast<std::ptrdiff_t>(col_[kk]);
            s0 -= l[0] * wj[0] + l[1] * wj[1] + l[2] * wj[2];
            s1 -= l[3] * wj[0] + l[4] * wj[1] + l[5] * wj[2];
            s2 -= l[6] * wj[0] + l[7] * wj[1] + l[8] * wj[2];
          }
          const double* d = dinv_.data() + 9 * static_cast<std::size_t>(i);
          w[3 * i] = d[0] * s0;
          w[3 * i + 1] = d[3] * s0 + d[4] * s1;
          w[3 * i + 2] = d[6] * s0 + d[7] * s1 + d[8] * s2;
        }
    }
    // Lᵀ x = y, rows in reverse: a row gathers what the later groups' rows owe it, then
    // scatters its own blocks into its group's earlier rows.
    for (int c = colours - 1; c >= 0; --c) {
#pragma omp for schedule(dynamic, 1)
      for (int g = colour_begin_[c]; g < colour_begin_[c + 1]; ++g)
        for (int i = group_row_[g + 1] - 1; i >= group_row_[g]; --i) {
          double s0 = w[3 * i], s1 = w[3 * i + 1], s2 = w[3 * i + 2];
          for (int p = cross_begin_[i]; p < cross_begin_[i + 1]; ++p) {
            const double* l = l_.data() + 9 * static_cast<std::size_t>(cross_block_[p]);
            const double* xj = w + 3 * static_cast<std::ptrdiff_t>(cross_row_[p]);
            s0 -= l[0] * xj[0] + l[3] * xj[1] + l[6] * xj[2];
            s1 -= l[1] * xj[0] + l[4] * xj[1] + l[7] * xj[2];
            s2 -= l[2] * xj[0] + l[5] * xj[1] + l[8] * xj[2];
          }
          const double* d = dinv_.data() + 9 * static_cast<std::size_t>(i);
          const double t0 = d[0] * s0 + d[3] * s1 + d[6] * s2;
          const double t1 = d[4] * s1 + d[7] * s2;
          const double t2 = d[8] * s2;
          double* zi = z + 3 * static_cast<std::ptrdiff_t>(iperm_[i]);
          zi[0] = w[3 * i] = t0;
          zi[1] = w[3 * i + 1] = t1;
          zi[2] = w[3 * i + 2] = t2;
          const int di = row_begin_[i + 1] - 1;
          for (int kk = own_begin_[i]; kk < di; ++kk) {
            const double* l = l_.data() + 9 * static_cast<std::size_t>(kk);
            double* wj = w + 3 * static_cast<std::ptrdiff_t>(col_[kk]);
            wj[0] -= l[0] * t0 + l[3] * t1 + l[6] * t2;
            wj[1] -= l[1] * t0 + l[4] * t1 + l[7] * t2;
            wj[2] -= l[2] * t0 + l[5] * t1 + l[8] * t2;
          }
        }
    }
  }
}

}  // namespace activefoam
