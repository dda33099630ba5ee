// Γ of one step (docs/model.md §6.1): diagonal 3×3 blocks, assembled, plus the vertex couplings
// of the terms that have them (cortex viscosity along mesh edges, contact friction across pairs),
// applied as products. The solver rebuilds it from the terms every step (ForceTerm::addFriction);
// the couplings' per-step data live here, not in the terms. Each coupling is one object whose
// blocks serve the product, the preconditioner and the assembly alike.
#pragma once

#include <cstdint>
#include <memory>
#include <vector>

#include <Eigen/Core>

#include "activefoam/block_matrix.h"

namespace activefoam {

// A term's couplings of one step: the off-diagonal blocks C_ij, i ≠ j, of Γ.
class Coupling {
 public:
  virtual ~Coupling() = default;
  // y += C v.
  virtual void addProduct(const double* v, double* y) const = 0;
  // C's blocks C_ij, i ≠ j (C_ji = C_ijᵀ implied; a vertex pair may come more than once, to be
  // summed), for a preconditioner or an assembly that needs them.
  virtual void forEachBlock(const BlockSink& sink) const = 0;
};

class FrictionOperator {
 public:
  // Starts this step's Γ on `num_vertices` vertices: the diagonal blocks zeroed (resized when the
  // topology changed), no coupling active.
  void reset(int num_vertices, std::uint64_t topology_version);
  BlockMatrix& diagonal() { return diagonal_; }
  const BlockMatrix& diagonal() const { return diagonal_; }
  // The coupling of `owner` (a term) for this step, active from now on: made on first use, then
  // the same object every step (its buffers reused). Products run in the order of first use.
  template <class C>
  C& coupling(const void* owner) {
    for (Slot& s : slots_)
      if (s.owner == owner) {
        s.active = true;
        return static_cast<C&>(*s.coupling);
      }
    slots_.push_back({owner, std::make_unique<C>(), true});
    return static_cast<C&>(*slots_.back().coupling);
  }
  int numBlocks() const { return diagonal_.numBlocks(); }
  void apply(const double* v, double* y) const;  // y = Γ v
  // Γ as blocks: the diagonal ones, then the couplings' (what the incomplete-Cholesky factor is
  // built from).
  void forEachBlock(const BlockSink& sink) const;
  // The whole Γ as one matrix (tests and tools).
  SpMat assembled() const;

 private:
  struct Slot {
    const void* owner;
    std::unique_ptr<Coupling> coupling;
    bool active;
  };
  BlockMatrix diagonal_;
  std::uint64_t version_ = ~std::uint64_t{0};
  std::vector<Slot> slots_;
};

}  // namespace activefoam
