// Keys by name: setField / clearField / getField with their range checks, the "did you mean"
// suggestion for an unknown key, and the ranges and numbers as every message writes them. The
// TOML/JSON parsers, the proto translation and `--set` all come through here.
#include "activefoam/spec.h"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <string>
#include <type_traits>
#include <utility>
#include <vector>

#include "spec_internal.h"

namespace activefoam {

using namespace spec_internal;

namespace {

template <class... F>
struct Overload : F... {
  using F::operator()...;
};
template <class... F>
Overload(F...) -> Overload<F...>;

template <class E>
constexpr bool kIsChoiceEnum =
    std::is_same_v<E, SceneKind> || std::is_same_v<E, IntegratorKind> ||
    std::is_same_v<E, PreconditionerKind> || std::is_same_v<E, ContactQuadrature> ||
    std::is_same_v<E, FidelityPreset> || std::is_same_v<E, ContactLawKind> ||
    std::is_same_v<E, RemeshRepair>;

SpecError unknownKey(std::string_view key) {
  std::string msg = "unknown key '" + std::string(key) + "'";
  if (std::string s = suggestKey(key); !s.empty()) msg += " (did you mean '" + s + "'?)";
  return {std::string(key), msg};
}

// "prepare.<key>": the key's value in [prepare] (SceneSpec::prepare).
constexpr std::string_view kPrepare = "prepare.";
bool isPrepareKey(std::string_view key) {
  return key.substr(0, kPrepare.size()) == kPrepare;
}

// Why [prepare] cannot hold the key; empty when it can.
std::string notPreparable(const SpecField& f) {
  const std::string marked = " (foam-run --keys marks the keys it takes)";
  switch (f.prep) {
    case SpecField::Prep::Kept:
      return {};
    case SpecField::Prep::Own:
      return "[prepare] cannot set it: the preparation sets it itself (a spheroid of the "
             "[scene] table's cells, its seed drawn from the run's, its step and length "
             "scene.prep_dt_s and scene.prep_max_s)" +
             marked;
    case SpecField::Prep::Fixed:
      return "[prepare] cannot set it: the preparation runs at " +
             (f.prep_value ? describe(*f.prep_value) : std::string("its default")) +
             " whatever the run's, so that runs differing in it share aggregates" + marked;
    case SpecField::Prep::Shared:
      if (!f.readBy(SceneKind::Spheroid))
        return "[prepare] cannot set it: only the preparation reads it; give it in [scene]";
      return "[prepare] cannot set it: the run's cells are the prepared ones, with their radii "
             "and meshes, so the run and its preparation have one value; give it in [" +
             f.key.substr(0, f.key.find('.')) + "]";
  }
  return {};
}

std::string_view lastSegment(std::string_view key) {
  const auto dot = key.rfind('.');
  return dot == std::string_view::npos ? key : key.substr(dot + 1);
}

}  // namespace

namespace spec_internal {

std::string describe(const SpecValue& v) {
  return std::visit(Overload{[](double d) { return formatNumber(d); },
                             [](std::int64_t i) { return std::to_string(i); },
                             [](const std::string& s) { return "'" + s + "'"; },
                             [](bool b) { return std::string(b ? "true" : "false"); }},
                    v);
}

std::string withUnit(const SpecField& f) {
  return f.unit.empty() ? f.range() : f.range() + " " + f.unit;
}

// The shared range check of setField and validate. `shown` is the value as the user wrote it.
std::string checkNumber(const Entry& e, double v, const std::string& shown) {
  const SpecField& f = e.field;
  if (!std::isfinite(v)) return shown + " is not a finite number";
  if (f.type == FieldType::Integer && v != std::floor(v)) return shown + " is not an integer";
  const bool below = f.lo_open ? !(v > f.lo) : !(v >= f.lo);
  const bool above = f.hi_open ? !(v < f.hi) : !(v <= f.hi);
  if (!f.choices.empty()) {  // Integer key with a fixed set of values
    const std::string text = formatNumber(v);
    if (std::find(f.choices.begin(), f.choices.end(), text) == f.choices.end())
      return shown + " is not " + f.range();
  }
  if (below || above) return shown + " is outside the allowed range " + withUnit(f);
  if (e.extra) return e.extra(v);
  return {};
}

bool atBefore(const Entry& e, const SceneSpec& spec) {
  if (e.at_before) return e.at_before(spec);
  if (e.field.since_unset) return !getField(spec, e.field.key);
  return e.field.before && getField(spec, e.field.key) == e.field.before;
}

std::uint32_t pinBit(std::string_view key) {
  static constexpr std::pair<std::string_view, std::uint32_t> kBits[] = {
      {"numerics.dt_s", 1u << 0},
      {"numerics.integrator", 1u << 1},
      {"numerics.cg_tol", 1u << 2},
      {"numerics.preconditioner", 1u << 3},
      {"numerics.triangles_per_cell", 1u << 4},
      {"numerics.contact_quadrature", 1u << 5},
      {"numerics.contact_law", 1u << 7},
      {"numerics.preset", kPinPreset}};
  for (const auto& [k, bit] : kBits)
    if (k == key) return bit;
  return 0;
}

}  // namespace spec_internal

std::string suggestKey(std::string_view unknown) {
  std::string best;
  std::size_t best_d = std::max<std::size_t>(2, unknown.size() / 4) + 1;
  std::vector<std::string_view> keys;
  for (const Entry& e : entries()) keys.push_back(e.field.key);
  keys.push_back("scene.kind");
  for (std::string_view k : keys) {
    const std::size_t d = editDistance(unknown, k);
    if (d < best_d) {
      best_d = d;
      best = std::string(k);
    }
  }
  if (!best.empty()) return best;
  // Same leaf name in another table: "gamma" → "cells.gamma", "numerics.alpha" → "cells.alpha".
  const std::string_view leaf = lastSegment(unknown);
  for (std::string_view k : keys) {
    if (lastSegment(k) == leaf && k != "scene") return std::string(k);
    if (editDistance(lastSegment(k), leaf) == 1 && leaf.size() > 3) best = std::string(k);
  }
  return best;
}

// ---- set / get ---------------------------------------------------------------------------------

namespace {

std::optional<SpecError> setFieldValue(SceneSpec& spec, std::string_view key,
                                       const SpecValue& value) {
  const Entry* e = findEntry(key);
  if (!e) return unknownKey(key);
  const SpecField& f = e->field;
  auto fail = [&](std::string msg) {
    return std::optional<SpecError>(SpecError{std::string(key), std::move(msg)});
  };

  if (f.type == FieldType::Boolean) {
    const auto* b = std::get_if<bool>(&value);
    if (!b) return fail("expected " + f.range() + ", got " + describe(value));
    *std::get<bool*>(e->slot(spec)) = *b;
    return std::nullopt;
  }
  if (f.type == FieldType::Choice) {
    const auto* s = std::get_if<std::string>(&value);
    if (!s) return fail("expected " + f.range() + ", got " + describe(value));
    const auto it = std::find(f.choices.begin(), f.choices.end(), *s);
    if (it == f.choices.end()) return fail("'" + *s + "' is not " + f.range());
    const int index = static_cast<int>(it - f.choices.begin());
    std::visit(
        [&](auto* p) {
          using T = std::remove_pointer_t<decltype(p)>;
          if constexpr (kIsChoiceEnum<T>) *p = static_cast<T>(index);
        },
        e->slot(spec));
    return std::nullopt;
  }

  double v = 0;
  if (const auto* d = std::get_if<double>(&value)) {
    v = *d;
  } else if (const auto* i = std::get_if<std::int64_t>(&value)) {
    v = static_cast<double>(*i);
  } else {
    return fail(std::string("expected ") +
                (f.type == FieldType::Integer ? "an integer" : "a number") + ", got " +
                describe(value));
  }
  if (std::string msg = checkNumber(*e, v, describe(value)); !msg.empty()) return fail(msg);

  std::visit(Overload{[&](double* p) { *p = v; }, [&](std::optional<double>* p) { *p = v; },
                      [&](std::int64_t* p) {
                        const auto* i = std::get_if<std::int64_t>(&value);
                        *p = i ? *i : static_cast<std::int64_t>(v);
                      },
                      [&](std::uint64_t* p) {
                        const auto* i = std::get_if<std::int64_t>(&value);
                        *p = static_cast<std::uint64_t>(i ? *i : static_cast<std::int64_t>(v));
                      },
                      [](auto*) {}},
             e->slot(spec));
  return std::nullopt;
}

// A key of [prepare]: range-checked as the run's, stored as getField reads it.
std::optional<SpecError> setPrepare(SceneSpec& spec, std::string_view key, const SpecValue& value) {
  const std::string_view inner = key.substr(kPrepare.size());
  auto fail = [&](std::string msg) {
    return std::optional<SpecError>(SpecError{std::string(key), std::move(msg)});
  };
  const Entry* e = findEntry(inner);
  if (!e) {
    std::string msg = "unknown key '" + std::string(inner) + "' in [prepare]";
    if (const std::string s = suggestKey(inner); !s.empty())
      msg += " (did you mean 'prepare." + s + "'?)";
    return fail(msg);
  }
  if (std::string why = notPreparable(e->field); !why.empty()) return fail(why);
  SceneSpec scratch;
  if (auto error = setFieldValue(scratch, inner, value)) return fail(error->message);
  spec.prepare[e->field.key] = *getField(scratch, e->field.key);
  return std::nullopt;
}

}  // namespace

std::optional<SpecError> setField(SceneSpec& spec, std::string_view key, const SpecValue& value) {
  if (isPrepareKey(key)) return setPrepare(spec, key, value);
  if (!findEntry(key))
    if (auto retired = setRetiredField(spec, key, value)) return *retired;
  if (key == "numerics.preset" && value == SpecValue(std::string("draft")))
    return SpecError{std::string(key),
                     "'draft' is retired: no step cheaper than standard was found fit "
                     "(docs/science/presets.md); use standard (the default)"};
  if (auto e = setFieldValue(spec, key, value)) return e;
  const std::uint32_t bit = pinBit(key);
  spec.numerics.pinned.bits |= bit;
  if (bit == kPinPreset) applyPreset(spec.numerics, spec.numerics.preset);
  return std::nullopt;
}

std::optional<SpecError> clearField(SceneSpec& spec, std::string_view key) {
  if (isPrepareKey(key)) {
    const Entry* e = findEntry(key.substr(kPrepare.size()));
    if (!e) return unknownKey(key);
    spec.prepare.erase(e->field.key);  // the preparation runs with the run's value again
    return std::nullopt;
  }
  const Entry* e = findEntry(key);
  if (!e) return unknownKey(key);
  Slot slot = e->slot(spec);
  if (auto** opt = std::get_if<std::optional<double>*>(&slot)) {
    (*opt)->reset();
    return std::nullopt;
  }
  return SpecError{std::string(key),
                   "is required and cannot be unset (allowed: " + withUnit(e->field) + ")"};
}

std::optional<SpecValue> getField(const SceneSpec& spec, std::string_view key) {
  if (isPrepareKey(key)) {
    const Entry* e = findEntry(key.substr(kPrepare.size()));
    const auto it = e ? spec.prepare.find(e->field.key) : spec.prepare.end();
    if (it == spec.prepare.end()) return std::nullopt;
    return it->second;
  }
  const Entry* e = findEntry(key);
  if (!e) return std::nullopt;
  // The slot functions take a mutable spec; nothing is written through them here.
  const Slot slot = e->slot(const_cast<SceneSpec&>(spec));
  const auto& choices = e->field.choices;
  return std::visit(Overload{[](double* p) -> std::optional<SpecValue> { return *p; },
                             [](std::optional<double>* p) -> std::optional<SpecValue> {
                               if (!*p) return std::nullopt;
                               return **p;
                             },
                             [](std::int64_t* p) -> std::optional<SpecValue> { return *p; },
                             [](std::uint64_t* p) -> std::optional<SpecValue> {
                               return static_cast<std::int64_t>(*p);
                             },
                             [](bool* p) -> std::optional<SpecValue> { return *p; },
                             [&](auto* p) -> std::optional<SpecValue> {
                               const auto index = static_cast<std::size_t>(*p);
                               if (index >= choices.size()) return std::string("?");
                               return choices[index];
                             }},
                    slot);
}

std::string SpecField::range() const {
  if (type == FieldType::Boolean) return "true or false";
  if (!choices.empty()) {
    std::string s = "one of ";
    for (std::size_t i = 0; i < choices.size(); ++i) s += (i ? "|" : "") + choices[i];
    return s;
  }
  return std::string(lo_open ? "(" : "[") + formatNumber(lo) + ", " + formatNumber(hi) +
         (hi_open ? ")" : "]");
}

std::string formatNumber(double v) {
  if (std::isnan(v)) return "nan";
  if (std::isinf(v)) return v > 0 ? "inf" : "-inf";
  char buf[64];
  const auto res = std::to_chars(buf, buf + sizeof buf, v);
  std::string s(buf, res.ptr);
  // "1e+07" → "1e7", "1e-05" → "1e-5".
  if (const auto e = s.find('e'); e != std::string::npos) {
    std::string mant = s.substr(0, e), exp = s.substr(e + 1);
    bool neg = false;
    if (!exp.empty() && (exp[0] == '+' || exp[0] == '-')) {
      neg = exp[0] == '-';
      exp.erase(0, 1);
    }
    exp.erase(0, std::min(exp.find_first_not_of('0'), exp.size() - 1));
    s = mant + "e" + (neg ? "-" : "") + exp;
  }
  return s;
}

std::size_t editDistance(std::string_view a, std::string_view b) {
  std::vector<std::size_t> row(b.size() + 1);
  for (std::size_t j = 0; j <= b.size(); ++j) row[j] = j;
  for (std::size_t i = 1; i <= a.size(); ++i) {
    std::size_t diag = row[0];
    row[0] = i;
    for (std::size_t j = 1; j <= b.size(); ++j) {
      const std::size_t up = row[j];
      row[j] = std::min({row[j] + 1, row[j - 1] + 1, diag + (a[i - 1] == b[j - 1] ? 0 : 1)});
      diag = up;
    }
  }
  return row[b.size()];
}

}  // namespace activefoam
