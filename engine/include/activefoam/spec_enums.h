// The spec's enumerations and their Choice spellings, apart from SceneSpec: the headers that
// only name an integrator, a preconditioner or a quadrature include this instead of spec.h.
#pragma once

#include <string_view>

namespace activefoam {

enum class SceneKind { Cell, Doublet, Spheroid, Fusion };
// ContactImplicitConsistent: contact-implicit with the consistent stiffness of the spring field in
// Γ (ros2's) instead of one spring per pair: the cells' motion converges in Δt
// (docs/science/motion-convergence.md).
enum class IntegratorKind { SemiImplicit, ContactImplicit, Ros2, ContactImplicitConsistent };
enum class PreconditionerKind { Jacobi, BlockJacobi, IncompleteCholesky };
enum class ContactQuadrature { Exact, Dunavant7, Centroid };
// Fidelity presets (docs/science/presets.md): named numerics, each measured.
enum class FidelityPreset { Standard, Reference };
// The contact law (docs/model.md, docs/numerics.md): which part of a facing pair's overlap
// polygon carries the pressure. Supplement: all of it (the paper's law); Prisms: only where each
// triangle lies over the other; PrismsOverlap: the overlapping part (g < 0) within the prisms, the
// adhesive part whole.
enum class ContactLawKind { Supplement, Prisms, PrismsOverlap };
// What the remesher does about a triangle it could not collapse (docs/numerics.md): None leaves
// it; Rescue runs the cell's remesh again allowing valence 3; RescueRebuild then rebuilds the
// cell's mesh if a sliver is still there.
enum class RemeshRepair { None, Rescue, RescueRebuild };

// The spellings of the spec's Choice keys ("contact-implicit", "block-jacobi", ...).
std::string_view toString(SceneKind);
std::string_view toString(IntegratorKind);
std::string_view toString(PreconditionerKind);
std::string_view toString(ContactQuadrature);
std::string_view toString(FidelityPreset);
std::string_view toString(ContactLawKind);
std::string_view toString(RemeshRepair);

}  // namespace activefoam
