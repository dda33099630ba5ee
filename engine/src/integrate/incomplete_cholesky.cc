#include "activefoam/incomplete_cholesky.h"

#include <algorithm>
#include <cmath>
#include <numeric>

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

bool IncompleteCholesky::factor(int num_blocks, const BlockSource& blocks) {
  n_ = 0;
  shift_ = 0;
  const int n = num_blocks;
  // Bucket the blocks by lower-triangle row; each row's repeats are summed below, in the order
  // the source gave them. The buffers are members: a step's ~10⁵ blocks are tens of MB, which
  // freshly allocated (and zeroed, and faulted in) every step cost more than their reuse.
  std::vector<int>& begin = begin_;
  begin.assign(n + 1, 0);
  bool in_range = true;
  blocks([&](int i, int j, const Eigen::Matrix3d&) {
    if (i < 0 || j < 0 || i >= n || j >= n)
      in_range = false;
    else
      ++begin[std::max(i, j) + 1];
  });
  if (!in_range) return false;
  std::partial_sum(begin.begin(), begin.end(), begin.begin());
  std::vector<int>& fill = fill_;
  std::vector<int>& cols = cols_;
  std::vector<double>& vals = vals_;
  fill.assign(begin.begin(), begin.end() - 1);
  cols.resize(begin[n]);
  vals.resize(9 * static_cast<std::size_t>(begin[n]));
  blocks([&](int i, int j, const Eigen::Matrix3d& m) {
    if (i < 0 || j < 0 || i >= n || j >= n) return;
    const int row = std::max(i, j);
    const int pos = fill[row]++;
    cols[pos] = std::min(i, j);
    double* v = vals.data() + 9 * static_cast<std::size_t>(pos);
    // Stored as A_(row, col): the block itself when i is the row, its transpose otherwise.
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 3; ++c) v[3 * r + c] = i >= j ? m(r, c) : m(c, r);
  });
  row_begin_.assign(n + 1, 0);
  col_.clear();  // capacity kept: the next step's pattern is about as large
  a_.clear();
  // A row's blocks repeat (a vertex pair is in many contact pairs): sum them into one slot per
  // column in the order given, then sort the few distinct columns.
  std::vector<int>& slot_of = slot_of_;
  std::vector<int>& slots = slots_;
  std::vector<double>& sums = sums_;
  slot_of.assign(n, -1);
  for (int i = 0; i < n; ++i) {
    slots.clear();
    sums.clear();
    for (int p = begin[i]; p < begin[i + 1]; ++p) {
      const double* v = vals.data() + 9 * static_cast<std::size_t>(p);
      int& s = slot_of[cols[p]];
      if (s < 0) {
        s = static_cast<int>(slots.size());
        slots.push_back(cols[p]);
        sums.insert(sums.end(), v, v + 9);
      } else {
        double* w = sums.data() + 9 * static_cast<std::size_t>(s);
        for (int k = 0; k < 9; ++k) w[k] += v[k];
      }
    }
    std::vector<int>& order = scratch_;
    order.resize(slots.size());
    std::iota(order.begin(), order.end(), 0);
    std::sort(order.begin(), order.end(), [&](int p, int q) { return slots[p] < slots[q]; });
    for (int s : order) {
      col_.push_back(slots[s]);
      a_.insert(a_.end(), sums.data() + 9 * static_cast<std::size_t>(s),
                sums.data() + 9 * static_cast<std::size_t>(s) + 9);
      slot_of[slots[s]] = -1;
    }
    row_begin_[i + 1] = static_cast<int>(col_.size());
    if (row_begin_[i + 1] == row_begin_[i] || col_.back() != i) return false;  // no diagonal
  }
  dinv_.assign(9 * static_cast<std::size_t>(n), 0.0);
  for (double shift = 0; shift <= 1; shift = shift == 0 ? 1e-3 : 2 * shift) {
    l_ = a_;
    bool ok = true;
    for (int i = 0; i < n && ok; ++i) {
      const int di = row_begin_[i + 1] - 1;
      if (shift > 0)
        for (int k = 0; k < 3; ++k) l_[9 * di + 4 * k] *= 1 + shift;
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
          ok = false;
        }
      }
    }
    if (ok) {
      n_ = n;
      shift_ = shift;
      return true;
    }
  }
  return false;
}

void IncompleteCholesky::apply(const double* r, double* z) const {
  // L y = r, row by row.
  for (int i = 0; i < n_; ++i) {
    double s0 = r[3 * i], s1 = r[3 * i + 1], s2 = r[3 * i + 2];
    const int di = row_begin_[i + 1] - 1;
    for (int kk = row_begin_[i]; kk < di; ++kk) {
      const double* l = l_.data() + 9 * static_cast<std::size_t>(kk);
      const double* zj = z + 3 * static_cast<std::ptrdiff_t>(col_[kk]);
      s0 -= l[0] * zj[0] + l[1] * zj[1] + l[2] * zj[2];
      s1 -= l[3] * zj[0] + l[4] * zj[1] + l[5] * zj[2];
      s2 -= l[6] * zj[0] + l[7] * zj[1] + l[8] * zj[2];
    }
    const double* d = dinv_.data() + 9 * static_cast<std::size_t>(i);
    z[3 * i] = d[0] * s0;
    z[3 * i + 1] = d[3] * s0 + d[4] * s1;
    z[3 * i + 2] = d[6] * s0 + d[7] * s1 + d[8] * s2;
  }
  // Lᵀ z = y, rows in reverse, each scattering its column.
  for (int i = n_ - 1; i >= 0; --i) {
    const double* d = dinv_.data() + 9 * static_cast<std::size_t>(i);
    const double y0 = z[3 * i], y1 = z[3 * i + 1], y2 = z[3 * i + 2];
    const double t0 = d[0] * y0 + d[3] * y1 + d[6] * y2;
    const double t1 = d[4] * y1 + d[7] * y2;
    const double t2 = d[8] * y2;
    z[3 * i] = t0, z[3 * i + 1] = t1, z[3 * i + 2] = t2;
    const int di = row_begin_[i + 1] - 1;
    for (int kk = row_begin_[i]; kk < di; ++kk) {
      const double* l = l_.data() + 9 * static_cast<std::size_t>(kk);
      double* zj = z + 3 * static_cast<std::ptrdiff_t>(col_[kk]);
      zj[0] -= l[0] * t0 + l[3] * t1 + l[6] * t2;
      zj[1] -= l[1] * t0 + l[4] * t1 + l[7] * t2;
      zj[2] -= l[2] * t0 + l[5] * t1 + l[8] * t2;
    }
  }
}

}  // namespace activefoam
