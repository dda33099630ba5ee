// The one place where proto scene specs meet engine specs (ARCHITECTURE.md).
//
// Typed messages map onto the engine's key table by name: field `cells.gamma` of
// activefoam.v1.SceneSpec is the key "cells.gamma", the `scene` oneof case is the key "scene",
// and the fields of the per-scene message are the keys "scene.*". Every value goes through the
// engine's setField/validate/resolve, so ranges and messages are the engine's own.
#pragma once

#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "activefoam/spec.h"
#include "activefoam/spec_io.h"
#include "activefoam/v1/job.pb.h"
#include "activefoam/v1/scene.pb.h"

namespace activefoam::server {

struct ConvertResult {
  std::optional<SceneSpec> spec;  // resolved and valid; set exactly when errors is empty
  std::vector<SpecError> errors;  // every problem, each naming its key
  bool ok() const { return errors.empty(); }
};

// Limits on what a request may carry (oversized input is refused before parsing).
inline constexpr std::size_t kMaxSpecTextBytes = 256 * 1024;
inline constexpr std::size_t kMaxSettings = 1000;

struct ConvertOptions {
  // Accept a spec beyond the measured stable range (measuredUnstable): foamd's
  // --allow-unstable, for an operator measuring where a method fails. Such a job runs and may
  // fail as the measurement said; it is never accepted silently by default.
  bool allow_unstable = false;
};

// Builds the spec of a submit: the typed message first, then the TOML/JSON `spec_text` on top,
// then the `key=value` settings; then validate + resolve, and refuse scenes this engine version
// cannot build (error on "scene"). At least one of the three must name the scene.
ConvertResult convertSpec(const v1::SceneSpec& typed, std::string_view spec_text = {},
                          const std::vector<std::string>& settings = {},
                          const ConvertOptions& options = {});

// Applies the set fields of a typed message onto `spec` (no validation beyond setField's ranges).
// `scene_given` tells whether the oneof was set.
std::vector<SpecError> applyTyped(const v1::SceneSpec& typed, SceneSpec& spec, bool& scene_given);

// The typed message of an engine spec: every key that is set (the per-scene message of its
// scene only). convertSpec(toProto(s)) == resolve(s) for a valid s.
v1::SceneSpec toProto(const SceneSpec& spec);

// A job's record (Job.spec_json: the resolved spec as stored at submission, maybe by an earlier
// version) as this engine reads it: on recordBase(), so that keys added since read as the run had
// them, retired switches as the keys that replaced them, the labels skipped. What the pool runs.
SpecParseResult readRecord(std::string_view spec_json);

// The record read so, resolved and written back in today's keys (Job.resolved_spec_json); its
// labels are the record's own where they still read, else null. Empty when it cannot be read.
std::string resolvedRecordJson(std::string_view spec_json);

// Sets job.resolved_spec_json from job.spec_json (every Job the service answers with).
void addResolvedRecord(v1::Job& job);

// "invalid spec: key: message; key: message" — the INVALID_ARGUMENT text.
std::string errorText(const std::vector<SpecError>& errors);

}  // namespace activefoam::server
