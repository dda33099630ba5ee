// The failure kinds' names, as a run reports them (RunSummary::failure, the step-rejected log).
#include "activefoam/failure_kind.h"

namespace activefoam {

std::string_view toString(FailureKind k) {
  switch (k) {
    case FailureKind::None:
      return "none";
    case FailureKind::NonFinite:
      return "non-finite";
    case FailureKind::CgNotConverged:
      return "cg-not-converged";
    case FailureKind::InvertedTriangle:
      return "inverted-triangle";
    case FailureKind::VolumeDrift:
      return "volume-drift";
    case FailureKind::Interpenetration:
      return "interpenetration";
    case FailureKind::ContactOscillation:
      return "contact-oscillation";
    case FailureKind::Cancelled:
      return "cancelled";
    case FailureKind::PreparationFailed:
      return "preparation-failed";
    case FailureKind::StepError:
      return "step-error";
  }
  return "unknown";
}

}  // namespace activefoam
