// Proto ↔ engine spec conversion by the key table (see spec_convert.h).
#include "spec_convert.h"

#include <cctype>
#include <cstdint>
#include <limits>
#include <type_traits>
#include <variant>

#include <google/protobuf/descriptor.h>
#include <google/protobuf/message.h>

#include "activefoam/spec_io.h"

namespace activefoam::server {
namespace {

namespace pb = google::protobuf;

// Enum value name → the engine's choice text: INTEGRATOR_SEMI_IMPLICIT → "semi-implicit"
// (the prefix is that of the enum's UNSPECIFIED value).
std::string enumChoice(const pb::EnumValueDescriptor* v) {
  std::string prefix = v->type()->value(0)->name();
  prefix.resize(prefix.size() - std::string_view("UNSPECIFIED").size());
  std::string name = v->name().substr(prefix.size());
  for (char& c : name) c = c == '_' ? '-' : static_cast<char>(std::tolower(c));
  return name;
}

const pb::EnumValueDescriptor* enumFromChoice(const pb::EnumDescriptor* e, std::string_view text) {
  for (int i = 1; i < e->value_count(); ++i)
    if (enumChoice(e->value(i)) == text) return e->value(i);
  return nullptr;
}

void applyMessage(const pb::Message& m, const std::string& prefix, SceneSpec& spec,
                  std::vector<SpecError>& errors) {
  const pb::Reflection* r = m.GetReflection();
  std::vector<const pb::FieldDescriptor*> fields;
  r->ListFields(m, &fields);
  for (const pb::FieldDescriptor* f : fields) {
    const std::string key = prefix + f->name();
    std::optional<SpecError> e;
    switch (f->cpp_type()) {
      case pb::FieldDescriptor::CPPTYPE_DOUBLE:
        e = setField(spec, key, r->GetDouble(m, f));
        break;
      case pb::FieldDescriptor::CPPTYPE_INT64:
        e = setField(spec, key, static_cast<std::int64_t>(r->GetInt64(m, f)));
        break;
      case pb::FieldDescriptor::CPPTYPE_BOOL:
        e = setField(spec, key, r->GetBool(m, f));
        break;
      case pb::FieldDescriptor::CPPTYPE_UINT64: {
        const std::uint64_t v = r->GetUInt64(m, f);
        if (v > static_cast<std::uint64_t>(std::numeric_limits<std::int64_t>::max()))
          e = SpecError{key, "too large: at most 9223372036854775807"};
        else
          e = setField(spec, key, static_cast<std::int64_t>(v));
        break;
      }
      case pb::FieldDescriptor::CPPTYPE_ENUM: {
        const pb::EnumValueDescriptor* v = r->GetEnum(m, f);
        if (v->number() != 0) e = setField(spec, key, enumChoice(v));
        break;
      }
      default:
        e = SpecError{key, "unsupported field type"};  // a proto/key-table mismatch
    }
    if (e) errors.push_back(*e);
  }
}

// Sets field `name` of `m` to a key's value; nothing where `m` has no such field.
void setProtoField(pb::Message* m, const std::string& name, const SpecValue& value) {
  const pb::FieldDescriptor* f = m->GetDescriptor()->FindFieldByName(name);
  if (!f) return;
  const pb::Reflection* r = m->GetReflection();
  std::visit(
      [&](const auto& v) {
        using T = std::decay_t<decltype(v)>;
        if constexpr (std::is_same_v<T, double>) {
          if (f->cpp_type() == pb::FieldDescriptor::CPPTYPE_DOUBLE) r->SetDouble(m, f, v);
        } else if constexpr (std::is_same_v<T, std::int64_t>) {
          if (f->cpp_type() == pb::FieldDescriptor::CPPTYPE_INT64) r->SetInt64(m, f, v);
          if (f->cpp_type() == pb::FieldDescriptor::CPPTYPE_UINT64)
            r->SetUInt64(m, f, static_cast<std::uint64_t>(v));
        } else if constexpr (std::is_same_v<T, bool>) {
          if (f->cpp_type() == pb::FieldDescriptor::CPPTYPE_BOOL) r->SetBool(m, f, v);
        } else if constexpr (std::is_same_v<T, std::string>) {
          if (f->cpp_type() == pb::FieldDescriptor::CPPTYPE_ENUM)
            if (const auto* ev = enumFromChoice(f->enum_type(), v)) r->SetEnum(m, f, ev);
        }
      },
      value);
}

}  // namespace

std::vector<SpecError> applyTyped(const v1::SceneSpec& typed, SceneSpec& spec, bool& scene_given) {
  std::vector<SpecError> errors;
  scene_given = false;
  const pb::Message* scene_msg = nullptr;
  switch (typed.scene_case()) {
    case v1::SceneSpec::kCell:
      scene_msg = &typed.cell();
      break;
    case v1::SceneSpec::kDoublet:
      scene_msg = &typed.doublet();
      break;
    case v1::SceneSpec::kSpheroid:
      scene_msg = &typed.spheroid();
      break;
    case v1::SceneSpec::kFusion:
      scene_msg = &typed.fusion();
      break;
    case v1::SceneSpec::SCENE_NOT_SET:
      break;
  }
  if (scene_msg) {
    const pb::FieldDescriptor* f =
        typed.GetDescriptor()->FindFieldByNumber(static_cast<int>(typed.scene_case()));
    if (auto e = setField(spec, "scene", f->name())) errors.push_back(*e);
    scene_given = true;
  }
  // Top-level scalars (the oneof and the nested tables are handled on their own).
  {
    v1::SceneSpec top;
    if (typed.has_seed()) top.set_seed(typed.seed());
    if (typed.has_duration_s()) top.set_duration_s(typed.duration_s());
    if (typed.has_sample_every_s()) top.set_sample_every_s(typed.sample_every_s());
    if (typed.has_snapshot_every_s()) top.set_snapshot_every_s(typed.snapshot_every_s());
    applyMessage(top, "", spec, errors);
  }
  if (typed.has_cells()) applyMessage(typed.cells(), "cells.", spec, errors);
  if (typed.has_numerics()) applyMessage(typed.numerics(), "numerics.", spec, errors);
  if (typed.has_accuracy()) applyMessage(typed.accuracy(), "accuracy.", spec, errors);
  if (typed.has_observe()) applyMessage(typed.observe(), "observe.", spec, errors);
  if (typed.prepare().has_cells())
    applyMessage(typed.prepare().cells(), "prepare.cells.", spec, errors);
  if (typed.prepare().has_numerics())
    applyMessage(typed.prepare().numerics(), "prepare.numerics.", spec, errors);
  if (scene_msg) applyMessage(*scene_msg, "scene.", spec, errors);
  return errors;
}

ConvertResult convertSpec(const v1::SceneSpec& typed, std::string_view spec_text,
                          const std::vector<std::string>& settings, const ConvertOptions& options) {
  ConvertResult out;
  if (spec_text.size() > kMaxSpecTextBytes) {
    out.errors.push_back({"spec_text", "too large: " + std::to_string(spec_text.size()) +
                                           " bytes, at most " + std::to_string(kMaxSpecTextBytes)});
    return out;
  }
  if (settings.size() > kMaxSettings) {
    out.errors.push_back({"settings", "too many: " + std::to_string(settings.size()) +
                                          ", at most " + std::to_string(kMaxSettings)});
    return out;
  }
  SceneSpec spec;
  bool scene_given = false;
  // The keys whose scene is checked: those given in spec_text and settings, and the typed
  // [observe] keys (a probe is read by some scenes only; the typed [scene] keys are per scene).
  std::vector<std::string> keys;
  out.errors = applyTyped(typed, spec, scene_given);
  if (!out.errors.empty()) return out;
  if (typed.has_observe()) {
    std::vector<const pb::FieldDescriptor*> set;
    typed.observe().GetReflection()->ListFields(typed.observe(), &set);
    for (const pb::FieldDescriptor* f : set) keys.push_back("observe." + f->name());
  }

  bool blank = true;
  for (char c : spec_text) blank = blank && std::isspace(static_cast<unsigned char>(c));
  if (!blank) {
    SpecParseOptions opts;
    opts.require_scene = false;
    opts.source = "spec_text";
    SpecParseResult parsed = parseSpecText(spec_text, SpecFormat::Auto, spec, opts);
    if (!parsed.ok()) {
      out.errors = parsed.errors;
      return out;
    }
    spec = *parsed.spec;
    scene_given = scene_given || parsed.scene_given;
    keys.insert(keys.end(), parsed.keys.begin(), parsed.keys.end());
  }
  if (!settings.empty()) {
    SpecParseResult set = applySettings(spec, settings);
    if (!set.ok()) {
      out.errors = set.errors;
      return out;
    }
    spec = *set.spec;
    scene_given = scene_given || set.scene_given;
    keys.insert(keys.end(), set.keys.begin(), set.keys.end());
  }
  if (!scene_given) {
    out.errors.push_back(
        {"scene", "missing: the spec must name its scene, " + findField("scene")->range()});
    return out;
  }
  SpecParseResult ready = validateAndResolve(spec);
  if (!ready.ok()) {
    out.errors = ready.errors;
    return out;
  }
  if (auto unused = checkSceneKeys(*ready.spec, keys); !unused.empty()) {
    out.errors = unused;
    return out;
  }
  // A job the stability study says fails would cost its user a queue slot and a failed run:
  // refused here with the measured limit (foam-run, the studies' tool, only warns), unless the
  // operator started foamd to measure exactly that (--allow-unstable).
  if (auto unstable = measuredUnstable(*ready.spec); !unstable.empty() && !options.allow_unstable) {
    out.errors = unstable;
    return out;
  }
  // Likewise a run that would "succeed" with a wrong answer (a gap the adhesion cannot close).
  if (auto wrong = silentlyWrong(*ready.spec); !wrong.empty()) {
    out.errors = wrong;
    return out;
  }
  out.spec = ready.spec;
  return out;
}

v1::SceneSpec toProto(const SceneSpec& spec) {
  v1::SceneSpec out;
  pb::Message* scene_msg = nullptr;
  switch (spec.scene) {
    case SceneKind::Cell:
      scene_msg = out.mutable_cell();
      break;
    case SceneKind::Doublet:
      scene_msg = out.mutable_doublet();
      break;
    case SceneKind::Spheroid:
      scene_msg = out.mutable_spheroid();
      break;
    case SceneKind::Fusion:
      scene_msg = out.mutable_fusion();
      break;
  }
  for (const SpecField& field : specFields()) {
    if (field.key == "scene") continue;
    const std::optional<SpecValue> value = getField(spec, field.key);
    if (!value) continue;
    pb::Message* m = &out;
    std::string name = field.key;
    if (const auto dot = name.find('.'); dot != std::string::npos) {
      const std::string table = name.substr(0, dot);
      name = name.substr(dot + 1);
      if (table == "cells")
        m = out.mutable_cells();
      else if (table == "numerics")
        m = out.mutable_numerics();
      else if (table == "accuracy")
        m = out.mutable_accuracy();
      else if (table == "observe")
        m = out.mutable_observe();
      else
        m = scene_msg;
    }
    setProtoField(m, name, *value);  // none for a [scene] key of another scene
  }
  for (const auto& [key, value] : spec.prepare) {
    const auto dot = key.find('.');
    const std::string table = key.substr(0, dot);
    pb::Message* m = table == "cells"
                         ? static_cast<pb::Message*>(out.mutable_prepare()->mutable_cells())
                         : out.mutable_prepare()->mutable_numerics();
    setProtoField(m, key.substr(dot + 1), value);
  }
  return out;
}

SpecParseResult readRecord(std::string_view spec_json) {
  SpecParseOptions as_record;
  as_record.record = true;
  return parseSpecText(spec_json, SpecFormat::Json, recordBase(), as_record);
}

namespace {

// The value at a dotted key of a nested document; nullptr where there is none.
template <class Json>
Json* at(Json& doc, const std::string& key) {
  Json* node = &doc;
  std::size_t begin = 0;
  for (;;) {
    const std::size_t dot = key.find('.', begin);
    const std::string part = key.substr(begin, dot == std::string::npos ? dot : dot - begin);
    if (!node->is_object() || !node->contains(part)) return nullptr;
    node = &(*node)[part];
    if (dot == std::string::npos) return node;
    begin = dot + 1;
  }
}

}  // namespace

std::string resolvedRecordJson(std::string_view spec_json) {
  const SpecParseResult parsed = readRecord(spec_json);
  if (!parsed.ok()) return {};
  nlohmann::json out = specToJson(resolve(*parsed.spec));
  // The record was read without its labels (it holds every value they chose, and a preset of an
  // earlier version may be retired): each is written as the record named it where this engine
  // reads that name, else null — never as the default the reading left in place.
  const nlohmann::json doc = nlohmann::json::parse(spec_json, nullptr, false);
  for (const SpecField& f : specFields()) {
    if (!f.label) continue;
    nlohmann::json* slot = at(out, f.key);
    if (!slot) continue;
    *slot = nullptr;
    const nlohmann::json* given = doc.is_discarded() ? nullptr : at(doc, f.key);
    if (!given || given->is_null()) continue;
    // The label alone, nested as in the record, read on its own.
    nlohmann::json alone = *given;
    for (std::size_t end = f.key.size(); end != std::string::npos;) {
      const std::size_t dot = end == 0 ? std::string::npos : f.key.rfind('.', end - 1);
      const std::size_t begin = dot == std::string::npos ? 0 : dot + 1;
      alone = nlohmann::json{{f.key.substr(begin, end - begin), std::move(alone)}};
      end = dot;
    }
    SpecParseOptions opts;
    opts.require_scene = false;
    if (parseSpecJson(alone, SceneSpec{}, opts).ok()) *slot = *given;
  }
  return out.dump();
}

void addResolvedRecord(v1::Job& job) {
  job.set_resolved_spec_json(resolvedRecordJson(job.spec_json()));
}

std::string errorText(const std::vector<SpecError>& errors) {
  std::string s = "invalid spec: ";
  for (std::size_t i = 0; i < errors.size(); ++i) s += (i ? "; " : "") + errors[i].str();
  return s;
}

}  // namespace activefoam::server
