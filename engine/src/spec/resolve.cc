// Resolution of a spec to what runs: reduced parameters to absolute ones, an accuracy target to
// its preset, and every derived default (τ_K, τ_r, Δt_min, ξ⊥/ξ∥, the initial gap) with the
// physical quantities they come from (Table 2 of the supplement).
#include "activefoam/spec.h"

#include <algorithm>
#include <cmath>
#include <cstdint>

#include "spec_internal.h"

namespace activefoam {

namespace spec_internal {

// Derived quantities without any checks (resolve's arithmetic).
SceneSpec resolveUnchecked(const SceneSpec& spec) {
  SceneSpec r = spec;
  if (r.accuracy.any()) {
    if (const auto p = presetForTarget(r.accuracy)) applyPreset(r.numerics, *p);
  }
  CellParams& c = r.cells;
  if (c.tau_gamma_s) {
    c.eta = *c.tau_gamma_s * c.gamma;
    c.tau_gamma_s.reset();
  }
  if (c.pa_reduced) {
    c.p_a = *c.pa_reduced * 2.0 * c.gamma / c.radius_mean_um;
    c.pa_reduced.reset();
  }
  if (c.l_eta_reduced) {
    const double l_eta = *c.l_eta_reduced * c.radius_mean_um;
    c.xi = c.eta / (l_eta * l_eta);
    c.l_eta_reduced.reset();
  }
  if (!c.tau_k_s) c.tau_k_s = defaultTauKS(c);
  if (!r.numerics.remesh_every_s) r.numerics.remesh_every_s = defaultRemeshEveryS(c);
  c.tau_shell_s.reset();  // what it gives is in τ_K and τ_r now
  if (!r.scene_params.gap_um) r.scene_params.gap_um = defaultGapUm(c);
  if (!r.numerics.dt_min_s) r.numerics.dt_min_s = defaultDtMinS(r.numerics.dt_s);
  if (!c.xi_normal) c.xi_normal = c.xi;
  if (!c.xi_tangential) c.xi_tangential = c.xi;
  // The preparation's values resolve as the run's would (an L_η/r of its own derives its ξ, ξ⊥
  // and ξ∥; a γ of its own its τ_K): what is left are those that differ from the run's.
  if (!spec.prepare.empty()) {
    const SceneSpec prep = resolveUnchecked(withPrepareValues(spec));
    r.prepare.clear();
    for (const Entry& e : entries()) {
      if (e.field.prep != SpecField::Prep::Kept) continue;
      const std::optional<SpecValue> v = getField(prep, e.field.key);
      if (v && v != getField(r, e.field.key)) r.prepare[e.field.key] = *v;
    }
  }
  return r;
}

}  // namespace spec_internal

// ---- resolve and derived quantities ------------------------------------------------------------

SceneSpec withPrepareValues(const SceneSpec& spec) {
  SceneSpec p = spec;
  p.prepare.clear();
  for (const auto& [key, value] : spec.prepare) (void)setField(p, key, value);  // validate()d
  return p;
}

SceneSpec resolve(const SceneSpec& spec) {
  return spec_internal::resolveUnchecked(spec);
}

std::int64_t sceneCellCount(const SceneSpec& spec) {
  const SceneParams& p = spec.scene_params;
  switch (spec.scene) {
    case SceneKind::Cell:
      return 1;
    case SceneKind::Doublet:
      return 2;
    case SceneKind::Spheroid:
      return p.n_cells;
    case SceneKind::Fusion:
      return (p.n_cells_a > 0 ? p.n_cells_a : p.n_cells) +
             (p.n_cells_b > 0 ? p.n_cells_b : p.n_cells);
  }
  return 0;
}

double tauShell(const CellParams& c) {
  return c.tau_shell_s.value_or(c.eta / (2.0 * std::sqrt(3.0) * c.gamma));
}
double adhesionW(const CellParams& c) {
  return (1.0 - c.alpha) * c.gamma;
}

double contactRangeH0(const CellParams& c) {
  return std::sqrt(adhesionW(c) / c.k_contact);
}
double defaultGapUm(const CellParams& c) {
  return std::min(0.05, 0.8 * contactRangeH0(c));
}

double initialGapUm(const SceneSpec& spec) {
  return spec.scene_params.gap_um.value_or(defaultGapUm(spec.cells));
}

// ---- derived defaults (spec.h: each is computed here only) ------------------------------------

double defaultTauKS(const CellParams& c) {
  return 2.0 * tauShell(c);
}
double defaultRemeshEveryS(const CellParams& c) {
  return 5.0 * tauShell(c);
}
double defaultDtMinS(double dt_s) {
  return dt_s / 64;
}
double tauKS(const CellParams& c) {
  return c.tau_k_s.value_or(defaultTauKS(c));
}
double remeshEveryS(const SceneSpec& spec) {
  return spec.numerics.remesh_every_s.value_or(defaultRemeshEveryS(spec.cells));
}
double dtMinS(const NumericsParams& n) {
  return n.dt_min_s.value_or(defaultDtMinS(n.dt_s));
}

}  // namespace activefoam
