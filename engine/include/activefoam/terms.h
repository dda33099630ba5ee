// The force terms that act within one cell (docs/model.md §2, §5).
#pragma once

#include <cmath>
#include <cstddef>
#include <vector>

#include "activefoam/force_term.h"
#include "activefoam/spec.h"

namespace activefoam {

// S2–S4: F_i += (γ_s/2)(x_k − x_j) × n̂_A = −γ_s ∂S_A/∂x_i. Energy Σ γ_s S_A.
// γ_s = γ − w f_A with f_A the contacting fraction of the triangle this step (ctx.contacts) and
// w = (1 − α) γ, so that a fully contacting triangle has γ_s = αγ (docs/model.md §3.1).
// With ctx.tension_stiffness_dt > 0 it adds to Γ that factor times the forces' out-of-plane
// stiffness: per edge ij, k_ij b̂b̂ᵀ with k_ij = ½ Σ γ_s cot θ over the two triangles' angles
// opposite the edge (the cotangent Laplacian, the Hessian of the area for displacements along
// the surface's normal; ≥ 0) and b̂ the edge's bisector, as a coupling (+ on the diagonal blocks
// of i and j, − across).
class SurfaceTension : public ForceTerm {
 public:
  explicit SurfaceTension(const CellParams& p) : gamma_(p.gamma), w_(adhesionW(p)) {}
  std::string_view name() const override { return "surface_tension"; }
  double addForces(const StepContext& ctx, Eigen::Matrix3Xd& f) const override;
  void addFriction(const StepContext& ctx, FrictionOperator& op) const override;

 private:
  double gamma_, w_;
};

// S5–S7: P_l = 2γ/r_l − K ε_l − (K/τ_K) I_l, F_i += P_l S_A n̂_A / 3. The integral I_l is
// advanced in endStep. Energy (with I_l frozen): −(2γ/r − K I/τ_K) V + K (V − V*)² / (2 V*).
class CytoplasmPressure : public ForceTerm {
 public:
  explicit CytoplasmPressure(const CellParams& p)
      : gamma_(p.gamma), k_(p.bulk_modulus), tau_k_(tauKS(p)) {}
  std::string_view name() const override { return "cytoplasm_pressure"; }
  double addForces(const StepContext& ctx, Eigen::Matrix3Xd& f) const override;
  void endStep(const StepContext& ctx, CellSet& cells) const override;
  double pressure(const CellSet& cells, const Geometry& geo, int c) const;

 private:
  double gamma_, k_, tau_k_;
};

// S12: Γ_ii += (3 η_m / (2 r_l)) S_i I.
class MediumDrag : public ForceTerm {
 public:
  explicit MediumDrag(const CellParams& p) : eta_m_(p.eta_m) {}
  std::string_view name() const override { return "medium_drag"; }
  void addFriction(const StepContext& ctx, FrictionOperator& op) const override;

 private:
  double eta_m_;
};

// S13: per edge ij, G = (η/√3)(n̂n̂ᵀ + t̂t̂ᵀ + ε_n b̂b̂ᵀ) as a coupling between i and j: +G on
// the diagonal blocks of i and j, −G across. The couplings are a product, edge by edge (32 bytes
// an edge): assembled, they were ~85 % of Γ's 2 M non-zeros on the 2 × 100 fusion, which every
// CG iteration streamed (docs/benchmarks.md, "6. Where a step goes").
class CortexViscosity : public ForceTerm {
 public:
  explicit CortexViscosity(const CellParams& p) : eps_n_(p.eps_n), g_(p.eta / std::sqrt(3.0)) {}
  std::string_view name() const override { return "cortex_viscosity"; }
  void addFriction(const StepContext& ctx, FrictionOperator& op) const override;

 private:
  double eps_n_, g_;
};

}  // namespace activefoam
