// The scene spec: every parameter of a run, in the units of docs/model.md §1 (µm, s, nN).
//
// A value type with the supplement's Table 1/2 defaults. One table (specFields) describes every
// key: its dotted name, type, allowed range, unit and help. Parsers (TOML/JSON in foam-run,
// proto in the server, `--set key=value` in the CLI) go through setField/getField by key, and
// validate() checks ranges and cross-field rules, so there is exactly one place that knows them.
#pragma once

#include <cstdint>
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
  double radius_mean_um = 8.88;     // mean cell radius r
  double radius_gamma_k = 37;       // Gamma shape k (θ = r/k); 0 = every cell has radius r exactly
  double gamma = 0.5;               // cortex tension γ, nN/µm
  double eta = 5.0;                 // cortex 2D viscosity η, nN·s/µm
  double eta_m = 0.4;               // medium viscosity η_m, kPa·s
  double bulk_modulus = 0.5;        // K, kPa
  std::optional<double> tau_k_s;    // PI integration time τ_K; default 2 τ_shell
  double alpha = 0.4375;            // relative cell–cell tension α = 1 − w/γ
  double p_a = 0.0372;              // protrusion pressure, kPa
  double tau_p_s = 600;             // persistence time τ_p, s
  double xi = 0.25;                 // contact friction ξ, kPa·s/µm
  std::optional<double> xi_normal;  // ξ⊥, default ξ
  std::optional<double> xi_tangential;  // ξ∥, default ξ
  double k_contact = 71.1;              // contact stiffness k_AB, nN/µm³
  double eps_n = 0.1;                   // out-of-plane factor of cortex viscosity (S13)
  // Reduced forms of Table 2. When given they win over the absolute values above.
  std::optional<double> tau_gamma_s;    // τ_γ = η/γ → η
  std::optional<double> pa_reduced;     // p_a r/2γ → p_a
  std::optional<double> l_eta_reduced;  // L_η/r = √(η/ξ)/r → ξ

  friend bool operator==(const CellParams&, const CellParams&) = default;
};

// The defaults are the `standard` preset's values.
struct NumericsParams {
  // Setting the preset (setField "numerics.preset") sets dt_s, integrator, cg_tol,
  // preconditioner, triangles_per_cell and contact_quadrature to its values, except those set
  // explicitly (`pinned`), in whatever order the keys arrive.
  FidelityPreset preset = FidelityPreset::Standard;
  PresetPins pinned;
  double dt_s = 0.1;
  IntegratorKind integrator = IntegratorKind::ContactImplicit;
  double cg_tol = 1e-3;
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
  // the neighbouring cell (the interpenetration guard stopped runs; earlier versions' behaviour).
  bool remesh_on_surface = true;
  // A cell's remesh that leaves a triangle below half of A_m runs again, allowing collapses that
  // leave a vertex of valence 3 (remesh.h, RemeshParams::rescue). false: such collapses are
  // always refused, which can lock a small triangle among vertices of valence 4 until it
  // inverts (earlier versions' behaviour).
  bool remesh_rescue = false;
  // A cell's remesh that still leaves a triangle below half of A_m (after the rescue, when that
  // is on) rebuilds the cell's mesh: a fresh icosphere of triangles_per_cell laid on its surface
  // from its centroid (remesh.h, rebuildRadially). false: the cell keeps its mesh, and a sliver
  // the remesher cannot remove can flatten until it inverts (earlier versions' behaviour).
  bool remesh_rebuild = false;
  // A collapse whose volume-preserving placement would put the merged vertex deeper than this
  // (µm) inside a cell this one touches (and deeper than the vertices it merges) is refused
  // (remesh.h, RemeshParams::keep_out), and so is a rebuild (numerics.remesh_rebuild) that would
  // put a touching cell's vertex that deep inside this one (RemeshParams::keep_out_points).
  // 0: off, it is done, and a remesh can push a vertex of a
  // pressed cell into its neighbour by more than the interpenetration guard allows, failing the
  // step at every Δt (earlier versions' behaviour).
  double remesh_keep_out_um = 0;
  ContactQuadrature contact_quadrature = ContactQuadrature::Exact;
  double max_volume_error = 0.05;  // |V − V*|/V* beyond this stops the run as failed
  // Interpenetration of two cells (the area-weighted mean gap over their contact pairs) beyond
  // this stops the run as failed (cells passing through each other).
  double max_penetration_um = 1.0;
  // Consecutive steps in which contacting vertices mostly reverse their velocity (the period-2
  // signature of an explicit scheme beyond its stability limit) before the run fails.
  std::int64_t max_oscillating_steps = 10;
  // Triangle pairs touch only when their normals face each other within this angle of
  // antiparallel (n̂_A·n̂_B < −cos φ). 90: every facing pair (n̂_A·n̂_B < 0), docs/model.md §3.2.
  // Nearly perpendicular pairs at junctions read gaps of micrometres along their bisector and
  // gave forces 1000× the tissue's (docs/science/motion-convergence.md, "Correction"). Not
  // applied in the spheroids' preparation.
  double contact_max_facing_deg = 90;
  // The overlap beyond which the contact pressure stops growing, µm: P = k max(g, −c), and
  // where a pair is deeper than c it adds no stiffness. 0: P = k g for every g (docs/model.md §3.4,
  // the supplement's law). Nearly perpendicular pairs read overlaps of micrometres along their
  // bisector; saturating the pressure there keeps the rims that a facing bound drops
  // (docs/science/motion-convergence.md). Not applied in the spheroids' preparation.
  double contact_max_overlap_um = 0;
  // A pair's contact keeps only the part of its polygon where each triangle's point lies over
  // the other triangle (inside its prism along its normal). false: the whole polygon of the
  // projections onto the bisector plane (docs/model.md §3.3, the supplement's law), where a
  // nearly perpendicular pair whose planes cross beside the triangles reads an overlap of
  // micrometres between triangles that are apart (docs/numerics.md). Not applied in the
  // spheroids' preparation.
  bool contact_within_prisms = false;
  // With contact_within_prisms: only the overlapping part of the polygon (g < 0) is kept within
  // the prisms, the adhesive part (0 ≤ g < h0) whole — the false overlaps are all at g < 0,
  // while the junctions' rims, where the spheroid's surface angle is read, are adhesive. Not
  // applied in the spheroids' preparation.
  bool contact_prisms_overlap_only = false;
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
  // motility the cells swell past the volume guard within seconds (docs/science/fig8-pa1-probe/);
  // false: the draw, as in earlier versions.
  bool polarity_from_preparation = false;

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

  // Exact, field by field (doubles compared by value): what a round trip must keep.
  friend bool operator==(const SceneSpec&, const SceneSpec&) = default;
};

// ---- the key table -------------------------------------------------------------------------

using SpecValue = std::variant<double, std::int64_t, std::string, bool>;

enum class FieldType { Real, Integer, Choice, Boolean };

struct SpecField {
  std::string key;  // dotted path as in the TOML: "seed", "cells.gamma", "numerics.dt_s", ...
  FieldType type;
  double lo, hi;  // allowed closed range [lo, hi] for Real/Integer
  bool lo_open;   // true: (lo, hi]
  bool optional;  // may be left unset (a derived default applies)
  std::string unit;
  std::string help;
  std::vector<std::string> choices;  // for Choice (and the allowed values of an Integer key)
  bool hi_open = false;              // true: [lo, hi) or (lo, hi)
  std::string range() const;         // "(0, 10]" or "one of cell|doublet|..." for messages
};

// Every key, in a stable order (top level, [cells], [numerics], [scene], [accuracy]).
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
// a non-finite number or a value outside the key's range.
std::optional<SpecError> setField(SceneSpec& spec, std::string_view key, const SpecValue& value);

// Unsets an optional key (its derived default applies again). Fails on an unknown key or a key
// that is not optional.
std::optional<SpecError> clearField(SceneSpec& spec, std::string_view key);

// The key's value; std::nullopt for an optional key that is unset (or an unknown key).
// Real keys give double, Integer keys std::int64_t, Choice keys std::string.
std::optional<SpecValue> getField(const SceneSpec& spec, std::string_view key);

// Every range and cross-field rule. Empty when the spec can run.
std::vector<SpecError> validate(const SceneSpec& spec);

// Fills derived defaults (τ_K, τ_r, ξ⊥/ξ∥), applies reduced parameters and turns an accuracy
// target into its preset, so the result states exactly what runs. Idempotent. Call validate()
// first.
SceneSpec resolve(const SceneSpec& spec);

// Settings the stability study measured to fail (docs/study/stability-map.md,
// docs/study/doublet.md), each naming numerics.dt_s and the limit: with contacts, the
// semi-implicit integrator at Δt ≥ 10 ms × (71.1 nN/µm³ / k_AB) (the explicit contact spring),
// the contact-implicit one at Δt ≥ 2 s, or ≥ 1 s with motility or 1280 triangles per cell
// (contact-oscillation), or ≥ 0.25 s with motility and 80 triangles (volume drift in the reduced
// fusion, docs/study/fusion/fusion.md). The server refuses them; foam-run, the studies' tool,
// warns.
std::vector<SpecError> measuredUnstable(const SceneSpec& spec);

// Every key's value in table order, as text: two specs with the same fingerprint run
// identically (checkpoints and the spheroid cache compare it). numerics.preset and the
// [accuracy] keys are left out: they only choose the values of other keys. numerics.adaptive and
// numerics.dt_min_s are left out at their defaults (true, Δt/64): a run that never fails a step
// runs as before they existed, so its checkpoints and prepared spheroids stay valid.
std::string specFingerprint(const SceneSpec& spec);

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
  // Stated errors: the largest the speed/accuracy study measured (docs/study/doublet.md, against
  // the Δt = 0.025 s, ε_CG = 1e-6, 1280-triangle reference) plus the study's noise floor, rounded
  // up. tests/scenes/test_presets.cc checks that every preset meets them.
  double contact_angle_error_deg;      // equilibrium contact angle
  double trajectory_error_deg;         // RMS over the approach θ(t)
  double doublet_wall_per_sim_hour_s;  // measured cost on the doublet (one core), for the table
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
double tauShell(const CellParams& c);        // η / (2√3 γ)
double adhesionW(const CellParams& c);       // w = (1 − α) γ
double contactRangeH0(const CellParams& c);  // h0 = √(w / k_AB)
// The facing bound of the contact law for numerics.contact_max_facing_deg: 0 at 90° (exactly:
// every facing pair, as before the key), −cos φ below.
double contactFacingDot(const NumericsParams& n);
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
