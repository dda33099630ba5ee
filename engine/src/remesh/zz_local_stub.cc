// LOCAL STUB, NOT COMMITTED
#include "activefoam/remesh.h"
namespace activefoam {
RemeshStats remesh(TriMesh& m, const RemeshParams&) {
  RemeshStats s;
  s.volume_before = s.volume_after = meshVolume(m);
  return s;
}
}  // namespace activefoam
