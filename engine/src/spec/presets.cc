// The fidelity presets (docs/science/presets.md): named numerics, their stated errors, and the
// choice of the cheapest one for an accuracy target.
#include "activefoam/spec.h"

#include <cstdint>
#include <optional>
#include <vector>

#include "spec_internal.h"

namespace activefoam {

using namespace spec_internal;

const std::vector<PresetInfo>& fidelityPresets() {
  // standard: the step the figure studies ran — one stage with the consistent stiffness of the
  //   contact springs (the cells' motion converged in Δt, docs/science/motion-convergence.md), Δt
  //   1 s, ε_CG 1e-2, the overlap within the triangles' prisms. Step fitness (10 seed pairs of
  //   the reduced base point, 4 h) found no difference from `reference` and none of its runs
  //   failed, at 3.1× less CPU a simulated hour. The adaptive step halves Δt where a step fails.
  // reference: the step it was judged against — Δt 0.25 s, ε_CG 1e-3, the supplement's law.
  // No cheaper step was found fit (Δt 0.5 s under the supplement's law failed a run; the
  // one-spring contact-implicit integrator under-resolves the motion at every Δt measured), so
  // there is no `draft`.
  // Stated errors on the doublet (tests/scenes/test_presets.cc: the contact angle against
  // arccos α, θ_c(t) against 1280 triangles at Δt 0.05 s), measured and rounded up: standard
  // 0.48° and 9.3° RMS, reference 0.50° and 7.8° — both at 320 triangles, where θ_c(t)'s error
  // is the mesh's (the step buys little of it; 1280 triangles do: docs/science/presets.md).
  static const std::vector<PresetInfo> presets = {
      {FidelityPreset::Standard, 1.0, IntegratorKind::ContactImplicitConsistent, 1e-2,
       PreconditionerKind::BlockJacobi, 320, ContactQuadrature::Exact,
       ContactLawKind::PrismsOverlap, 1.0, 10.0},
      {FidelityPreset::Reference, 0.25, IntegratorKind::ContactImplicitConsistent, 1e-3,
       PreconditionerKind::BlockJacobi, 320, ContactQuadrature::Exact, ContactLawKind::Supplement,
       1.0, 8.0},
  };
  return presets;
}

const PresetInfo& presetInfo(FidelityPreset preset) {
  for (const PresetInfo& p : fidelityPresets())
    if (p.preset == preset) return p;
  return fidelityPresets()[0];
}

void applyPreset(NumericsParams& n, FidelityPreset preset) {
  const PresetInfo& p = presetInfo(preset);
  const std::uint32_t pins = n.pinned.bits;
  auto free = [&](const char* key) { return !(pins & pinBit(key)); };
  n.preset = preset;
  if (free("numerics.dt_s")) n.dt_s = p.dt_s;
  if (free("numerics.integrator")) n.integrator = p.integrator;
  if (free("numerics.cg_tol")) n.cg_tol = p.cg_tol;
  if (free("numerics.preconditioner")) n.preconditioner = p.preconditioner;
  if (free("numerics.triangles_per_cell")) n.triangles_per_cell = p.triangles_per_cell;
  if (free("numerics.contact_quadrature")) n.contact_quadrature = p.contact_quadrature;
  if (free("numerics.contact_law")) n.contact_law = p.contact_law;
}

std::optional<FidelityPreset> presetForTarget(const AccuracyTarget& target) {
  if (!target.any()) return std::nullopt;
  for (const PresetInfo& p : fidelityPresets()) {
    if (target.contact_angle_deg && p.contact_angle_error_deg > *target.contact_angle_deg) continue;
    if (target.trajectory_deg && p.trajectory_error_deg > *target.trajectory_deg) continue;
    return p.preset;
  }
  return std::nullopt;
}

}  // namespace activefoam
