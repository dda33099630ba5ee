#include "activefoam/block_matrix.h"

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <stdexcept>

#include "activefoam/threads.h"

namespace activefoam {

void BlockMatrix::setPattern(int num_blocks, std::vector<std::pair<int, int>> couplings) {
  n_ = num_blocks;
  // Bucket by row, then sort each short row: a global sort of the ~10⁶ couplings of a 2 × 100-cell
  // aggregate was 15 % of a step whenever a remesh forced a rebuild. Threaded (the rebuild follows
  // every remesh): couplings counted and scattered over per-thread ranges, rows sorted and laid
  // out in parallel. Integers only, and rows are sorted: the pattern does not depend on the split.
  const auto m = static_cast<std::int64_t>(couplings.size());
  const bool parallel = m > grain().min_items;
  const int R = parallel ? threads() : 1;
  const auto range = [&](int r) {
    return std::pair<std::int64_t, std::int64_t>{m * r / R, m * (r + 1) / R};
  };
  const std::size_t stride = static_cast<std::size_t>(n_) + 1;
  // count[r · stride + i + 1]: row i's entries from range r; then where range r writes them.
  std::vector<int> count(static_cast<std::size_t>(R) * stride, 0);
#pragma omp parallel for schedule(static, 1) if (parallel)
  for (int r = 0; r < R; ++r) {
    int* c = &count[r * stride + 1];
    const auto [b, e] = range(r);
    for (std::int64_t q = b; q < e; ++q) {
      ++c[couplings[q].first];
      ++c[couplings[q].second];
    }
  }
  std::vector<int> start(stride, 0);
  std::vector<int> all;
  {
    int at = 0;
    for (int i = 0; i < n_; ++i) {
      start[i] = at;
      ++at;  // the diagonal
      for (int r = 0; r < R; ++r) {
        int& slot = count[r * stride + i + 1];
        const int k = slot;
        slot = at;
        at += k;
      }
    }
    start[n_] = at;
    all.resize(static_cast<std::size_t>(at));
  }
#pragma omp parallel for schedule(static, 1) if (parallel)
  for (int r = 0; r < R; ++r) {
    int* next = &count[r * stride + 1];
    const auto [b, e] = range(r);
    for (std::int64_t q = b; q < e; ++q) {
      const auto [i, j] = couplings[q];
      all[next[i]++] = j;
      all[next[j]++] = i;
    }
  }
  couplings.clear();
  couplings.shrink_to_fit();
  row_begin_.assign(stride, 0);
#pragma omp parallel for schedule(static) if (parallel)
  for (int i = 0; i < n_; ++i) {
    const auto first = all.begin() + start[i], last = all.begin() + start[i + 1];
    *first = i;
    std::sort(first, last);
    row_begin_[i + 1] = static_cast<int>(std::unique(first, last) - first);
  }
  for (int i = 0; i < n_; ++i) row_begin_[i + 1] += row_begin_[i];
  cols_.resize(static_cast<std::size_t>(row_begin_[n_]));
  offset_.resize(cols_.size());
  width_.resize(cols_.size());
  diag_.resize(n_);
  transpose_.resize(cols_.size());

  // Scalar CSR: row 3i+a holds, for each block k of block-row i, columns 3·cols_[k] + {0,1,2};
  // block-row i's 3 rows of 3·nb entries start at 9 · row_begin_[i].
  const Eigen::Index nnz = 9 * static_cast<Eigen::Index>(cols_.size());
  a_.resize(3 * n_, 3 * n_);
  a_.resizeNonZeros(nnz);
  auto* outer = a_.outerIndexPtr();
  auto* inner = a_.innerIndexPtr();
#pragma omp parallel for schedule(static) if (parallel)
  for (int i = 0; i < n_; ++i) {
    const int kb = row_begin_[i], nb = row_begin_[i + 1] - kb;
    std::copy(all.begin() + start[i], all.begin() + start[i] + nb, cols_.begin() + kb);
    Eigen::Index pos = 9 * static_cast<Eigen::Index>(kb);
    for (int k = kb; k < kb + nb; ++k) {
      offset_[k] = pos + 3 * (k - kb);
      width_[k] = 3 * nb;
      if (cols_[k] == i) diag_[i] = k;
    }
    for (int r = 0; r < 3; ++r) {
      outer[3 * i + r] = static_cast<SpMat::StorageIndex>(pos);
      for (int k = kb; k < kb + nb; ++k)
        for (int c = 0; c < 3; ++c) inner[pos++] = 3 * cols_[k] + c;
    }
  }
  outer[3 * n_] = static_cast<SpMat::StorageIndex>(nnz);
#pragma omp parallel for schedule(static) if (parallel)
  for (int i = 0; i < n_; ++i)
    for (int k = row_begin_[i]; k < row_begin_[i + 1]; ++k) transpose_[k] = findBlock(cols_[k], i);
  diagonal_only_ = static_cast<int>(cols_.size()) == n_;
  setZero();
}

void BlockMatrix::setZero() {
  // ~10⁶ values on the 2 × 100-cell aggregate: a memory-bound fill that two cores share.
  double* v = a_.valuePtr();
  const std::int64_t nnz = a_.nonZeros(), chunk = 1 << 16;
  const std::int64_t chunks = (nnz + chunk - 1) / chunk;
#pragma omp parallel for schedule(static) if (chunks > 1)
  for (std::int64_t j = 0; j < chunks; ++j)
    std::fill(v + j * chunk, v + std::min(nnz, (j + 1) * chunk), 0.0);
}

void BlockMatrix::multiply(const double* x, double* y) const {
  const double* v = a_.valuePtr();
  if (diagonal_only_) {  // the general loop's sums, in its order
#pragma omp parallel for schedule(static) if (n_ > grain().min_items)
    for (int i = 0; i < n_; ++i) {
      const double* b = v + 9 * static_cast<std::ptrdiff_t>(i);
      const double* xi = x + 3 * static_cast<std::ptrdiff_t>(i);
      double* yi = y + 3 * static_cast<std::ptrdiff_t>(i);
      yi[0] = b[0] * xi[0] + b[1] * xi[1] + b[2] * xi[2];
      yi[1] = b[3] * xi[0] + b[4] * xi[1] + b[5] * xi[2];
      yi[2] = b[6] * xi[0] + b[7] * xi[1] + b[8] * xi[2];
    }
    return;
  }
  // Rows are independent and each is summed in its own fixed order: any split gives the same
  // bits.
#pragma omp parallel for schedule(static) if (n_ > grain().min_items)
  for (int i = 0; i < n_; ++i) {
    const int kb = row_begin_[i], ke = row_begin_[i + 1];
    const int w = 3 * (ke - kb);
    const double* r0 = v + offset_[kb];
    const double* r1 = r0 + w;
    const double* r2 = r1 + w;
    double y0 = 0, y1 = 0, y2 = 0;
    for (int k = kb; k < ke; ++k, r0 += 3, r1 += 3, r2 += 3) {
      const double* xj = x + 3 * static_cast<std::ptrdiff_t>(cols_[k]);
      y0 += r0[0] * xj[0] + r0[1] * xj[1] + r0[2] * xj[2];
      y1 += r1[0] * xj[0] + r1[1] * xj[1] + r1[2] * xj[2];
      y2 += r2[0] * xj[0] + r2[1] * xj[1] + r2[2] * xj[2];
    }
    y[3 * i] = y0;
    y[3 * i + 1] = y1;
    y[3 * i + 2] = y2;
  }
}

Eigen::Matrix3d BlockMatrix::diagonalBlock(int i) const {
  const int k = diag_[i];
  const double* b = a_.valuePtr() + offset_[k];
  Eigen::Matrix3d m;
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) m(r, c) = b[r * width_[k] + c];
  return m;
}

void BlockMatrix::forEachLowerBlock(const BlockSink& sink) const {
  Eigen::Matrix3d m;
  for (int i = 0; i < n_; ++i)
    for (int k = row_begin_[i]; k < row_begin_[i + 1] && cols_[k] <= i; ++k) {
      const double* b = a_.valuePtr() + offset_[k];
      for (int r = 0; r < 3; ++r)
        for (int c = 0; c < 3; ++c) m(r, c) = b[r * width_[k] + c];
      sink(i, cols_[k], m);
    }
}

int BlockMatrix::findBlock(int i, int j) const {
  const auto first = cols_.begin() + row_begin_[i], last = cols_.begin() + row_begin_[i + 1];
  const auto it = std::lower_bound(first, last, j);
  if (it == last || *it != j) throw std::logic_error("BlockMatrix: block outside the pattern");
  return static_cast<int>(it - cols_.begin());
}

namespace {
template <int Sign>
inline void addTo(double* row0, int width, const Eigen::Matrix3d& m) {
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) row0[r * width + c] += Sign * m(r, c);
}
}  // namespace

void BlockMatrix::addDiagonalInPattern(int i, const Eigen::Matrix3d& m) {
  const int k = diag_[i];
  addTo<1>(blockValues(k), width_[k], m);
}

void BlockMatrix::addCoupling(int i, int j, const Eigen::Matrix3d& m) {
  // m is symmetric for every dissipative term, so the (j, i) block is −m as well.
  const int kij = findBlock(i, j), kji = transpose_[kij], kii = diag_[i], kjj = diag_[j];
  addTo<1>(blockValues(kii), width_[kii], m);
  addTo<1>(blockValues(kjj), width_[kjj], m);
  addTo<-1>(blockValues(kij), width_[kij], m);
  addTo<-1>(blockValues(kji), width_[kji], m);
}

}  // namespace activefoam
