// The velocity solve of one step (docs/model.md §6.1): the force sum F, the friction operator Γ
// (FrictionOperator: assembled diagonal blocks + the terms' couplings applied as products) and
// preconditioned CG on Γ v = F. What Γ carries besides friction (Δt K_c, the contact springs'
// linearised stiffness) is the time scheme's choice, passed in the step context
// (StepContext::contact_stiffness_dt); terms never read the spec's Δt.
#pragma once

#include <cstdint>
#include <memory>
#include <vector>

#include <Eigen/Core>

#include "activefoam/block_matrix.h"
#include "activefoam/force_term.h"
#include "activefoam/friction_operator.h"
#include "activefoam/incomplete_cholesky.h"
#include "activefoam/solver.h"
#include "activefoam/spec_enums.h"

namespace activefoam {

struct NumericsParams;

using ForceTerms = std::vector<std::unique_ptr<ForceTerm>>;

class VelocitySolver {
 public:
  explicit VelocitySolver(const NumericsParams& numerics);

  // F = Σ terms' forces (3 × vertices); returns the sum of their energies.
  double computeForces(const StepContext& ctx, const ForceTerms& terms, Eigen::Matrix3Xd& f) const;
  // Γ of this step: pattern rebuilt when the topology changed, values overwritten.
  void prepareFriction(const StepContext& ctx, const ForceTerms& terms);
  // Γ's assembled part: its diagonal blocks.
  const BlockMatrix& frictionMatrix() const { return op_.diagonal(); }
  const FrictionOperator& friction() const { return op_; }
  void applyFriction(const double* v, double* y) const;  // y = Γ v
  // Γ as blocks: the assembled lower triangle, then the product's couplings (what the
  // incomplete-Cholesky factor is built from).
  void forEachFrictionBlock(const BlockSink& sink) const;
  // Solves Γ v = F; v holds the warm start on entry. With the incomplete-Cholesky
  // preconditioner the factor of this Γ is built first, unless `reuse_factor` asks for the one
  // of the previous solve (ros2's second stage, whose Γ* differs from Γ₀ by O(Δt)): nothing of
  // the factor outlives a step, so rollback and resume need not know about it.
  SolveStats solve(const Eigen::Matrix3Xd& f, Eigen::VectorXd& v, bool reuse_factor = false);

 private:
  FrictionOperator op_;
  LinearSolver solver_;
  PreconditionerKind preconditioner_;
  IncompleteCholesky factor_;
  std::vector<int> cell_vertex_begin_;  // of the cells Γ was prepared for
};

}  // namespace activefoam
