// The coarse level of a two-level preconditioner for the velocity solve: each cell's rigid
// motions (three translations, three rotations about its centroid, and optionally its uniform
// dilation). Block-Jacobi sees each vertex alone, while the slowest modes of Γ are cell-scale —
// cells sliding, turning and pressing on each other through friction and contact — so CG spends
// most of its iterations on them. With P the vertices' velocities in each cell's rigid motions,
// the coarse operator A_c = Pᵀ A P has 6 (or 7) unknowns a cell; it is assembled from A's blocks
// in one pass and factorised once a solve, and the preconditioner adds P A_c⁻¹ Pᵀ r to
// block-Jacobi's z (additive two-level: symmetric positive definite, so CG's theory holds).
#pragma once

#include <Eigen/Core>
#include <Eigen/SparseCholesky>
#include <Eigen/SparseCore>
#include <functional>
#include <vector>

#include "activefoam/block_matrix.h"

namespace activefoam {

class RigidCoarseSpace {
 public:
  // Calls its argument with a sink that receives A's blocks: (i, i) the diagonal ones, (i, j),
  // i ≠ j, the off-diagonal ones with A_ji = A_ijᵀ implied (a pair may come more than once).
  using BlockSource = std::function<void(const BlockSink&)>;

  // Builds and factorises A_c for the vertices at `x` grouped into cells by `cell_vertex_begin`
  // (cell c owns [begin[c], begin[c+1])). `dilation` adds each cell's uniform expansion to its
  // six rigid motions. Deterministic: one pass in the order the source gives the blocks.
  // Returns false (and the correction is then zero) when A_c is not positive definite.
  bool build(const Eigen::Matrix3Xd& x, const std::vector<int>& cell_vertex_begin, bool dilation,
             const BlockSource& blocks);
  // z += P A_c⁻¹ Pᵀ r (r and z: 3 × vertices, packed).
  void addCorrection(const double* r, double* z) const;
  bool ready() const { return ready_; }
  int unknowns() const { return static_cast<int>(rhs_.size()); }

 private:
  int modes_ = 6;
  bool ready_ = false;
  std::vector<int> begin_;
  std::vector<int> cell_of_;       // vertex → cell
  Eigen::Matrix3Xd r_;             // vertex − its cell's centroid, over the cell's scale
  Eigen::SparseMatrix<double> a_;  // A_c, lower and upper triangles
  Eigen::SimplicialLLT<Eigen::SparseMatrix<double>> llt_;
  mutable Eigen::VectorXd rhs_, sol_;
};

}  // namespace activefoam
