// The scene spec's key table, validation and resolution (DESIGN.md §3, §9, §10).
//
// Everything that knows a key's type, range, unit or cross-field rule lives in this file; the
// TOML/JSON parsers, the proto translation and `--set` all go through setField/getField.
#include "activefoam/spec.h"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <limits>
#include <type_traits>

namespace activefoam {
namespace {

// Where a key's value lives in a SceneSpec.
using Slot =
    std::variant<double*, std::optional<double>*, std::int64_t*, std::uint64_t*, SceneKind*,
                 IntegratorKind*, PreconditionerKind*, ContactQuadrature*, FidelityPreset*, bool*>;

// An extra per-key rule beyond the range: returns an error message, empty when the value is fine.
using ExtraRule = std::string (*)(double v);

struct Entry {
  SpecField field;
  Slot (*slot)(SceneSpec&);
  ExtraRule extra = nullptr;
};

constexpr double kSeedMax = 9007199254740992.0;  // 2^53: exact in a JSON number / double

SpecField real(std::string key, bool lo_open, double lo, double hi, bool hi_open, std::string unit,
               std::string help, bool optional = false) {
  SpecField f{std::move(key),  FieldType::Real, lo, hi,     lo_open, optional,
              std::move(unit), std::move(help), {}, hi_open};
  return f;
}

SpecField integer(std::string key, double lo, double hi, std::string help,
                  std::vector<std::string> allowed = {}) {
  SpecField f{std::move(key),  FieldType::Integer, lo, hi, false, false, "",
              std::move(help), std::move(allowed)};
  return f;
}

SpecField boolean(std::string key, std::string help) {
  SpecField f{std::move(key), FieldType::Boolean, 0, 0, false, false, "", std::move(help), {}};
  return f;
}

SpecField choice(std::string key, std::vector<std::string> choices, std::string help) {
  SpecField f{std::move(key),  FieldType::Choice, 0, 0, false, false, "",
              std::move(help), std::move(choices)};
  return f;
}

std::string gammaShapeRule(double v) {
  if (v != 0 && v < 1)
    return formatNumber(v) + " is not allowed: use 0 (every cell has radius r) or a shape k ≥ 1";
  return {};
}

const std::vector<Entry>& entries() {
  static const std::vector<Entry> table = [] {
    constexpr bool kOpen = true, kClosed = false;
    std::vector<Entry> t;
    // ---- top level
    t.push_back({choice("scene", {"cell", "doublet", "spheroid", "fusion"},
                        "what to simulate: one cell, a doublet, one spheroid, or two fusing "
                        "spheroids (also `kind` in the [scene] table)"),
                 [](SceneSpec& s) -> Slot { return &s.scene; }});
    t.push_back(
        {integer("seed", 0, kSeedMax,
                 "random seed; a run is reproducible from (seed, spec) on any thread count"),
         [](SceneSpec& s) -> Slot { return &s.seed; }});
    t.push_back({real("duration_s", kOpen, 0, 1e7, kClosed, "s", "simulated time"),
                 [](SceneSpec& s) -> Slot { return &s.duration_s; }});
    t.push_back({real("sample_every_s", kOpen, 0, 1e7, kClosed, "s",
                      "interval of the observables in samples.csv (≤ duration_s, ≥ dt_s)"),
                 [](SceneSpec& s) -> Slot { return &s.sample_every_s; }});
    t.push_back({real("snapshot_every_s", kClosed, 0, 1e7, kClosed, "s",
                      "interval of mesh snapshots; 0 = none"),
                 [](SceneSpec& s) -> Slot { return &s.snapshot_every_s; }});
    // ---- [cells]
    t.push_back(
        {real("cells.radius_mean_um", kOpen, 0.1, 1000, kClosed, "µm", "mean cell radius r"),
         [](SceneSpec& s) -> Slot { return &s.cells.radius_mean_um; }});
    t.push_back({real("cells.radius_gamma_k", kClosed, 0, 1e6, kClosed, "",
                      "shape k of the Gamma law of cell radii (θ = r/k); 0 = all cells radius r"),
                 [](SceneSpec& s) -> Slot { return &s.cells.radius_gamma_k; }, gammaShapeRule});
    t.push_back({real("cells.gamma", kOpen, 0, 100, kClosed, "nN/µm", "cortex tension γ"),
                 [](SceneSpec& s) -> Slot { return &s.cells.gamma; }});
    t.push_back({real("cells.eta", kOpen, 0, 1e4, kClosed, "nN·s/µm",
                      "cortex 2D viscosity η (or give cells.tau_gamma_s)"),
                 [](SceneSpec& s) -> Slot { return &s.cells.eta; }});
    t.push_back({real("cells.eta_m", kOpen, 0, 1e3, kClosed, "kPa·s", "medium viscosity η_m"),
                 [](SceneSpec& s) -> Slot { return &s.cells.eta_m; }});
    t.push_back({real("cells.bulk_modulus", kOpen, 0, 1e4, kClosed, "kPa",
                      "bulk modulus K of the volume control"),
                 [](SceneSpec& s) -> Slot { return &s.cells.bulk_modulus; }});
    t.push_back({real("cells.tau_k_s", kOpen, 0, 1e6, kClosed, "s",
                      "integration time τ_K of the volume PI control; default 2 τ_shell", true),
                 [](SceneSpec& s) -> Slot { return &s.cells.tau_k_s; }});
    t.push_back({real("cells.alpha", kClosed, 0, 1, kOpen, "",
                      "relative cell–cell tension α = 1 − w/γ; contact angle θ_c = arccos α"),
                 [](SceneSpec& s) -> Slot { return &s.cells.alpha; }});
    t.push_back({real("cells.p_a", kClosed, 0, 10, kClosed, "kPa",
                      "protrusion pressure of active migration (or give cells.pa_reduced)"),
                 [](SceneSpec& s) -> Slot { return &s.cells.p_a; }});
    t.push_back(
        {real("cells.tau_p_s", kOpen, 0, 1e7, kClosed, "s", "polarity persistence time τ_p"),
         [](SceneSpec& s) -> Slot { return &s.cells.tau_p_s; }});
    t.push_back({real("cells.xi", kClosed, 0, 1e4, kClosed, "kPa·s/µm",
                      "contact friction ξ (or give cells.l_eta_reduced)"),
                 [](SceneSpec& s) -> Slot { return &s.cells.xi; }});
    t.push_back({real("cells.xi_normal", kClosed, 0, 1e4, kClosed, "kPa·s/µm",
                      "normal contact friction ξ⊥; default ξ", true),
                 [](SceneSpec& s) -> Slot { return &s.cells.xi_normal; }});
    t.push_back({real("cells.xi_tangential", kClosed, 0, 1e4, kClosed, "kPa·s/µm",
                      "tangential contact friction ξ∥; default ξ", true),
                 [](SceneSpec& s) -> Slot { return &s.cells.xi_tangential; }});
    t.push_back({real("cells.k_contact", kOpen, 0, 1e7, kClosed, "nN/µm³",
                      "contact stiffness k_AB; range h0 = √(w/k_AB)"),
                 [](SceneSpec& s) -> Slot { return &s.cells.k_contact; }});
    t.push_back({real("cells.eps_n", kClosed, 0, 1, kClosed, "",
                      "out-of-plane factor ε_n of the cortex viscosity (S13)"),
                 [](SceneSpec& s) -> Slot { return &s.cells.eps_n; }});
    t.push_back({real("cells.tau_gamma_s", kOpen, 0, 1e5, kClosed, "s",
                      "reduced: τ_γ = η/γ; when given, η = τ_γ γ", true),
                 [](SceneSpec& s) -> Slot { return &s.cells.tau_gamma_s; }});
    t.push_back({real("cells.pa_reduced", kClosed, 0, 50, kClosed, "",
                      "reduced: p_a r/2γ; when given, p_a = value · 2γ/r", true),
                 [](SceneSpec& s) -> Slot { return &s.cells.pa_reduced; }});
    t.push_back({real("cells.l_eta_reduced", kOpen, 0, 100, kClosed, "",
                      "reduced: L_η/r = √(η/ξ)/r; when given, ξ = η/(value · r)²", true),
                 [](SceneSpec& s) -> Slot { return &s.cells.l_eta_reduced; }});
    // ---- [numerics]
    t.push_back({choice("numerics.preset", {"draft", "standard", "reference"},
                        "fidelity preset: sets dt_s, integrator, cg_tol, preconditioner, "
                        "triangles_per_cell and contact_quadrature, except those given "
                        "explicitly (errors and costs: docs/study/presets.md)"),
                 [](SceneSpec& s) -> Slot { return &s.numerics.preset; }});
    t.push_back({real("numerics.dt_s", kOpen, 0, 10, kClosed, "s", "time step Δt"),
                 [](SceneSpec& s) -> Slot { return &s.numerics.dt_s; }});
    t.push_back({choice("numerics.integrator", {"semi-implicit", "contact-implicit", "ros2"},
                        "semi-implicit: forces explicit, friction implicit; contact-implicit: "
                        "also the contact springs' normal stiffness; ros2: contact-implicit in "
                        "two stages, second order (two solves per step)"),
                 [](SceneSpec& s) -> Slot { return &s.numerics.integrator; }});
    t.push_back({real("numerics.cg_tol", kOpen, 0, 0.5, kClosed, "",
                      "relative residual tolerance of the CG solve"),
                 [](SceneSpec& s) -> Slot { return &s.numerics.cg_tol; }});
    t.push_back({integer("numerics.cg_max_iter", 1, 1e6,
                         "CG iterations per step before the run fails as not converged"),
                 [](SceneSpec& s) -> Slot { return &s.numerics.cg_max_iter; }});
    t.push_back(
        {choice("numerics.preconditioner", {"jacobi", "block-jacobi", "incomplete-cholesky"},
                "CG preconditioner: diagonal, 3×3 block diagonal, or block IC(0) of Γ "
                "with the contact couplings (refactored every step)"),
         [](SceneSpec& s) -> Slot { return &s.numerics.preconditioner; }});
    t.push_back({integer("numerics.triangles_per_cell", 80, 1280,
                         "initial triangles per cell (icosphere with 1, 2 or 3 subdivisions)",
                         {"80", "320", "1280"}),
                 [](SceneSpec& s) -> Slot { return &s.numerics.triangles_per_cell; }});
    t.push_back({real("numerics.remesh_every_s", kClosed, 0, 1e7, kClosed, "s",
                      "remeshing interval τ_r; default 5 τ_shell; 0 disables remeshing", true),
                 [](SceneSpec& s) -> Slot { return &s.numerics.remesh_every_s; }});
    t.push_back({real("numerics.remesh_min_area_factor", kOpen, 0, 1, kOpen, "",
                      "collapse triangles smaller than factor · A_Δ (A_Δ = 4πr²/triangles)"),
                 [](SceneSpec& s) -> Slot { return &s.numerics.remesh_min_area_factor; }});
    t.push_back({real("numerics.remesh_max_area_factor", kOpen, 1, 100, kClosed, "",
                      "split triangles larger than factor · A_Δ"),
                 [](SceneSpec& s) -> Slot { return &s.numerics.remesh_max_area_factor; }});
    t.push_back({choice("numerics.contact_quadrature", {"exact", "dunavant7", "centroid"},
                        "integration of the contact pressure over the overlap polygon"),
                 [](SceneSpec& s) -> Slot { return &s.numerics.contact_quadrature; }});
    t.push_back({real("numerics.max_volume_error", kOpen, 0, 1, kClosed, "",
                      "relative cell volume error |V − V*|/V* that stops the run as failed"),
                 [](SceneSpec& s) -> Slot { return &s.numerics.max_volume_error; }});
    t.push_back(
        {real("numerics.max_penetration_um", kOpen, 0, 100, kClosed, "µm",
              "interpenetration of two cells (area-weighted mean over their contact) that stops "
              "the run as failed"),
         [](SceneSpec& s) -> Slot { return &s.numerics.max_penetration_um; }});
    t.push_back({integer("numerics.max_oscillating_steps", 1, 1e6,
                         "consecutive steps of reversing contact velocities (explicit-scheme "
                         "instability) that stop the run as failed"),
                 [](SceneSpec& s) -> Slot { return &s.numerics.max_oscillating_steps; }});
    t.push_back({boolean("numerics.adaptive",
                         "retry a step that fails a check (inverted triangle, volume drift, CG, "
                         "contact oscillation, interpenetration, non-finite) at half the time "
                         "step, down to numerics.dt_min_s; false: the first failure ends the run"),
                 [](SceneSpec& s) -> Slot { return &s.numerics.adaptive; }});
    t.push_back({real("numerics.dt_min_s", kOpen, 0, 10, kClosed, "s",
                      "smallest time step of the adaptive schedule (halvings of dt_s stop at the "
                      "last one ≥ this); default dt_s/64",
                      true),
                 [](SceneSpec& s) -> Slot { return &s.numerics.dt_min_s; }});
    t.push_back({real("numerics.max_step_error_um", kClosed, 0, 100, kClosed, "µm",
                      "ros2 only: retry at half the time step a step whose error estimate "
                      "Δt/2·max|k₁ + k₂| (second-order step against its embedded first-order "
                      "one) exceeds this; taken anyway at numerics.dt_min_s; 0 = off"),
                 [](SceneSpec& s) -> Slot { return &s.numerics.max_step_error_um; }});
    // ---- [scene]
    t.push_back({real("scene.axes_ratio", kClosed, 0.2, 5, kClosed, "",
                      "cell: start as an ellipsoid (q r, r, r/q) of equal volume; 1 = sphere"),
                 [](SceneSpec& s) -> Slot { return &s.scene_params.axes_ratio; }});
    t.push_back({real("scene.gap_um", kClosed, 0, 10, kClosed, "µm",
                      "doublet: initial gap between the two cells; fusion: between the two "
                      "spheroids; unset: min(0.05, 0.8 h0), h0 = √(w/k_AB) the adhesion range",
                      true),
                 [](SceneSpec& s) -> Slot { return &s.scene_params.gap_um; }});
    t.push_back(
        {integer("scene.n_cells", 1, 2000, "spheroid: number of cells N; fusion: N per spheroid"),
         [](SceneSpec& s) -> Slot { return &s.scene_params.n_cells; }});
    t.push_back({integer("scene.n_cells_a", 0, 2000, "fusion: cells in spheroid A; 0 = n_cells"),
                 [](SceneSpec& s) -> Slot { return &s.scene_params.n_cells_a; }});
    t.push_back({integer("scene.n_cells_b", 0, 2000, "fusion: cells in spheroid B; 0 = n_cells"),
                 [](SceneSpec& s) -> Slot { return &s.scene_params.n_cells_b; }});
    t.push_back({real("scene.prep_dt_s", kOpen, 0, 10, kClosed, "s",
                      "fusion: time step of the spheroids' preparation (relaxation of the packed "
                      "cells), always with the contact-implicit integrator"),
                 [](SceneSpec& s) -> Slot { return &s.scene_params.prep_dt_s; }});
    t.push_back({real("scene.prep_max_s", kClosed, 0, 1e5, kClosed, "s",
                      "fusion: longest relaxation of a spheroid's packed cells; 0 = none"),
                 [](SceneSpec& s) -> Slot { return &s.scene_params.prep_max_s; }});
    t.push_back({real("scene.prep_min_s", kClosed, 0, 1e5, kClosed, "s",
                      "fusion: shortest relaxation of a spheroid (compaction is not declared "
                      "before it); weak adhesion (cells.alpha >= 0.8) opens the junctions "
                      "slowly and needs at least 300/(1 - alpha) s"),
                 [](SceneSpec& s) -> Slot { return &s.scene_params.prep_min_s; }});
    t.push_back({real("scene.compact_rate_per_s", kOpen, 0, 1, kClosed, "1/s",
                      "fusion: a spheroid is prepared (compact) when its radius of "
                      "gyration changes by less than this (relative, per second) over 60 s"),
                 [](SceneSpec& s) -> Slot { return &s.scene_params.compact_rate_per_s; }});
    t.push_back({boolean("scene.allow_uncompacted",
                         "fusion: fuse spheroids that are not compact after scene.prep_max_s "
                         "as they are; false: the job fails with preparation-failed"),
                 [](SceneSpec& s) -> Slot { return &s.scene_params.allow_uncompacted; }});
    // ---- [accuracy]
    t.push_back({real("accuracy.contact_angle_deg", kOpen, 0, 90, kClosed, "°",
                      "accuracy target instead of numerics: largest acceptable error of the "
                      "equilibrium contact angle; the cheapest preset that promises it runs",
                      true),
                 [](SceneSpec& s) -> Slot { return &s.accuracy.contact_angle_deg; }});
    t.push_back({real("accuracy.trajectory_deg", kOpen, 0, 90, kClosed, "°",
                      "accuracy target instead of numerics: largest acceptable RMS error of the "
                      "contact angle on its way to equilibrium, θ(t)",
                      true),
                 [](SceneSpec& s) -> Slot { return &s.accuracy.trajectory_deg; }});
    return t;
  }();
  return table;
}

const Entry* findEntry(std::string_view key) {
  if (key == "scene.kind") key = "scene";
  for (const Entry& e : entries())
    if (e.field.key == key) return &e;
  return nullptr;
}

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
    std::is_same_v<E, FidelityPreset>;

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

SpecError unknownKey(std::string_view key) {
  std::string msg = "unknown key '" + std::string(key) + "'";
  if (std::string s = suggestKey(key); !s.empty()) msg += " (did you mean '" + s + "'?)";
  return {std::string(key), msg};
}

std::string_view lastSegment(std::string_view key) {
  const auto dot = key.rfind('.');
  return dot == std::string_view::npos ? key : key.substr(dot + 1);
}

// The numerics keys a preset controls, with their PresetPins bits.
constexpr std::uint32_t kPinPreset = 1u << 6;
std::uint32_t pinBit(std::string_view key) {
  static constexpr std::pair<std::string_view, std::uint32_t> kBits[] = {
      {"numerics.dt_s", 1u << 0},
      {"numerics.integrator", 1u << 1},
      {"numerics.cg_tol", 1u << 2},
      {"numerics.preconditioner", 1u << 3},
      {"numerics.triangles_per_cell", 1u << 4},
      {"numerics.contact_quadrature", 1u << 5},
      {"numerics.preset", kPinPreset}};
  for (const auto& [k, bit] : kBits)
    if (k == key) return bit;
  return 0;
}

// Derived quantities without any checks (resolve's arithmetic).
SceneSpec resolveUnchecked(const SceneSpec& spec) {
  SceneSpec r = spec;
  if (r.accuracy.any()) {
    if (const auto p = presetForTarget(r.accuracy)) applyPreset(r.numerics, *p);
  }
  CellParams& c = r.cells;
  if (c.tau_gamma_s) {
    c.eta = *c.tau_gamma_s * c.gamma;
    c.tau_gamma_s.reset();
  }
  if (c.pa_reduced) {
    c.p_a = *c.pa_reduced * 2.0 * c.gamma / c.radius_mean_um;
    c.pa_reduced.reset();
  }
  if (c.l_eta_reduced) {
    const double l_eta = *c.l_eta_reduced * c.radius_mean_um;
    c.xi = c.eta / (l_eta * l_eta);
    c.l_eta_reduced.reset();
  }
  const double ts = tauShell(c);
  if (!c.tau_k_s) c.tau_k_s = 2.0 * ts;
  if (!r.numerics.remesh_every_s) r.numerics.remesh_every_s = 5.0 * ts;
  if (!r.scene_params.gap_um) r.scene_params.gap_um = defaultGapUm(c);
  if (!r.numerics.dt_min_s) r.numerics.dt_min_s = r.numerics.dt_s / 64;
  if (!c.xi_normal) c.xi_normal = c.xi;
  if (!c.xi_tangential) c.xi_tangential = c.xi;
  return r;
}

}  // namespace

// ---- SpecField ---------------------------------------------------------------------------------

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

const std::vector<SpecField>& specFields() {
  static const std::vector<SpecField> fields = [] {
    std::vector<SpecField> f;
    for (const Entry& e : entries()) f.push_back(e.field);
    return f;
  }();
  return fields;
}

const SpecField* findField(std::string_view key) {
  const Entry* e = findEntry(key);
  if (!e) return nullptr;
  // Same index in specFields() as in entries().
  return &specFields()[static_cast<std::size_t>(e - entries().data())];
}

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

}  // namespace

std::optional<SpecError> setField(SceneSpec& spec, std::string_view key, const SpecValue& value) {
  if (auto e = setFieldValue(spec, key, value)) return e;
  const std::uint32_t bit = pinBit(key);
  spec.numerics.pinned.bits |= bit;
  if (bit == kPinPreset) applyPreset(spec.numerics, spec.numerics.preset);
  return std::nullopt;
}

std::optional<SpecError> clearField(SceneSpec& spec, std::string_view key) {
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

// ---- validate ----------------------------------------------------------------------------------

std::vector<SpecError> validate(const SceneSpec& spec) {
  std::vector<SpecError> errors;
  std::vector<std::string> bad;  // keys whose own value is invalid: cross rules skip them
  auto error = [&](const std::string& key, std::string msg) {
    errors.push_back({key, std::move(msg)});
    bad.push_back(key);
  };
  auto ok = [&](std::initializer_list<std::string_view> keys) {
    for (std::string_view k : keys)
      if (std::find(bad.begin(), bad.end(), k) != bad.end()) return false;
    return true;
  };

  // Each key on its own.
  for (const Entry& e : entries()) {
    const std::optional<SpecValue> v = getField(spec, e.field.key);
    if (!v || e.field.type == FieldType::Boolean) continue;
    if (e.field.type == FieldType::Choice) {
      const std::string& s = std::get<std::string>(*v);
      if (std::find(e.field.choices.begin(), e.field.choices.end(), s) == e.field.choices.end())
        error(e.field.key, "invalid value, expected " + e.field.range());
      continue;
    }
    double d = 0;
    std::string shown;
    if (const auto* i = std::get_if<std::int64_t>(&*v)) {
      d = static_cast<double>(*i);
      shown = std::to_string(*i);
    } else {
      d = std::get<double>(*v);
      shown = formatNumber(d);
    }
    if (std::string msg = checkNumber(e, d, shown); !msg.empty()) error(e.field.key, msg);
  }
  if (spec.seed > static_cast<std::uint64_t>(kSeedMax))
    error("seed", std::to_string(spec.seed) + " is outside the allowed range " +
                      findField("seed")->range());

  const double duration = spec.duration_s, dt = spec.numerics.dt_s;
  // Time axis.
  if (ok({"duration_s", "numerics.dt_s"})) {
    if (dt > duration) {
      error("numerics.dt_s",
            formatNumber(dt) + " s is longer than duration_s = " + formatNumber(duration) + " s");
    } else if (duration / dt > kMaxSteps) {
      error("numerics.dt_s", "duration_s / dt_s = " + formatNumber(std::ceil(duration / dt)) +
                                 " steps exceeds the limit of " + formatNumber(kMaxSteps));
    }
  }
  if (ok({"duration_s", "sample_every_s"})) {
    const double s = spec.sample_every_s;
    if (s > duration) {
      error("sample_every_s",
            formatNumber(s) + " s is longer than duration_s = " + formatNumber(duration) + " s");
    } else if (duration / s > kMaxSamples) {
      error("sample_every_s",
            "duration_s / sample_every_s = " + formatNumber(std::ceil(duration / s)) +
                " samples exceeds the limit of " + formatNumber(kMaxSamples));
    } else if (ok({"numerics.dt_s"}) && s < dt) {
      error("sample_every_s",
            formatNumber(s) + " s is shorter than numerics.dt_s = " + formatNumber(dt) + " s");
    }
  }
  if (ok({"duration_s", "snapshot_every_s"}) && spec.snapshot_every_s > 0) {
    const double s = spec.snapshot_every_s;
    if (duration / s > kMaxSnapshots) {
      error("snapshot_every_s",
            "duration_s / snapshot_every_s = " + formatNumber(std::ceil(duration / s)) +
                " snapshots exceeds the limit of " + formatNumber(kMaxSnapshots));
    } else if (ok({"numerics.dt_s"}) && s < dt) {
      error("snapshot_every_s", formatNumber(s) + " s is shorter than numerics.dt_s = " +
                                    formatNumber(dt) + " s (0 disables snapshots)");
    }
  }

  if (const auto dmin = spec.numerics.dt_min_s;
      dmin && ok({"numerics.dt_s", "numerics.dt_min_s"}) && *dmin > dt)
    error("numerics.dt_min_s", formatNumber(*dmin) + " s exceeds numerics.dt_s = " +
                                   formatNumber(dt) + " s (the floor of the adaptive time step)");

  if (spec.numerics.max_step_error_um > 0) {
    if (ok({"numerics.integrator"}) && spec.numerics.integrator != IntegratorKind::Ros2)
      error("numerics.max_step_error_um",
            "needs numerics.integrator = ros2 (the only integrator with an error estimate); "
            "set it to 0 for " +
                std::string(toString(spec.numerics.integrator)));
    else if (ok({"numerics.adaptive"}) && !spec.numerics.adaptive)
      error("numerics.max_step_error_um",
            "needs numerics.adaptive = true (a step over the estimate is retried at half Δt)");
  }

  if (const SceneParams& sp = spec.scene_params; ok({"scene.prep_min_s", "scene.prep_max_s"}) &&
                                                 sp.prep_max_s > 0 && sp.prep_min_s > sp.prep_max_s)
    error("scene.prep_min_s", formatNumber(sp.prep_min_s) +
                                  " s exceeds scene.prep_max_s = " + formatNumber(sp.prep_max_s) +
                                  " s (the longest relaxation); allowed [0, " +
                                  formatNumber(sp.prep_max_s) + "] s");

  // Remeshing thresholds: a split halves a triangle, so the halves must stay above A_m.
  const double amin = spec.numerics.remesh_min_area_factor;
  const double amax = spec.numerics.remesh_max_area_factor;
  if (ok({"numerics.remesh_min_area_factor", "numerics.remesh_max_area_factor"}) &&
      !(amax > 2.0 * amin)) {
    error("numerics.remesh_max_area_factor",
          formatNumber(amax) + " must exceed 2 × numerics.remesh_min_area_factor = " +
              formatNumber(2.0 * amin) + " (split halves would be collapsed again)");
  }

  // Size of the problem.
  if (ok({"scene", "scene.n_cells", "scene.n_cells_a", "scene.n_cells_b",
          "numerics.triangles_per_cell"})) {
    const double cells = static_cast<double>(sceneCellCount(spec));
    const double tris = cells * static_cast<double>(spec.numerics.triangles_per_cell);
    if (tris > kMaxTotalTriangles) {
      const bool ab = spec.scene == SceneKind::Fusion &&
                      (spec.scene_params.n_cells_a > 0 || spec.scene_params.n_cells_b > 0);
      error(ab ? "scene.n_cells_a" : "scene.n_cells",
            formatNumber(cells) + " cells × " + std::to_string(spec.numerics.triangles_per_cell) +
                " triangles = " + formatNumber(tris) + " triangles exceeds the limit of " +
                formatNumber(kMaxTotalTriangles) +
                " (lower the cell count or numerics.triangles_per_cell)");
    }
  }

  // An accuracy target chooses the numerics: explicit values must agree with its preset.
  if (spec.accuracy.any() && ok({"accuracy.contact_angle_deg", "accuracy.trajectory_deg"})) {
    const std::vector<PresetInfo>& presets = fidelityPresets();
    const std::optional<FidelityPreset> chosen = presetForTarget(spec.accuracy);
    if (!chosen) {
      auto finest = [&](double PresetInfo::*err) {
        double best = presets[0].*err;
        for (const PresetInfo& p : presets) best = std::min(best, p.*err);
        return best;
      };
      const double ca = finest(&PresetInfo::contact_angle_error_deg);
      const double tr = finest(&PresetInfo::trajectory_error_deg);
      if (spec.accuracy.contact_angle_deg && *spec.accuracy.contact_angle_deg < ca)
        error("accuracy.contact_angle_deg",
              formatNumber(*spec.accuracy.contact_angle_deg) +
                  "° is finer than any preset promises; allowed [" + formatNumber(ca) +
                  ", 90] ° (the finest: `reference`, docs/study/presets.md)");
      if (spec.accuracy.trajectory_deg && *spec.accuracy.trajectory_deg < tr)
        error("accuracy.trajectory_deg",
              formatNumber(*spec.accuracy.trajectory_deg) +
                  "° is finer than any preset promises; allowed [" + formatNumber(tr) +
                  ", 90] ° (the finest: `reference`, docs/study/presets.md)");
    } else {
      SceneSpec want = spec;  // the numerics the target chooses
      want.numerics.pinned.bits = 0;
      applyPreset(want.numerics, *chosen);
      const std::string name(toString(*chosen));
      for (const char* key : {"numerics.preset", "numerics.dt_s", "numerics.integrator",
                              "numerics.cg_tol", "numerics.preconditioner",
                              "numerics.triangles_per_cell", "numerics.contact_quadrature"}) {
        if (!(spec.numerics.pinned.bits & pinBit(key))) continue;
        const std::optional<SpecValue> given = getField(spec, key), target = getField(want, key);
        if (given != target)
          error(key,
                "is given together with an accuracy target, which chooses the numerics "
                "itself (the target picks preset '" +
                    name + "', where " + std::string(key) + " = " + describe(*target) +
                    "); give one or the other");
      }
    }
  }

  // Values derived from reduced forms and default rules must land in their keys' ranges.
  if (errors.empty()) {
    const SceneSpec r = resolveUnchecked(spec);
    auto derived = [&](const char* key, const char* target, double value, std::string how) {
      const Entry* e = findEntry(target);
      if (std::string msg = checkNumber(*e, value, formatNumber(value)); !msg.empty())
        error(key, how + " = " + msg);
    };
    const CellParams& c = spec.cells;
    if (c.tau_gamma_s)
      derived("cells.tau_gamma_s", "cells.eta", r.cells.eta, "gives cells.eta = τ_γ·γ");
    if (c.pa_reduced)
      derived("cells.pa_reduced", "cells.p_a", r.cells.p_a, "gives cells.p_a = value·2γ/r");
    if (c.l_eta_reduced)
      derived("cells.l_eta_reduced", "cells.xi", r.cells.xi, "gives cells.xi = η/(value·r)²");
    if (!c.tau_k_s)
      derived("cells.tau_k_s", "cells.tau_k_s", *r.cells.tau_k_s,
              "unset, and its default 2 τ_shell");
    if (!spec.numerics.remesh_every_s)
      derived("numerics.remesh_every_s", "numerics.remesh_every_s", *r.numerics.remesh_every_s,
              "unset, and its default 5 τ_shell");
  }
  return errors;
}

std::vector<SpecError> measuredUnstable(const SceneSpec& spec) {
  std::vector<SpecError> out;
  if (sceneCellCount(spec) < 2) return out;  // the limits are those of the contacts
  const NumericsParams& n = spec.numerics;
  const double k_default = CellParams{}.k_contact;
  const bool motile = spec.cells.p_a > 0 || spec.cells.pa_reduced.value_or(0) > 0;
  double limit = 0;
  std::string why, kind = "contact-oscillation; docs/study/stability-map.md";
  // Whether the map's adaptive ladders ran this integrator past the limit (they did for both
  // implicit ones; the 80-triangle volume drift is slow, and rejecting steps does not undo it).
  bool adaptive_settles = n.integrator != IntegratorKind::SemiImplicit;
  if (n.integrator == IntegratorKind::SemiImplicit) {
    // Failing rungs of the map: 40 / 10 / 2.5 ms at k_AB × 0.25 / 1 / 4 — the explicit spring's
    // limit scales like 1/k_AB.
    limit = 0.01 * k_default / spec.cells.k_contact;
    why =
        "the semi-implicit integrator treats the contact springs explicitly and was measured "
        "to fail from " +
        formatNumber(limit) + " s at k_AB = " + formatNumber(spec.cells.k_contact) + " nN/µm³";
  } else if (n.integrator == IntegratorKind::Ros2) {
    // ros2's own map (2026-11-24): 2 s ran everywhere (k_AB × 1/64 … 4, p_a r/2γ 0 … 1; and on
    // 1280 triangles in the doublet study), 4 s drifted out of volume everywhere.
    limit = 4.0;
    why = "ros2 was measured to fail from 4 s (volume-drift at every k_AB and motility of the map)";
    kind = "docs/study/stability-map.md";
  } else {
    // The first map (polarity noise keyed by step) failed at 1 s with motility; the map with the
    // noise keyed by time ran 1 s there and failed at 2 s: the lower limit stays.
    const bool fine = n.triangles_per_cell >= 1280;
    limit = motile || fine ? 1.0 : 2.0;
    why = std::string("the contact-implicit integrator was measured to fail from ") +
          formatNumber(limit) + " s" +
          (motile ? " with motility"
           : fine ? " with 1280 triangles per cell"
                  : "");
  }
  if (n.integrator != IntegratorKind::SemiImplicit) {
    if (motile && n.triangles_per_cell <= 80) {
      // The reduced fusion with 80 triangles ran at Δt = 0.1 s and drifted out of volume at
      // 0.25 and 0.5 s (cells losing 7–15 % of their volume after ~25 min).
      limit = 0.25;
      why =
          "80 triangles per cell with motility were measured to fail from 0.25 s (they ran at "
          "0.1 s)";
      kind = "volume-drift in the 2 × 30 fusion; docs/study/fusion/fusion.md";
      adaptive_settles = false;
    }
  }
  // With the adaptive step the map's implicit runs beyond these limits finished, by rejecting
  // tries, at a mean step of 1.2–1.5 s (contact-implicit) or ~2 s (ros2): still refused, since
  // the asked Δt is not what would run and the rejected tries are spent for nothing.
  std::string hint;
  if (n.integrator == IntegratorKind::SemiImplicit)
    hint = ", or use numerics.integrator = contact-implicit";
  else if (n.adaptive && adaptive_settles)
    hint =
        "; the adaptive step would run it by rejecting tries, at a mean step near the limit: "
        "ask for that instead";
  if (n.dt_s >= limit)
    out.push_back({"numerics.dt_s", formatNumber(n.dt_s) + " s is beyond the stable range: " + why +
                                        " (" + kind + "); allowed (0, " + formatNumber(limit) +
                                        ") s" + hint});
  return out;
}

// ---- resolve and derived quantities ------------------------------------------------------------

SceneSpec resolve(const SceneSpec& spec) {
  return resolveUnchecked(spec);
}

std::int64_t sceneCellCount(const SceneSpec& spec) {
  const SceneParams& p = spec.scene_params;
  switch (spec.scene) {
    case SceneKind::Cell:
      return 1;
    case SceneKind::Doublet:
      return 2;
    case SceneKind::Spheroid:
      return p.n_cells;
    case SceneKind::Fusion:
      return (p.n_cells_a > 0 ? p.n_cells_a : p.n_cells) +
             (p.n_cells_b > 0 ? p.n_cells_b : p.n_cells);
  }
  return 0;
}

double tauShell(const CellParams& c) {
  return c.eta / (2.0 * std::sqrt(3.0) * c.gamma);
}
double adhesionW(const CellParams& c) {
  return (1.0 - c.alpha) * c.gamma;
}
double contactRangeH0(const CellParams& c) {
  return std::sqrt(adhesionW(c) / c.k_contact);
}
double defaultGapUm(const CellParams& c) {
  return std::min(0.05, 0.8 * contactRangeH0(c));
}

double initialGapUm(const SceneSpec& spec) {
  return spec.scene_params.gap_um.value_or(defaultGapUm(spec.cells));
}

std::vector<SpecError> silentlyWrong(const SceneSpec& spec) {
  std::vector<SpecError> out;
  if (spec.scene != SceneKind::Doublet && spec.scene != SceneKind::Fusion) return out;
  const SceneSpec r = resolveUnchecked(spec);
  const double h0 = contactRangeH0(r.cells), gap = *r.scene_params.gap_um;
  if (gap >= h0)
    out.push_back({"scene.gap_um",
                   formatNumber(gap) + " µm is at or beyond the adhesion range h0 = √(w/k_AB) = " +
                       formatNumber(h0) + " µm (cells.alpha = " + formatNumber(r.cells.alpha) +
                       ", cells.gamma = " + formatNumber(r.cells.gamma) +
                       " nN/µm, cells.k_contact = " + formatNumber(r.cells.k_contact) +
                       " nN/µm³): the " +
                       (spec.scene == SceneKind::Doublet ? "cells" : "spheroids") +
                       " would not touch unless motility brings them together; allowed [0, " +
                       formatNumber(h0) + ") µm, or leave it unset (default min(0.05, 0.8 h0) = " +
                       formatNumber(defaultGapUm(r.cells)) + " µm)"});
  // Weak adhesion: the radius of gyration stands still long before the junctions have opened,
  // so the compaction criterion alone would start the fusion from point contacts.
  const SceneParams& sp = r.scene_params;
  // allow_uncompacted does not lift it: it is about prep_max_s running out, not this.
  if (spec.scene == SceneKind::Fusion && sp.prep_max_s > 0 && r.cells.alpha >= kWeakAdhesionAlpha) {
    const double need = weakAdhesionPrepMinS(r.cells.alpha);
    if (sp.prep_min_s < need)
      out.push_back(
          {"scene.prep_min_s",
           formatNumber(sp.prep_min_s) +
               " s lets a spheroid at cells.alpha = " + formatNumber(r.cells.alpha) +
               " count as compact before its junctions have opened (weak adhesion: the surface "
               "contact angle still rises long after the radius of gyration stands still; "
               "docs/validation.md); allowed: at least " +
               formatNumber(kWeakAdhesionOpenS) + "/(1 - cells.alpha) = " + formatNumber(need) +
               " s at cells.alpha >= " + formatNumber(kWeakAdhesionAlpha) +
               (need > sp.prep_max_s ? ", with scene.prep_max_s (now " +
                                           formatNumber(sp.prep_max_s) + " s) at least as long"
                                     : "")});
  }
  return out;
}

double weakAdhesionPrepMinS(double alpha) {
  // Whole seconds; the tolerance keeps 300/(1 − 0.9) at 3000, not 3001.
  return alpha >= kWeakAdhesionAlpha ? std::ceil(kWeakAdhesionOpenS / (1 - alpha) - 1e-6) : 0;
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

// ---- enum names (the Choice spellings) ---------------------------------------------------------

std::string_view toString(SceneKind k) {
  switch (k) {
    case SceneKind::Cell:
      return "cell";
    case SceneKind::Doublet:
      return "doublet";
    case SceneKind::Spheroid:
      return "spheroid";
    case SceneKind::Fusion:
      return "fusion";
  }
  return "?";
}

std::string_view toString(IntegratorKind k) {
  switch (k) {
    case IntegratorKind::SemiImplicit:
      return "semi-implicit";
    case IntegratorKind::ContactImplicit:
      return "contact-implicit";
    case IntegratorKind::Ros2:
      return "ros2";
  }
  return "?";
}

std::string_view toString(PreconditionerKind k) {
  switch (k) {
    case PreconditionerKind::Jacobi:
      return "jacobi";
    case PreconditionerKind::BlockJacobi:
      return "block-jacobi";
    case PreconditionerKind::IncompleteCholesky:
      return "incomplete-cholesky";
  }
  return "?";
}

std::string_view toString(FidelityPreset p) {
  switch (p) {
    case FidelityPreset::Draft:
      return "draft";
    case FidelityPreset::Standard:
      return "standard";
    case FidelityPreset::Reference:
      return "reference";
  }
  return "?";
}

// ---- fidelity presets
// ----------------------------------------------------------------------------

const std::vector<PresetInfo>& fidelityPresets() {
  // From docs/study/doublet.md (the doublet's Pareto front; measured errors in brackets; costs of
  // the 2026-11-24 regeneration):
  //   draft      Δt 0.5 s, 320 triangles  (θ_c 0.34°, θ(t) RMS 9.7°; 1.4 s per simulated hour)
  //   standard   Δt 0.1 s, 320 triangles  (θ_c 0.47°, θ(t) RMS 8.3°;   7 s) — the supplement's
  //              Δt, 5× below the contact-implicit limit with motility (stability-map.md)
  //   reference  Δt 0.1 s, 1280 triangles (θ_c 0.12°, θ(t) RMS 0.5°;  36 s)
  // ros2 on 1280 triangles at Δt 0.5 s is as accurate as reference (0.66° RMS) at the same cost
  // (33 s; Jacobi CG): no preset of its own.
  // Among 320-triangle settings the error sits at the mesh's floor (7–10° RMS) whatever Δt ≤ 1 s:
  // draft buys its 5× speed with no measurable loss on the doublet, but it runs at the stability
  // limit with motility (1 s fails), which is why it is not the default. Its ε_CG is 1e-2: 2.5×
  // fewer CG iterations than 1e-3 (the step 1.44× cheaper on the 2 × 100 reference) with θ(t)
  // within the one-seed noise of 1e-3's over 2 h of the reduced fusion, and the 18 adaptive-step
  // fusions all finishing (docs/study/presets.md).
  // All three precondition CG by 3×3 blocks (since 2026-11-24; Jacobi before): CG stops on the
  // same true residual whatever the preconditioner, and the blocks see the contact springs'
  // direction (Δt k S n̂n̂ᵀ dominates a contacting vertex's block): 11 instead of 20 CG
  // iterations a step on the 2 × 100 reference at draft, 18 instead of 26 at standard, each
  // iteration as dear (the coupling products are most of it) (docs/study/presets.md).
  static const std::vector<PresetInfo> presets = {
      {FidelityPreset::Draft, 0.5, IntegratorKind::ContactImplicit, 1e-2,
       PreconditionerKind::BlockJacobi, 320, ContactQuadrature::Exact, 1.0, 12.0, 1.4},
      {FidelityPreset::Standard, 0.1, IntegratorKind::ContactImplicit, 1e-3,
       PreconditionerKind::BlockJacobi, 320, ContactQuadrature::Exact, 1.0, 10.0, 7},
      {FidelityPreset::Reference, 0.1, IntegratorKind::ContactImplicit, 1e-3,
       PreconditionerKind::BlockJacobi, 1280, ContactQuadrature::Exact, 0.5, 2.0, 36},
  };
  return presets;
}

const PresetInfo& presetInfo(FidelityPreset preset) {
  for (const PresetInfo& p : fidelityPresets())
    if (p.preset == preset) return p;
  return fidelityPresets()[1];
}

void applyPreset(NumericsParams& n, FidelityPreset preset) {
  const PresetInfo& p = presetInfo(preset);
  const std::uint32_t pins = n.pinned.bits;
  auto free = [&](const char* key) { return !(pins & pinBit(key)); };
  n.preset = preset;
  if (free("numerics.dt_s")) n.dt_s = p.dt_s;
  if (free("numerics.integrator")) n.integrator = p.integrator;
  if (free("numerics.cg_tol")) n.cg_tol = p.cg_tol;
  if (free("numerics.preconditioner")) n.preconditioner = p.preconditioner;
  if (free("numerics.triangles_per_cell")) n.triangles_per_cell = p.triangles_per_cell;
  if (free("numerics.contact_quadrature")) n.contact_quadrature = p.contact_quadrature;
}

std::optional<FidelityPreset> presetForTarget(const AccuracyTarget& target) {
  if (!target.any()) return std::nullopt;
  for (const PresetInfo& p : fidelityPresets()) {
    if (target.contact_angle_deg && p.contact_angle_error_deg > *target.contact_angle_deg) continue;
    if (target.trajectory_deg && p.trajectory_error_deg > *target.trajectory_deg) continue;
    return p.preset;
  }
  return std::nullopt;
}

std::string_view toString(ContactQuadrature q) {
  switch (q) {
    case ContactQuadrature::Exact:
      return "exact";
    case ContactQuadrature::Dunavant7:
      return "dunavant7";
    case ContactQuadrature::Centroid:
      return "centroid";
  }
  return "?";
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
