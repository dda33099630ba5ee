#include "activefoam/block_matrix.h"

#include <algorithm>
#include <stdexcept>

namespace activefoam {

void BlockMatrix::setPattern(int num_blocks, std::vector<std::pair<int, int>> couplings) {
  n_ = num_blocks;
  const size_t nc = couplings.size();
  for (size_t k = 0; k < nc; ++k) couplings.emplace_back(couplings[k].second, couplings[k].first);
  for (int i = 0; i < n_; ++i) couplings.emplace_back(i, i);
  std::sort(couplings.begin(), couplings.end());
  couplings.erase(std::unique(couplings.begin(), couplings.end()), couplings.end());

  row_begin_.assign(n_ + 1, 0);
  cols_.resize(couplings.size());
  for (size_t k = 0; k < couplings.size(); ++k) {
    row_begin_[couplings[k].first + 1]++;
    cols_[k] = couplings[k].second;
  }
  for (int i = 0; i < n_; ++i) row_begin_[i + 1] += row_begin_[i];

  // Scalar CSR: row 3i+a holds, for each block k of block-row i, columns 3·cols_[k] + {0,1,2}.
  const Eigen::Index nnz = 9 * static_cast<Eigen::Index>(cols_.size());
  a_.resize(3 * n_, 3 * n_);
  a_.resizeNonZeros(nnz);
  auto* outer = a_.outerIndexPtr();
  auto* inner = a_.innerIndexPtr();
  offset_.resize(cols_.size());
  width_.resize(cols_.size());
  diag_.resize(n_);
  Eigen::Index pos = 0;
  for (int i = 0; i < n_; ++i) {
    const int nb = row_begin_[i + 1] - row_begin_[i];
    for (int k = row_begin_[i]; k < row_begin_[i + 1]; ++k) {
      offset_[k] = pos + 3 * (k - row_begin_[i]);
      width_[k] = 3 * nb;
      if (cols_[k] == i) diag_[i] = k;
    }
    for (int r = 0; r < 3; ++r) {
      outer[3 * i + r] = static_cast<SpMat::StorageIndex>(pos);
      for (int k = row_begin_[i]; k < row_begin_[i + 1]; ++k)
        for (int c = 0; c < 3; ++c) inner[pos++] = 3 * cols_[k] + c;
    }
  }
  outer[3 * n_] = static_cast<SpMat::StorageIndex>(pos);
  transpose_.resize(cols_.size());
  for (int i = 0; i < n_; ++i)
    for (int k = row_begin_[i]; k < row_begin_[i + 1]; ++k) transpose_[k] = findBlock(cols_[k], i);
  setZero();
}

void BlockMatrix::setZero() {
  std::fill_n(a_.valuePtr(), a_.nonZeros(), 0.0);
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

void BlockMatrix::addDiagonal(int i, const Eigen::Matrix3d& m) {
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
