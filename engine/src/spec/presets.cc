// The fidelity presets (docs/study/presets.md): named numerics, their stated errors and costs,
// and the choice of the cheapest one for an accuracy target.
#include "activefoam/spec.h"

#include <cstdint>
#include <optional>
#include <vector>

#include "spec_internal.h"

namespace activefoam {

using namespace spec_internal;

// ---- fidelity presets
// ----------------------------------------------------------------------------

const std::vector<PresetInfo>& fidelityPresets() {
  // From docs/study/doublet.md (the doublet's Pareto front; measured errors in brackets; costs of
  // the 2026-11-24 regeneration):
  //   draft      Δt 0.5 s, 320 triangles  (θ_c 0.34°, θ(t) RMS 9.7°; 1.4 s per simulated hour)
  //   standard   Δt 0.1 s, 320 triangles  (θ_c 0.47°, θ(t) RMS 8.3°;   7 s) — the supplement's
  //              Δt, 5× below the contact-implicit limit with motility (stability-map.md)
  //   reference  Δt 0.1 s, 1280 triangles (θ_c 0.12°, θ(t) RMS 0.5°;  36 s)
  // ros2 on 1280 triangles at Δt 0.5 s is as accurate as reference (0.66° RMS) at the same cost
  // (33 s; Jacobi CG): no preset of its own.
  // Among 320-triangle settings the error sits at the mesh's floor (7–10° RMS) whatever Δt ≤ 1 s:
  // draft buys its 5× speed with no measurable loss on the doublet, but it runs at the stability
  // limit with motility (1 s fails), which is why it is not the default. Its ε_CG is 1e-2: 2.5×
  // fewer CG iterations than 1e-3 (the step 1.44× cheaper on the 2 × 100 reference) with θ(t)
  // within the one-seed noise of 1e-3's over 2 h of the reduced fusion, and the 18 adaptive-step
  // fusions all finishing (docs/study/presets.md).
  // All three precondition CG by 3×3 blocks (since 2026-11-24; Jacobi before): CG stops on the
  // same true residual whatever the preconditioner, and the blocks see the contact springs'
  // direction (Δt k S n̂n̂ᵀ dominates a contacting vertex's block): 11 instead of 20 CG
  // iterations a step on the 2 × 100 reference at draft, 18 instead of 26 at standard, each
  // iteration as dear (the coupling products are most of it) (docs/study/presets.md).
  static const std::vector<PresetInfo> presets = {
      {FidelityPreset::Draft, 0.5, IntegratorKind::ContactImplicit, 1e-2,
       PreconditionerKind::BlockJacobi, 320, ContactQuadrature::Exact, 1.0, 12.0, 1.4},
      {FidelityPreset::Standard, 0.1, IntegratorKind::ContactImplicit, 1e-3,
       PreconditionerKind::BlockJacobi, 320, ContactQuadrature::Exact, 1.0, 10.0, 7},
      {FidelityPreset::Reference, 0.1, IntegratorKind::ContactImplicit, 1e-3,
       PreconditionerKind::BlockJacobi, 1280, ContactQuadrature::Exact, 0.5, 2.0, 36},
  };
  return presets;
}

const PresetInfo& presetInfo(FidelityPreset preset) {
  for (const PresetInfo& p : fidelityPresets())
    if (p.preset == preset) return p;
  return fidelityPresets()[1];
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
