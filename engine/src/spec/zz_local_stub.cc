// LOCAL STUB, NOT COMMITTED
#include <cmath>
#include "activefoam/spec.h"
namespace activefoam {
double tauShell(const CellParams& c) {
  return c.eta / (2 * std::sqrt(3.0) * c.gamma);
}
std::string_view toString(SceneKind k) {
  return k == SceneKind::Cell ? "cell" : "other";
}
}  // namespace activefoam
