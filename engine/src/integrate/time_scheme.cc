#include "activefoam/time_scheme.h"

#include "activefoam/spec.h"

namespace activefoam {

std::unique_ptr<TimeScheme> makeTimeScheme(const NumericsParams& numerics) {
  switch (numerics.integrator) {
    case IntegratorKind::SemiImplicit:
      return makeOneStage(false);
    case IntegratorKind::ContactImplicit:
      return makeOneStage(true);
    case IntegratorKind::Ros2:
      return makeRos2(numerics);
    case IntegratorKind::ContactImplicitConsistent:
      return makeOneStage(true, true);
  }
  return makeOneStage(true);  // unreachable: validate() admits the kinds above only
}

}  // namespace activefoam
