// Whether a run reads a key, beyond its scene (SpecField::scenes): some keys are read only
// under a setting of another one, and a spec that sets them where they go unread is told so
// (checkSceneKeys, spec_io.h) instead of being run as if they acted. The key table says which
// (fields.cc).
#pragma once

#include <string>
#include <string_view>

#include "activefoam/spec.h"

namespace activefoam {

// Empty when `spec` (resolved) reads `key` as far as the other keys go (an unknown key too);
// else when the key is read and why this spec does not, e.g. "read only while remeshing is on
// (numerics.remesh_every_s > 0), which this spec turns off (numerics.remesh_every_s = 0)".
std::string unreadCondition(const SceneSpec& spec, std::string_view key);

}  // namespace activefoam
