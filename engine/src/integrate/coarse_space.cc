#include "activefoam/coarse_space.h"

#include <algorithm>
#include <cmath>

namespace activefoam {

namespace {

constexpr int kMax = 7;
using Modes = Eigen::Matrix<double, 3, kMax>;  // a vertex's velocity in its cell's modes
using Block = Eigen::Matrix<double, kMax, kMax>;

// Velocity of a vertex at r (from its cell's centroid, over the cell's scale) in each mode:
// translations, rotations ω × r, dilation r.
Modes modesAt(const Eigen::Vector3d& r) {
  Modes p = Modes::Zero();
  p(0, 0) = p(1, 1) = p(2, 2) = 1;
  p(1, 3) = -r.z(), p(2, 3) = r.y();  // e_x × r
  p(0, 4) = r.z(), p(2, 4) = -r.x();  // e_y × r
  p(0, 5) = -r.y(), p(1, 5) = r.x();  // e_z × r
  p.col(6) = r;
  return p;
}

}  // namespace

bool RigidCoarseSpace::build(const Eigen::Matrix3Xd& x, const std::vector<int>& cell_vertex_begin,
                             bool dilation, const BlockSource& blocks) {
  modes_ = dilation ? 7 : 6;
  begin_ = cell_vertex_begin;
  const int nc = static_cast<int>(begin_.size()) - 1;
  const int nv = static_cast<int>(x.cols());
  cell_of_.assign(nv, 0);
  r_.resize(3, nv);
  for (int c = 0; c < nc; ++c) {
    const int b = begin_[c], e = begin_[c + 1];
    Eigen::Vector3d centroid = Eigen::Vector3d::Zero();
    for (int i = b; i < e; ++i) centroid += x.col(i);
    centroid /= std::max(1, e - b);
    double r2 = 0;
    for (int i = b; i < e; ++i) r2 += (x.col(i) - centroid).squaredNorm();
    // The rotations' and the dilation's columns scaled to the translations' (a cell of unit
    // scale): A_c's diagonal then spans a few orders of magnitude, not the cell radius squared.
    const double scale = r2 > 0 ? std::sqrt(r2 / (e - b)) : 1;
    for (int i = b; i < e; ++i) {
      cell_of_[i] = c;
      r_.col(i) = (x.col(i) - centroid) / scale;
    }
  }
  // A_c's blocks: each cell's own, and one per pair of cells that A couples (c < d).
  std::vector<Block> own(nc, Block::Zero());
  std::vector<std::vector<std::pair<int, Block>>> cross(nc);
  auto crossBlock = [&](int c, int d) -> Block& {
    for (auto& [k, m] : cross[c])
      if (k == d) return m;
    cross[c].emplace_back(d, Block::Zero());
    return cross[c].back().second;
  };
  blocks([&](int i, int j, const Eigen::Matrix3d& m) {
    const Modes pi = modesAt(r_.col(i));
    if (i == j) {
      own[cell_of_[i]].noalias() += pi.transpose() * m * pi;
      return;
    }
    const Modes pj = modesAt(r_.col(j));
    const Block g = pi.transpose() * m * pj;
    const int ci = cell_of_[i], cj = cell_of_[j];
    if (ci == cj)
      own[ci] += g + g.transpose();
    else if (ci < cj)
      crossBlock(ci, cj) += g;
    else
      crossBlock(cj, ci) += g.transpose();
  });
  const int k = modes_;
  std::vector<Eigen::Triplet<double>> t;
  for (int c = 0; c < nc; ++c) {
    for (int p = 0; p < k; ++p)
      for (int q = 0; q < k; ++q) t.emplace_back(k * c + p, k * c + q, own[c](p, q));
    for (const auto& [d, m] : cross[c])
      for (int p = 0; p < k; ++p)
        for (int q = 0; q < k; ++q) {
          t.emplace_back(k * c + p, k * d + q, m(p, q));
          t.emplace_back(k * d + q, k * c + p, m(p, q));
        }
  }
  a_.resize(k * nc, k * nc);
  a_.setFromTriplets(t.begin(), t.end());
  llt_.compute(a_);
  ready_ = llt_.info() == Eigen::Success;
  rhs_.resize(k * nc);
  sol_.resize(k * nc);
  return ready_;
}

void RigidCoarseSpace::addCorrection(const double* r, double* z) const {
  if (!ready_) return;
  const int nc = static_cast<int>(begin_.size()) - 1;
  const int k = modes_;
  // Pᵀ r, cell by cell in vertex order (the same sums for any thread count).
  for (int c = 0; c < nc; ++c) {
    Eigen::Matrix<double, kMax, 1> s = Eigen::Matrix<double, kMax, 1>::Zero();
    for (int i = begin_[c]; i < begin_[c + 1]; ++i)
      s.noalias() += modesAt(r_.col(i)).transpose() * Eigen::Map<const Eigen::Vector3d>(r + 3 * i);
    rhs_.segment(k * c, k) = s.head(k);
  }
  sol_ = llt_.solve(rhs_);
  for (int c = 0; c < nc; ++c) {
    Eigen::Matrix<double, kMax, 1> w = Eigen::Matrix<double, kMax, 1>::Zero();
    w.head(k) = sol_.segment(k * c, k);
    for (int i = begin_[c]; i < begin_[c + 1]; ++i)
      Eigen::Map<Eigen::Vector3d>(z + 3 * i) += modesAt(r_.col(i)) * w;
  }
}

}  // namespace activefoam
