// What the key table knows of the keys' history: the fingerprint that leaves out what runs as
// before, the base on which earlier jobs' records read, and the keys that exist no more.
#include <cstdint>
#include <optional>
#include <sstream>
#include <string>
#include <variant>

#include "activefoam/spec.h"
#include "spec_internal.h"

namespace activefoam {

using namespace spec_internal;

std::string specFingerprint(const SceneSpec& spec) {
  std::ostringstream os;
  os.precision(17);
  for (const Entry& e : entries()) {
    const SpecField& f = e.field;
    if (f.label || atBefore(e, spec)) continue;
    os << f.key << '=';
    if (const auto v = getField(spec, f.key)) std::visit([&](const auto& x) { os << x; }, *v);
    os << ';';
  }
  // Absent without a [prepare] table: the fingerprints of specs without one stay as they were.
  for (const auto& [key, value] : spec.prepare) {
    os << "prepare." << key << '=';
    std::visit([&](const auto& x) { os << x; }, value);
    os << ';';
  }
  return os.str();
}

SceneSpec recordBase() {
  SceneSpec s;
  for (const Entry& e : entries())
    if (e.field.before) setField(s, e.field.key, *e.field.before);
  s.numerics.pinned = {};  // the record's own keys pin what they set
  return s;
}

namespace {

std::optional<SpecError> retiredAt(std::string_view key, const SpecValue& value,
                                   const SpecValue& neutral, const std::string& why) {
  auto number = [](const SpecValue& v) -> std::optional<double> {
    if (const auto* d = std::get_if<double>(&v)) return *d;
    if (const auto* i = std::get_if<std::int64_t>(&v)) return static_cast<double>(*i);
    return std::nullopt;
  };
  if (value == neutral || (number(value) && number(value) == number(neutral))) return std::nullopt;
  return SpecError{std::string(key), "is retired (" + why + "); only its neutral value " +
                                         describe(neutral) + " still reads"};
}

}  // namespace

std::optional<std::optional<SpecError>> setRetiredField(SceneSpec& spec, std::string_view key,
                                                        const SpecValue& value) {
  const bool* b = std::get_if<bool>(&value);
  auto needBool = [&]() -> std::optional<SpecError> {
    return SpecError{std::string(key), "expected true or false, got " + describe(value)};
  };
  NumericsParams& n = spec.numerics;
  // The contact law's two switches of earlier versions: contact_within_prisms, and with it
  // contact_prisms_overlap_only. The two read as the law they named together, in either order.
  if (key == "numerics.contact_within_prisms") {
    if (!b) return needBool();
    ContactLawKind law = ContactLawKind::Supplement;
    if (*b)
      law = n.contact_law == ContactLawKind::Supplement ? ContactLawKind::Prisms : n.contact_law;
    return setField(spec, "numerics.contact_law", std::string(toString(law)));
  }
  if (key == "numerics.contact_prisms_overlap_only") {
    if (!b) return needBool();
    if (*b) return setField(spec, "numerics.contact_law", std::string("prisms-overlap"));
    if (n.contact_law == ContactLawKind::PrismsOverlap)
      return setField(spec, "numerics.contact_law", std::string("prisms"));
    return std::optional<SpecError>{};
  }
  // The remesher's two switches of earlier versions: rescue, and rebuild after it (a rebuild
  // without the rescue, which no study ran, reads as both). The two read as the policy they
  // named together, in either order.
  if (key == "numerics.remesh_rescue") {
    if (!b) return needBool();
    RemeshRepair r = RemeshRepair::None;
    if (*b) r = n.remesh_repair == RemeshRepair::None ? RemeshRepair::Rescue : n.remesh_repair;
    return setField(spec, "numerics.remesh_repair", std::string(toString(r)));
  }
  if (key == "numerics.remesh_rebuild") {
    if (!b) return needBool();
    if (*b) return setField(spec, "numerics.remesh_repair", std::string("rescue-rebuild"));
    if (n.remesh_repair == RemeshRepair::RescueRebuild)
      return setField(spec, "numerics.remesh_repair", std::string("rescue"));
    return std::optional<SpecError>{};
  }
  if (key == "numerics.contact_max_facing_deg")
    return retiredAt(key, value, 90.0,
                     "the facing bound was measured and not adopted: numerics.contact_law "
                     "removes the false overlaps it was for");
  if (key == "numerics.contact_max_overlap_um")
    return retiredAt(key, value, 0.0,
                     "the saturated pressure was measured not fit: numerics.contact_law removes "
                     "the false overlaps it was for");
  return std::nullopt;
}

}  // namespace activefoam
