// The scene spec: every parameter of a run, in the units of docs/model.md §1 (µm, s, nN).
//
// A value type with the supplement's Table 1/2 defaults. One table (specFields) describes every
// key: its dotted name, type, allowed range, unit and help. Parsers (TOML/JSON in foam-run,
// proto in the server, `--set key=value` in the CLI) go through setField/getField by key, and
// validate() checks ranges and cross-field rules, so there is exactly one place that knows them.
#pragma once

#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <string_view>
#include <variant>
#include <vector>

#include "activefoam/spec_enums.h"

namespace activefoam {

// The numerics keys a preset sets, as bits: which of them a spec set explicitly. Provenance, not
// a value: two specs with the same values are equal whatever their pins.
struct PresetPins {
  std::uint32_t bits = 0;
  friend bool operator==(const PresetPins&, const PresetPins&) { return true; }
};

struct CellParams {
  double radius_mean_um = 8.88;   // mean cell radius r
  double radius_gamma_k = 37;     // Gamma shape k (θ = r/k); 0 = every cell has radius r exactly
  double gamma = 0.5;             // cortex tension γ, nN/µm
  double eta = 5.0;               // cortex 2D viscosity η, nN·s/µm
  double eta_m = 0.4;             // medium viscosity η_m, kPa·s
  double bulk_modulus = 0.5;      // K, kPa
  std::optional<double> tau_k_s;  // PI integration time τ_K; default 2 τ_shell
  // τ_shell, from which τ_K and τ_r derive where not given; default η/(2√3 γ). Resolve clears it.
  std::optional<double> tau_shell_s;
  double alpha = 0.4375;                // relative cell–cell tension α = 1 − w/γ
  double p_a = 0.0372;                  // protrusion pressure, kPa
  double tau_p_s = 600;                 // persistence time τ_p, s
  double xi = 0.25;                     // contact friction ξ, kPa·s/µm
  std::optional<double> xi_normal;      // ξ⊥, default ξ
  std::optional<double> xi_tangential;  // ξ∥, default ξ
  double k_contact = 71.1;              // contact stiffness k_AB, nN/µm³
  double eps_n = 0.1;                   // out-of-plane factor of cortex viscosity (S13)
  // Reduced forms of Table 2. When given they win over the absolute values above.
  std::optional<double> tau_gamma_s;    // τ_γ = η/γ → η
  std::optional<double> pa_reduced;     // p_a r/2γ → p_a
  std::optional<double> l_eta_reduced;  // L_η/r = √(η/ξ)/r → ξ

  friend bool operator==(const CellParams&, const CellParams&) = default;
};

// The defaults are the `standard` preset's values: the step the figure studies were validated at
// (docs/science/presets.md).
struct NumericsParams {
  // Setting the preset (setField "numerics.preset") sets dt_s, integrator, cg_tol,
  // preconditioner, triangles_per_cell, contact_quadrature and contact_law to its values, except
  // those set explicitly (`pinned`), in whatever order the keys arrive.
  FidelityPreset preset = FidelityPreset::Standard;
  PresetPins pinned;
  double dt_s = 1.0;
  IntegratorKind integrator = IntegratorKind::ContactImplicitConsistent;
  double cg_tol = 1e-2;
  std::int64_t cg_max_iter = 1000;
  PreconditionerKind preconditioner = PreconditionerKind::BlockJacobi;
  std::int64_t triangles_per_cell = 320;      // 80 | 320 | 1280
  std::optional<double> remesh_every_s;       // τ_r, default 5 τ_shell; 0 disables remeshing
  double remesh_min_area_factor = 1.0 / 3.0;  // A_m = factor · A_Δ
  double remesh_max_area_factor = 3.0;        // A_M = factor · A_Δ
  // Tangential smoothing in the remesher keeps every vertex on the cell's surface (remesh.h):
  // a smoothed vertex is projected back onto its ring, and the volume smoothing changed is
  // restored by one normal offset of the whole cell. false: smoothing corrected the volume by
  // moving the vertex along its normal, by up to half an edge, which at a contact pushed it into
  // the neighbouring cell (the interpenetration guard stopped runs).
  bool remesh_on_surface = true;
  // A triangle the remesher could not collapse (below half of A_m after a remesh): Rescue runs
  // the cell's remesh again allowing collapses that leave a vertex of valence 3 (otherwise a
  // small triangle can lock among vertices of valence 4 until it inverts); RescueRebuild then
  // rebuilds a cell that still has one: a fresh icosphere laid on its surface from its centroid
  // (remesh.h). Each repair changes only runs that need it; the reports count them.
  RemeshRepair remesh_repair = RemeshRepair::RescueRebuild;
  // A collapse whose volume-preserving placement would put the merged vertex deeper than this
  // (µm) inside a cell this one touches (and deeper than the vertices it merges) is refused
  // (remesh.h, RemeshParams::keep_out), and so is a rebuild that would put a touching cell's
  // vertex that deep inside this one (RemeshParams::keep_out_points). 0: off, and a remesh can
  // push a vertex of a pressed cell into its neighbour by more than the interpenetration guard
  // allows, failing the step at every Δt.
  double remesh_keep_out_um = 0;
  ContactQuadrature contact_quadrature = ContactQuadrature::Exact;
  // |V − V*|/V* beyond this stops the run as failed. 20 %: at high motility the cells' volumes
  // swing to 8–18 % and back within seconds in runs that go on (docs/science/presets.md); a run
  // none of whose steps crosses 5 % has the same bits at 5 %.
  double max_volume_error = 0.2;
  // Interpenetration of two cells (the area-weighted mean gap over their contact pairs) beyond
  // this stops the run as failed (cells passing through each other).
  double max_penetration_um = 1.0;
  // Which part of a facing pair's overlap carries the contact pressure (spec_enums.h). The
  // supplement's law reads micrometres of false overlap between nearly perpendicular triangles
  // whose planes cross beside them; the overlap within prisms removes it (docs/numerics.md).
  // Not applied in the spheroids' preparation.
  ContactLawKind contact_law = ContactLawKind::PrismsOverlap;
  // The surface tension's out-of-plane stiffness in Γ, as the contact springs' is (Δt γ_s times
  // the cotangent Laplacian along each edge's bisector): the one-stage implicit integrators then
  // hold Δt 2 s and more, where the explicit tension's vertex-scale ripple, damped only by the
  // cortex's out-of-plane viscosity ε_n η, reverses every step (docs/numerics.md).
  bool tension_implicit = false;
  // Consecutive steps in which contacting vertices mostly reverse their velocity (the period-2
  // signature of an explicit scheme beyond its stability limit) before the run fails.
  std::int64_t max_oscillating_steps = 10;
  // Adaptive time step (time_stepper.h): a step that fails one of the checks above is
  // undone and retried at half the length, down to dt_min_s (default Δt/64); after a run of good
  // steps Δt grows back. false: the first failed step ends the run (the studies measure that).
  bool adaptive = true;
  std::optional<double> dt_min_s;
  // ros2 only: a step whose error estimate Δt/2 · max_i |k₁ + k₂|_i (µm: the distance between
  // the second-order step and its embedded first-order one, linearly implicit Euler) exceeds
  // this is rejected and retried at half the length; at dt_min_s it is taken. 0: off.
  double max_step_error_um = 0;

  friend bool operator==(const NumericsParams&, const NumericsParams&) = default;
};

struct SceneParams {
  double axes_ratio = 1.3;  // cell: start as ellipsoid (q r, r, r/q) at equal volume; 1 = sphere
  // doublet / fusion: initial gap between the two cells / spheroids, µm; unset: defaultGapUm,
  // inside the adhesion range (a gap beyond h0 = √(w/k_AB) never closes for passive cells).
  std::optional<double> gap_um;
  std::int64_t n_cells = 100;  // spheroid: N; fusion: N per spheroid unless a/b are given
  std::int64_t n_cells_a = 0;  // fusion: cells in spheroid A (0 = n_cells)
  std::int64_t n_cells_b = 0;  // fusion: cells in spheroid B (0 = n_cells)
  // Spheroid preparation (spheroid and fusion scenes; see spheroid.h).
  double prep_dt_s = 0.5;            // time step of the relaxation (contact-implicit)
  double prep_max_s = 1800;          // longest relaxation, s (0: the packed cells as they are)
  double compact_rate_per_s = 5e-5;  // compact: |ΔRg|/Rg over 60 s below this × 60 s
  // Shortest relaxation, s: compaction is not declared before it. Weak adhesion opens the
  // cells' junctions slowly while the radius of gyration already stands still (α = 0.9: the
  // surface contact angle still rises for ~2000 s; docs/validation.md), so silentlyWrong asks
  // for weakAdhesionPrepMinS(α) there.
  double prep_min_s = 0;
  // A spheroid not compact after prep_max_s (> 0) fails the job unless this is set (its rate of
  // compaction is named). prep_max_s = 0 asks for the packed cells as they are.
  bool allow_uncompacted = false;
  // Fusion: each cell keeps the polarity its spheroid's preparation ended with, instead of one
  // drawn afresh at t = 0. A fresh draw moves every protrusion to a new side at once, and at high
  // motility the cells swell past the volume guard within seconds (docs/science/presets.md).
  bool polarity_from_preparation = true;

  friend bool operator==(const SceneParams&, const SceneParams&) = default;
};

// An accuracy target instead of numerical settings: resolve() picks the cheapest preset whose
// stated errors (fidelityPresets()) meet every target given.
struct AccuracyTarget {
  std::optional<double> contact_angle_deg;  // error of the equilibrium contact angle, °
  std::optional<double> trajectory_deg;     // RMS error of the contact angle's approach θ(t), °
  bool any() const { return contact_angle_deg || trajectory_deg; }

  friend bool operator==(const AccuracyTarget&, const AccuracyTarget&) = default;
};

// The [observe] table: probes, measurements a run adds to its samples as columns of their own
// and, some, to its summary as curves and final values (probe.h). A probe reads the state and never
// changes it: the run's other columns keep their bits, and the spheroids' preparation ignores these
// keys.
struct ObserveParams {
  bool rigid_motion = false;   // the aggregate's rigid turn and drift since t = 0
  bool dissipation = false;    // the power each friction term dissipates, and the forces' power
  bool msrd_by_depth = false;  // the MSRD split by the cells' depth in the aggregate (fusion)
  bool shape = false;          // the cells' smoothed shape index, elongation and contact fraction
  bool torque = false;         // the aggregate as a body: net torque, rigid spin, torques (fusion)
  // msrd_by_depth's origins: the samples from this time on, s
  double msrd_by_depth_after_s = 0;

  friend bool operator==(const ObserveParams&, const ObserveParams&) = default;
};

using SpecValue = std::variant<double, std::int64_t, std::string, bool>;

struct SceneSpec {
  SceneKind scene = SceneKind::Fusion;
  std::uint64_t seed = 1;
  double duration_s = 86400;
  double sample_every_s = 60;
  double snapshot_every_s = 600;  // 0 = no snapshots
  CellParams cells;
  NumericsParams numerics;
  SceneParams scene_params;  // the [scene] table
  AccuracyTarget accuracy;   // the [accuracy] table
  ObserveParams observe;     // the [observe] table
  // The [prepare] table (fusion): values the spheroids' preparation runs with instead of the
  // run's, by key ("cells.l_eta_reduced"), for keys the key table marks Prep::Kept; keys
  // "prepare.<key>" of setField. resolve() leaves in it the preparation's resolved values that
  // differ from the run's (a reduced key becomes what it derives), so that an empty table is
  // exactly a spec without one.
  std::map<std::string, SpecValue> prepare;

  // Exact, field by field (doubles compared by value): what a round trip must keep.
  friend bool operator==(const SceneSpec&, const SceneSpec&) = default;
};

// ---- the key table -------------------------------------------------------------------------

enum class FieldType { Real, Integer, Choice, Boolean };

struct SpecField {
  std::string key;  // dotted path as in the TOML: "seed", "cells.gamma", "numerics.dt_s", ...
  FieldType type = FieldType::Real;
  double lo = 0, hi = 0;  // allowed closed range [lo, hi] for Real/Integer
  bool lo_open = false;   // true: (lo, hi]
  bool optional = false;  // may be left unset (a derived default applies)
  std::string unit;
  std::string help;
  std::vector<std::string> choices;  // for Choice (and the allowed values of an Integer key)
  bool hi_open = false;              // true: [lo, hi) or (lo, hi)
  // What every other list of keys would repeat, said once here:
  // - `label`: the key only chooses other keys' values (the preset, the accuracy targets); two
  //   specs that differ only in it run identically, and the fingerprint leaves it out.
  // - `before`: the value that reproduces runs made before the key existed. The fingerprint
  //   leaves the key out at it (earlier checkpoints and prepared spheroids stay valid), and a
  //   record that lacks the key (an earlier job's resolved spec) reads at it. Empty: the key is
  //   as old as the spec. `since_unset`: an optional key added later, whose absence is how the
  //   runs before it read (the fingerprint leaves it out while unset).
  // - `prep`: how the spheroids' preparation treats the key (spheroidPrepSpec). Kept: it runs
  //   with the run's value (the key shapes the aggregates). Fixed: with `prep_value` (unset for
  //   an optional key when empty), so that runs differing only in it start from the same
  //   aggregates. Own: the preparation sets it itself (its duration, Δt, scene). Shared: as
  //   Kept, and the run cannot differ from its preparation in it (the run's cells are the
  //   prepared ones, with their radii and meshes; scene.prep_* are the preparation's own). Only
  //   a Kept key may be given another value for the preparation in [prepare].
  // - `scenes`: which scenes read it (bit 1 << SceneKind); a spec that sets it for another scene
  //   is told so.
  bool label = false;
  std::optional<SpecValue> before;
  bool since_unset = false;
  enum class Prep { Kept, Fixed, Own, Shared } prep = Prep::Kept;
  std::optional<SpecValue> prep_value;
  unsigned scenes = 0xF;
  std::string range() const;  // "(0, 10]" or "one of cell|doublet|..." for messages
  bool readBy(SceneKind k) const { return scenes & (1u << static_cast<unsigned>(k)); }
};

// Every key, in a stable order (top level, [cells], [numerics], [scene], [accuracy], [observe]).
//
// The top-level key "scene" (the scene kind) shares its name with the [scene] table, which TOML
// and JSON cannot both hold in one document. The kind may therefore also be written as `kind`
// inside the table: findField("scene.kind") returns the "scene" field, and setField/getField
// accept "scene.kind" as an alias of "scene".
//
// numerics.triangles_per_cell is an Integer key whose `choices` list its allowed values
// ("80", "320", "1280"); range() then reads "one of 80|320|1280".
const std::vector<SpecField>& specFields();
const SpecField* findField(std::string_view key);

// The known key closest to an unknown one (edit distance, or the same last segment in another
// table: "gamma" → "cells.gamma"); empty when nothing is close.
std::string suggestKey(std::string_view unknown_key);

struct SpecError {
  std::string field;    // dotted key, e.g. "numerics.dt_s"
  std::string message;  // one line: what is wrong and the allowed range
  std::string str() const { return field + ": " + message; }
};

// Sets one key. Integers are accepted for Real keys; reals with no fractional part for Integer
// keys; strings for Choice keys. Fails (with the key named) on an unknown key, a wrong type,
// a non-finite number or a value outside the key's range. "prepare.<key>" sets the key's value in
// [prepare] (and fails, saying why, for a key that is not Prep::Kept); clearField and getField
// take such keys too.
std::optional<SpecError> setField(SceneSpec& spec, std::string_view key, const SpecValue& value);

// Unsets an optional key (its derived default applies again). Fails on an unknown key or a key
// that is not optional.
std::optional<SpecError> clearField(SceneSpec& spec, std::string_view key);

// The key's value; std::nullopt for an optional key that is unset (or an unknown key).
// Real keys give double, Integer keys std::int64_t, Choice keys std::string.
std::optional<SpecValue> getField(const SceneSpec& spec, std::string_view key);

// `spec` with its [prepare] values in place of the run's, and no [prepare] table: the spec the
// spheroids' preparation starts from (spheroidPrepSpec), resolved where `spec` is.
SceneSpec withPrepareValues(const SceneSpec& spec);

// Every range and cross-field rule. Empty when the spec can run.
std::vector<SpecError> validate(const SceneSpec& spec);

// Fills derived defaults (τ_K, τ_r, ξ⊥/ξ∥), applies reduced parameters and turns an accuracy
// target into its preset, so the result states exactly what runs; [prepare] keeps the
// preparation's resolved values that differ from the run's. Idempotent. Call validate() first.
SceneSpec resolve(const SceneSpec& spec);

// Settings the stability study measured to fail (docs/study/stability-map.md,
// docs/study/doublet.md), each naming numerics.dt_s and the limit: with contacts, the
// semi-implicit integrator at Δt ≥ 10 ms × (71.1 nN/µm³ / k_AB) (the explicit contact spring),
// the contact-implicit one at Δt ≥ 2 s, or ≥ 1 s with motility or 1280 triangles per cell
// (contact-oscillation), or ≥ 0.25 s with motility and 80 triangles (volume drift in the reduced
// fusion, docs/study/fusion/fusion.md). The server refuses them; foam-run, the studies' tool,
// warns.
std::vector<SpecError> measuredUnstable(const SceneSpec& spec);

// Every key's value in table order, then the [prepare] values, as text: two specs with the same
// fingerprint run identically (checkpoints and the spheroid cache compare it). Labels are left out,
// and so is a key at its `before` value (numerics.dt_min_s at its default Δt/64): a run of today's
// engine at the settings of an earlier one keeps that one's checkpoints and prepared spheroids.
std::string specFingerprint(const SceneSpec& spec);

// A spec whose every key that has a `before` value holds it, the others their defaults: the base
// on which an earlier job's record (its resolved spec) is read, so that keys added since read as
// the run had them.
SceneSpec recordBase();

// Keys that exist no more. A record that holds one at the value that reproduces what runs now
// (or, for those a key replaced, any value: it maps onto that key) reads; anything else is an
// error naming what replaced it. Empty when `key` is no retired key.
std::optional<std::optional<SpecError>> setRetiredField(SceneSpec& spec, std::string_view key,
                                                        const SpecValue& value);

// Levenshtein distance (for "did you mean" suggestions on unknown keys and tables).
std::size_t editDistance(std::string_view a, std::string_view b);

// ---- fidelity presets
// ----------------------------------------------------------------------------

struct PresetInfo {
  FidelityPreset preset;
  // The numerics it sets.
  double dt_s;
  IntegratorKind integrator;
  double cg_tol;
  PreconditionerKind preconditioner;
  std::int64_t triangles_per_cell;
  ContactQuadrature contact_quadrature;
  ContactLawKind contact_law;
  // Stated errors on the doublet (the equilibrium contact angle against arccos α and the
  // approach θ_c(t) against a finer run, tests/scenes/test_presets.cc, which checks that every
  // preset meets them): what it measured, rounded up.
  double contact_angle_error_deg;  // equilibrium contact angle
  double trajectory_error_deg;     // RMS over the approach θ(t)
};

// Every preset, cheapest first.
const std::vector<PresetInfo>& fidelityPresets();
const PresetInfo& presetInfo(FidelityPreset preset);

// Sets the preset and every numerics value it controls that `n.pinned` does not hold.
void applyPreset(NumericsParams& n, FidelityPreset preset);

// The cheapest preset whose stated errors meet every target given; nullopt when none does (or
// no target is given).
std::optional<FidelityPreset> presetForTarget(const AccuracyTarget& target);

// Number of cells the scene builds: cell 1, doublet 2, spheroid n_cells, fusion a + b.
std::int64_t sceneCellCount(const SceneSpec& spec);

// Shortest decimal text that reads back to the same double ("0.1", "1e-05" → "1e-5", "86400").
std::string formatNumber(double v);

// Limits of validate() beyond the per-key ranges (guards against absurd, machine-killing input).
inline constexpr double kMaxTotalTriangles = 2.0e6;  // cells × triangles_per_cell
inline constexpr double kMaxSteps = 1.0e9;           // duration_s / dt_s
inline constexpr double kMaxSamples = 1.0e7;         // duration_s / sample_every_s
inline constexpr double kMaxSnapshots = 1.0e5;       // duration_s / snapshot_every_s

// Derived quantities of a (resolved) spec.
double tauShell(const CellParams& c);        // cells.tau_shell_s, or η / (2√3 γ)
double adhesionW(const CellParams& c);       // w = (1 − α) γ
double contactRangeH0(const CellParams& c);  // h0 = √(w / k_AB)
// The derived defaults, each computed here only: resolve() fills the unset keys with them, and
// the engine's readers of a key that may be unset fall back on the same functions.
double defaultTauKS(const CellParams& c);         // τ_K = 2 τ_shell
double defaultRemeshEveryS(const CellParams& c);  // τ_r = 5 τ_shell
double defaultDtMinS(double dt_s);                // Δt/64, the floor of the adaptive step
double tauKS(const CellParams& c);                // cells.tau_k_s, or its default
double remeshEveryS(const SceneSpec& spec);       // numerics.remesh_every_s, or its default
double dtMinS(const NumericsParams& n);           // numerics.dt_min_s, or its default
// The initial gap of doublet and fusion when scene.gap_um is unset: min(0.05 µm, 0.8 h0) — the
// supplement's 50 nm where that is inside the adhesion range (all defaults: h0 = 63 nm), closer
// where weak adhesion or stiff contacts shrink the range (α = 0.9: h0 = 26 nm).
double defaultGapUm(const CellParams& c);
// scene.gap_um, or its default.
double initialGapUm(const SceneSpec& spec);
// Weak adhesion (α ≥ kWeakAdhesionAlpha) opens a spheroid's junctions slowly: measured on
// 20-cell spheroids (docs/validation.md) the surface contact angle needs ~1000 s to settle at
// α = 0.75 and ~2000–3000 s at α = 0.9 (motile / passive) while the radius of gyration stands
// still from the start. The shortest relaxation asked of such a fusion: 300/(1 − α) s (0 below).
inline constexpr double kWeakAdhesionAlpha = 0.8;
inline constexpr double kWeakAdhesionOpenS = 300;  // × 1/(1 − α)
double weakAdhesionPrepMinS(double alpha);
// Settings that run but are known to give a wrong answer without failing: an initial gap of
// doublet or fusion at or beyond the adhesion range (the cells or spheroids never touch); a
// fusion at weak adhesion whose spheroids may count as compact before weakAdhesionPrepMinS
// (the fusion would start from point contacts). foamd refuses them; foam-run warns.
std::vector<SpecError> silentlyWrong(const SceneSpec& spec);

}  // namespace activefoam
