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
// Fidelity presets (issue 6, docs/study/): named numerics from the speed/accuracy study.
enum class FidelityPreset { Draft, Standard, Reference };

// The spellings of the spec's Choice keys ("contact-implicit", "block-jacobi", ...).
std::string_view toString(SceneKind);
std::string_view toString(IntegratorKind);
std::string_view toString(PreconditionerKind);
std::string_view toString(ContactQuadrature);
std::string_view toString(FidelityPreset);

}  // namespace activefoam
