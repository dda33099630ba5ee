#include "activefoam/velocity_solver.h"

#include <limits>

#include "activefoam/spec.h"

namespace activefoam {

VelocitySolver::VelocitySolver(const NumericsParams& n)
    : solver_(n.preconditioner, n.cg_tol, static_cast<int>(n.cg_max_iter)),
      preconditioner_(n.preconditioner) {}

double VelocitySolver::computeForces(const StepContext& ctx, const ForceTerms& terms,
                                     Eigen::Matrix3Xd& f) const {
  f.setZero(3, ctx.cells.numVertices());
  double energy = 0;
  for (const auto& term : terms) energy += term->addForces(ctx, f);
  return energy;
}

void VelocitySolver::prepareFriction(const StepContext& ctx, const ForceTerms& terms) {
  op_.reset(ctx.cells.numVertices(), ctx.cells.topology_version);
  if (preconditioner_ == PreconditionerKind::IncompleteCholesky)
    cell_vertex_begin_ = ctx.cells.cell_vertex_begin;  // the factor's groups (solve())
  for (const auto& term : terms) term->addFriction(ctx, op_);
}

void VelocitySolver::applyFriction(const double* v, double* y) const {
  op_.apply(v, y);
}

void VelocitySolver::forEachFrictionBlock(const BlockSink& sink) const {
  op_.forEachBlock(sink);
}

SolveStats VelocitySolver::solve(const Eigen::Matrix3Xd& f, Eigen::VectorXd& v, bool reuse_factor) {
  Eigen::Map<const Eigen::VectorXd> b(f.data(), f.size());
  const IncompleteCholesky* factor = nullptr;
  if (preconditioner_ == PreconditionerKind::IncompleteCholesky) {
    if (!reuse_factor || factor_.numBlocks() != op_.numBlocks()) {
      // The cells are the factor's groups: its triangular solves run the cells of one colour
      // (no two of them in contact) in parallel.
      const bool ok = factor_.factor(
          op_.numBlocks(), [this](const BlockSink& sink) { forEachFrictionBlock(sink); },
          cell_vertex_begin_);
      if (!ok) {
        // Γ is SPD whenever the step is sane; a factor that breaks down at every shift means
        // non-finite entries, which the CG guard reports.
        SolveStats s;
        s.residual = std::numeric_limits<double>::quiet_NaN();
        return s;
      }
    }
    factor = &factor_;
  }
  return solver_.solve([this](const double* in, double* out) { applyFriction(in, out); },
                       op_.diagonal(), b, v, factor);
}

}  // namespace activefoam
