// Reading and writing scene specs (docs/model.md §9): TOML or JSON documents with the keys of
// specFields(), nested tables [cells], [numerics], [scene], and `key=value` overrides (--set).
// [prepare] holds keys of those tables again (`[prepare.cells]`, or `cells.xi = …` and
// `"cells.xi" = …` in `[prepare]`: the keys "prepare.cells.xi" of setField).
//
// Every leaf goes through setField, so ranges and messages are the engine's. Parsing collects
// every error (unknown keys and tables, wrong types, out-of-range values) instead of stopping at
// the first; syntax errors carry the parser's line and column.
//
// The scene kind: plain TOML and JSON cannot hold both `scene = "fusion"` and a [scene] table.
// The kind is the top-level string `scene = "fusion"`, or `kind = "fusion"` inside [scene]
// (the form specToJson writes). For TOML, the form `scene = "fusion"` at the
// top and a [scene] table below — is accepted as well (the header is renamed before parsing).
#pragma once

#include <filesystem>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include <nlohmann/json.hpp>

#include "activefoam/spec.h"

namespace activefoam {

enum class SpecFormat { Auto, Toml, Json };

struct SpecParseOptions {
  // A document must name its scene (docs/usage.md: `scene = "fusion"` alone is a valid spec;
  // nothing at all is not). Off when the scene may come from elsewhere, e.g. a later --set.
  bool require_scene = true;
  // Name used in syntax errors and I/O errors ("spec.toml"); defaults to <toml>/<json>/<set>.
  std::string source;
  // The document is a record (a job's resolved spec, written by this or an earlier version):
  // its labels (the preset's name, accuracy targets) are skipped, since it holds every value
  // they chose. Parse it on recordBase(), so that keys added since read as the run had them.
  bool record = false;
};

struct SpecParseResult {
  std::optional<SceneSpec> spec;  // set exactly when errors is empty
  std::vector<SpecError> errors;  // every problem found, in document order
  bool scene_given = false;       // the document set `scene` (or [scene] kind)
  std::vector<std::string> keys;  // the keys it set, in order (for checkSceneKeys)
  bool ok() const { return errors.empty(); }
};

// The keys among `keys` (those a document or settings set) that the run does not read and that
// hold a value other than the one they would have unset: one error each, naming the key and why.
// Keys of other scenes (scene.n_cells on a cell, gap_um on a spheroid, the contacts' and
// motility's cells.* and numerics.* keys on a single cell, ...), named with the scenes that use
// them; and keys read only under another key's setting (spec_reads.h: the remesher's with
// remeshing off, numerics.dt_min_s without the adaptive step), named with that setting. A key
// that goes unread is a mistake about what runs, not a harmless extra; a resolved spec, which
// lists every key at its default, passes.
std::vector<SpecError> checkSceneKeys(const SceneSpec& spec, const std::vector<std::string>& keys);

// First non-blank character '{' → JSON, else TOML.
SpecFormat sniffSpecFormat(std::string_view text);

// Applies a document's keys on top of `base` (defaults unless given).
SpecParseResult parseSpecText(std::string_view text, SpecFormat format = SpecFormat::Auto,
                              const SceneSpec& base = {}, const SpecParseOptions& options = {});
SpecParseResult parseSpecJson(const nlohmann::json& doc, const SceneSpec& base = {},
                              const SpecParseOptions& options = {});
// Format from the extension (.toml / .json), else sniffed. "-" reads standard input.
SpecParseResult parseSpecFile(const std::filesystem::path& path, const SceneSpec& base = {},
                              const SpecParseOptions& options = {});

// One `key=value` (as for `foam-run --set`): the value is read by the key's type; strings may be
// quoted. `scene.kind=…` is accepted for `scene=…`.
std::optional<SpecError> applySetting(SceneSpec& spec, std::string_view key_equals_value);
// Several, collecting every error. The result's scene_given tells whether one of them set it.
SpecParseResult applySettings(const SceneSpec& base, const std::vector<std::string>& settings);

// Checks a parsed spec and resolves it (validate, then resolve): what runs.
SpecParseResult validateAndResolve(const SceneSpec& spec);

// Every key, nested like the TOML ({"seed":…, "cells":{…}, "numerics":{…}, "scene":{"kind":…}}).
// Unset optional keys are null (a resolved spec has none but the cleared reduced forms).
// "prepare" ({"cells":{…}}) only where the spec has a [prepare] table.
// parseSpecJson(specToJson(s)) gives back s exactly.
nlohmann::json specToJson(const SceneSpec& spec);

}  // namespace activefoam
