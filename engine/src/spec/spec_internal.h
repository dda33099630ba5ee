// What the spec's files share and the public header does not show: the key table's entries with
// the slot each key lives in, the range check that setField and validate() both apply, the preset
// pins, and resolve's arithmetic.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <variant>
#include <vector>

#include "activefoam/spec.h"

namespace activefoam::spec_internal {

// Where a key's value lives in a SceneSpec.
using Slot = std::variant<double*, std::optional<double>*, std::int64_t*, std::uint64_t*,
                          SceneKind*, IntegratorKind*, PreconditionerKind*, ContactQuadrature*,
                          FidelityPreset*, ContactLawKind*, RemeshRepair*, bool*>;

// An extra per-key rule beyond the range: returns an error message, empty when the value is fine.
using ExtraRule = std::string (*)(double v);

struct Entry {
  SpecField field;
  Slot (*slot)(SceneSpec&);
  ExtraRule extra = nullptr;
  // For a `before` that is not one value (numerics.dt_min_s: its derived default): whether the
  // spec holds the key at it.
  bool (*at_before)(const SceneSpec&) = nullptr;
  // A key read only under a setting of another key (the remesher's while remeshing is on):
  // whether the (resolved) spec reads it, and the words that say when it does (spec_reads.h).
  // Null: read wherever its scene reads it.
  bool (*read_if)(const SceneSpec&) = nullptr;
  const char* read_if_text = nullptr;
};

// Whether `spec` holds the entry's key at its `before` value (false for a key without one).
bool atBefore(const Entry& e, const SceneSpec& spec);

inline constexpr double kSeedMax = 9007199254740992.0;  // 2^53: exact in a JSON number / double

// The key table (fields.cc), in specFields() order; "scene.kind" finds the "scene" entry.
const std::vector<Entry>& entries();
const Entry* findEntry(std::string_view key);

// A value as the user wrote it, for messages: 0.1, 3, 'ros2', true (keys.cc).
std::string describe(const SpecValue& v);
// The key's range with its unit: "(0, 10] s".
std::string withUnit(const SpecField& f);
// The shared range check of setField and validate. `shown` is the value as the user wrote it.
std::string checkNumber(const Entry& e, double v, const std::string& shown);

// The numerics keys a preset controls, with their PresetPins bits (0 for any other key).
inline constexpr std::uint32_t kPinPreset = 1u << 6;
std::uint32_t pinBit(std::string_view key);

// Derived quantities without any checks (resolve's arithmetic; resolve.cc).
SceneSpec resolveUnchecked(const SceneSpec& spec);

}  // namespace activefoam::spec_internal
