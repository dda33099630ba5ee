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
  Eigen::Index pos = 0;
  for (int i = 0; i < n_; ++i) {
    for (int r = 0; r < 3; ++r) {
      outer[3 * i + r] = static_cast<SpMat::StorageIndex>(pos);
      for (int k = row_begin_[i]; k < row_begin_[i + 1]; ++k)
        for (int c = 0; c < 3; ++c) inner[pos++] = 3 * cols_[k] + c;
    }
  }
  outer[3 * n_] = static_cast<SpMat::StorageIndex>(pos);
  setZero();
}

void BlockMatrix::setZero() {
  std::fill_n(a_.valuePtr(), a_.nonZeros(), 0.0);
}

void BlockMatrix::addBlock(int i, int j, const Eigen::Matrix3d& m) {
  const auto first = cols_.begin() + row_begin_[i], last = cols_.begin() + row_begin_[i + 1];
  const auto it = std::lower_bound(first, last, j);
  if (it == last || *it != j) throw std::logic_error("BlockMatrix: block outside the pattern");
  const int k = static_cast<int>(it - first);
  const int width = 3 * (row_begin_[i + 1] - row_begin_[i]);
  double* row0 = a_.valuePtr() + a_.outerIndexPtr()[3 * i] + 3 * k;
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) row0[r * width + c] += m(r, c);
}

void BlockMatrix::addDiagonal(int i, const Eigen::Matrix3d& m) {
  addBlock(i, i, m);
}

void BlockMatrix::addCoupling(int i, int j, const Eigen::Matrix3d& m) {
  addBlock(i, i, m);
  addBlock(j, j, m);
  addBlock(i, j, -m);
  addBlock(j, i, -m.transpose());
}

}  // namespace activefoam
