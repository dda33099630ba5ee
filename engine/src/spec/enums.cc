// The Choice spellings of the spec's enumerations (spec_enums.h).
#include "activefoam/spec_enums.h"

namespace activefoam {

// ---- enum names (the Choice spellings) ---------------------------------------------------------

std::string_view toString(SceneKind k) {
  switch (k) {
    case SceneKind::Cell:
      return "cell";
    case SceneKind::Doublet:
      return "doublet";
    case SceneKind::Spheroid:
      return "spheroid";
    case SceneKind::Fusion:
      return "fusion";
  }
  return "?";
}

std::string_view toString(IntegratorKind k) {
  switch (k) {
    case IntegratorKind::SemiImplicit:
      return "semi-implicit";
    case IntegratorKind::ContactImplicit:
      return "contact-implicit";
    case IntegratorKind::Ros2:
      return "ros2";
    case IntegratorKind::ContactImplicitConsistent:
      return "contact-implicit-consistent";
  }
  return "?";
}

std::string_view toString(PreconditionerKind k) {
  switch (k) {
    case PreconditionerKind::Jacobi:
      return "jacobi";
    case PreconditionerKind::BlockJacobi:
      return "block-jacobi";
    case PreconditionerKind::IncompleteCholesky:
      return "incomplete-cholesky";
  }
  return "?";
}

std::string_view toString(FidelityPreset p) {
  switch (p) {
    case FidelityPreset::Standard:
      return "standard";
    case FidelityPreset::Reference:
      return "reference";
  }
  return "?";
}

std::string_view toString(ContactQuadrature q) {
  switch (q) {
    case ContactQuadrature::Exact:
      return "exact";
    case ContactQuadrature::Dunavant7:
      return "dunavant7";
    case ContactQuadrature::Centroid:
      return "centroid";
  }
  return "?";
}

std::string_view toString(ContactLawKind k) {
  switch (k) {
    case ContactLawKind::Supplement:
      return "supplement";
    case ContactLawKind::Prisms:
      return "prisms";
    case ContactLawKind::PrismsOverlap:
      return "prisms-overlap";
  }
  return "?";
}

std::string_view toString(RemeshRepair r) {
  switch (r) {
    case RemeshRepair::None:
      return "none";
    case RemeshRepair::Rescue:
      return "rescue";
    case RemeshRepair::RescueRebuild:
      return "rescue-rebuild";
  }
  return "?";
}

}  // namespace activefoam
