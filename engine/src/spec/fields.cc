// The key table: every key of the scene spec with its type, range, unit, help, the place its
// value lives in a SceneSpec, and what the fingerprint, the preparation, the scene check and
// clients need to know of it (SpecField). Adding a key is one entry here and its use.
#include "activefoam/spec.h"
#include "activefoam/spec_reads.h"

#include <string>
#include <utility>
#include <vector>

#include "spec_internal.h"

namespace activefoam {

using namespace spec_internal;

namespace {

// The key's type, range and words; the history columns start empty (SpecField).
SpecField field(std::string key, FieldType type, double lo, double hi, bool lo_open, bool optional,
                std::string unit, std::string help, std::vector<std::string> choices = {},
                bool hi_open = false) {
  SpecField f;
  f.key = std::move(key);
  f.type = type;
  f.lo = lo;
  f.hi = hi;
  f.lo_open = lo_open;
  f.optional = optional;
  f.unit = std::move(unit);
  f.help = std::move(help);
  f.choices = std::move(choices);
  f.hi_open = hi_open;
  return f;
}

SpecField real(std::string key, bool lo_open, double lo, double hi, bool hi_open, std::string unit,
               std::string help, bool optional = false) {
  return field(std::move(key), FieldType::Real, lo, hi, lo_open, optional, std::move(unit),
               std::move(help), {}, hi_open);
}

SpecField integer(std::string key, double lo, double hi, std::string help,
                  std::vector<std::string> allowed = {}) {
  return field(std::move(key), FieldType::Integer, lo, hi, false, false, "", std::move(help),
               std::move(allowed));
}

SpecField boolean(std::string key, std::string help) {
  return field(std::move(key), FieldType::Boolean, 0, 0, false, false, "", std::move(help));
}

SpecField choice(std::string key, std::vector<std::string> choices, std::string help) {
  return field(std::move(key), FieldType::Choice, 0, 0, false, false, "", std::move(help),
               std::move(choices));
}

// Annotations of the entry just added (SpecField: label, before or since_unset, prep, scenes;
// Entry: read_if).
constexpr unsigned kContacts = 0xE;  // doublet, spheroid, fusion: the scenes with contacts
constexpr unsigned kFusionOnly = 1u << 3;
void label(std::vector<Entry>& t) {
  t.back().field.label = true;
}
void since(std::vector<Entry>& t, SpecValue before) {
  t.back().field.before = std::move(before);
}
void sinceUnset(std::vector<Entry>& t) {
  t.back().field.since_unset = true;
}
void prepAt(std::vector<Entry>& t, std::optional<SpecValue> value) {
  t.back().field.prep = SpecField::Prep::Fixed;
  t.back().field.prep_value = std::move(value);
}
void prepOwn(std::vector<Entry>& t) {
  t.back().field.prep = SpecField::Prep::Own;
}
void prepShared(std::vector<Entry>& t) {
  t.back().field.prep = SpecField::Prep::Shared;
}
void readBy(std::vector<Entry>& t, unsigned scenes) {
  t.back().field.scenes = scenes;
}
void readIf(std::vector<Entry>& t, bool (*when)(const SceneSpec&), const char* text) {
  t.back().read_if = when;
  t.back().read_if_text = text;
}
bool remeshing(const SceneSpec& s) {
  return remeshEveryS(s) > 0;
}
bool oneStageImplicit(const SceneSpec& s) {
  return s.numerics.integrator == IntegratorKind::ContactImplicit ||
         s.numerics.integrator == IntegratorKind::ContactImplicitConsistent;
}
constexpr const char* kOneStageImplicit =
    "read only by the contact-implicit integrators (numerics.integrator = contact-implicit or "
    "contact-implicit-consistent)";
constexpr const char* kRemeshing =
    "read only while remeshing is on (numerics.remesh_every_s > 0), which this spec turns off "
    "(numerics.remesh_every_s = 0)";
constexpr unsigned scenes(SceneKind k) {
  return 1u << static_cast<unsigned>(k);
}

std::string gammaShapeRule(double v) {
  if (v != 0 && v < 1)
    return formatNumber(v) + " is not allowed: use 0 (every cell has radius r) or a shape k ≥ 1";
  return {};
}

}  // namespace

namespace spec_internal {

const std::vector<Entry>& entries() {
  static const std::vector<Entry> table = [] {
    constexpr bool kOpen = true, kClosed = false;
    std::vector<Entry> t;
    // ---- top level
    t.push_back({choice("scene", {"cell", "doublet", "spheroid", "fusion"},
                        "what to simulate: one cell, a doublet, one spheroid, or two fusing "
                        "spheroids (also `kind` in the [scene] table)"),
                 [](SceneSpec& s) -> Slot { return &s.scene; }});
    prepOwn(t);
    t.push_back(
        {integer("seed", 0, kSeedMax,
                 "random seed; a run is reproducible from (seed, spec) on any thread count"),
         [](SceneSpec& s) -> Slot { return &s.seed; }});
    prepOwn(t);
    t.push_back({real("duration_s", kOpen, 0, 1e7, kClosed, "s", "simulated time"),
                 [](SceneSpec& s) -> Slot { return &s.duration_s; }});
    prepOwn(t);
    t.push_back({real("sample_every_s", kOpen, 0, 1e7, kClosed, "s",
                      "interval of the observables in samples.csv (≤ duration_s, ≥ dt_s)"),
                 [](SceneSpec& s) -> Slot { return &s.sample_every_s; }});
    prepOwn(t);
    t.push_back({real("snapshot_every_s", kClosed, 0, 1e7, kClosed, "s",
                      "interval of mesh snapshots; 0 = none"),
                 [](SceneSpec& s) -> Slot { return &s.snapshot_every_s; }});
    prepOwn(t);
    // ---- [cells]
    t.push_back(
        {real("cells.radius_mean_um", kOpen, 0.1, 1000, kClosed, "µm", "mean cell radius r"),
         [](SceneSpec& s) -> Slot { return &s.cells.radius_mean_um; }});
    prepShared(t);
    t.push_back({real("cells.radius_gamma_k", kClosed, 0, 1e6, kClosed, "",
                      "shape k of the Gamma law of cell radii (θ = r/k); 0 = all cells radius r"),
                 [](SceneSpec& s) -> Slot { return &s.cells.radius_gamma_k; }, gammaShapeRule});
    prepShared(t);
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
    t.push_back({real("cells.tau_shell_s", kOpen, 0, 1e6, kClosed, "s",
                      "shell relaxation time τ_shell, from which τ_K = 2 τ_shell and the remesh "
                      "interval τ_r = 5 τ_shell derive where they are not given; default "
                      "η/(2√3 γ) at the run's own γ",
                      true),
                 [](SceneSpec& s) -> Slot { return &s.cells.tau_shell_s; }});
    sinceUnset(t);
    t.push_back({real("cells.alpha", kClosed, 0, 1, kOpen, "",
                      "relative cell–cell tension α = 1 − w/γ; contact angle θ_c = arccos α"),
                 [](SceneSpec& s) -> Slot { return &s.cells.alpha; }});
    readBy(t, kContacts);
    t.push_back({real("cells.p_a", kClosed, 0, 10, kClosed, "kPa",
                      "protrusion pressure of active migration (or give cells.pa_reduced)"),
                 [](SceneSpec& s) -> Slot { return &s.cells.p_a; }});
    readBy(t, kContacts);
    t.push_back(
        {real("cells.tau_p_s", kOpen, 0, 1e7, kClosed, "s", "polarity persistence time τ_p"),
         [](SceneSpec& s) -> Slot { return &s.cells.tau_p_s; }});
    readBy(t, kContacts);
    t.push_back({real("cells.xi", kClosed, 0, 1e4, kClosed, "kPa·s/µm",
                      "contact friction ξ (or give cells.l_eta_reduced)"),
                 [](SceneSpec& s) -> Slot { return &s.cells.xi; }});
    readBy(t, kContacts);
    t.push_back({real("cells.xi_normal", kClosed, 0, 1e4, kClosed, "kPa·s/µm",
                      "normal contact friction ξ⊥; default ξ", true),
                 [](SceneSpec& s) -> Slot { return &s.cells.xi_normal; }});
    readBy(t, kContacts);
    t.push_back({real("cells.xi_tangential", kClosed, 0, 1e4, kClosed, "kPa·s/µm",
                      "tangential contact friction ξ∥; default ξ", true),
                 [](SceneSpec& s) -> Slot { return &s.cells.xi_tangential; }});
    readBy(t, kContacts);
    t.push_back({real("cells.k_contact", kOpen, 0, 1e7, kClosed, "nN/µm³",
                      "contact stiffness k_AB; range h0 = √(w/k_AB)"),
                 [](SceneSpec& s) -> Slot { return &s.cells.k_contact; }});
    readBy(t, kContacts);
    t.push_back({real("cells.eps_n", kClosed, 0, 1, kClosed, "",
                      "out-of-plane factor ε_n of the cortex viscosity (S13)"),
                 [](SceneSpec& s) -> Slot { return &s.cells.eps_n; }});
    t.push_back({real("cells.tau_gamma_s", kOpen, 0, 1e5, kClosed, "s",
                      "reduced: τ_γ = η/γ; when given, η = τ_γ γ", true),
                 [](SceneSpec& s) -> Slot { return &s.cells.tau_gamma_s; }});
    t.push_back({real("cells.pa_reduced", kClosed, 0, 50, kClosed, "",
                      "reduced: p_a r/2γ; when given, p_a = value · 2γ/r", true),
                 [](SceneSpec& s) -> Slot { return &s.cells.pa_reduced; }});
    readBy(t, kContacts);
    t.push_back({real("cells.l_eta_reduced", kOpen, 0, 100, kClosed, "",
                      "reduced: L_η/r = √(η/ξ)/r; when given, ξ = η/(value · r)²", true),
                 [](SceneSpec& s) -> Slot { return &s.cells.l_eta_reduced; }});
    readBy(t, kContacts);
    // ---- [numerics]
    t.push_back({choice("numerics.preset", {"standard", "reference"},
                        "fidelity preset: sets dt_s, integrator, cg_tol, preconditioner, "
                        "triangles_per_cell, contact_quadrature and contact_law, except those "
                        "given explicitly (what each runs and costs: docs/science/presets.md)"),
                 [](SceneSpec& s) -> Slot { return &s.numerics.preset; }});
    label(t);
    prepAt(t, std::string("standard"));
    t.push_back({real("numerics.dt_s", kOpen, 0, 10, kClosed, "s", "time step Δt"),
                 [](SceneSpec& s) -> Slot { return &s.numerics.dt_s; }});
    prepOwn(t);
    t.push_back(
        {choice("numerics.integrator",
                {"semi-implicit", "contact-implicit", "ros2", "contact-implicit-consistent"},
                "contact-implicit-consistent: one stage with the contact springs' consistent "
                "stiffness (motion converged in Δt); contact-implicit: one spring per pair "
                "(under-resolves the cells' motion at every Δt measured); ros2: two stages, "
                "second order; semi-implicit: contact forces explicit"),
         [](SceneSpec& s) -> Slot { return &s.numerics.integrator; }});
    prepAt(t, std::string("contact-implicit"));
    t.push_back({real("numerics.cg_tol", kOpen, 0, 0.5, kClosed, "",
                      "relative residual tolerance ε_CG of the CG solve"),
                 [](SceneSpec& s) -> Slot { return &s.numerics.cg_tol; }});
    prepAt(t, 1e-3);
    t.push_back({integer("numerics.cg_max_iter", 1, 1e6,
                         "CG iterations per step before the step fails as not converged"),
                 [](SceneSpec& s) -> Slot { return &s.numerics.cg_max_iter; }});
    prepAt(t, std::int64_t{1000});
    t.push_back(
        {choice("numerics.preconditioner", {"jacobi", "block-jacobi", "incomplete-cholesky"},
                "CG preconditioner: diagonal, 3×3 block diagonal, or block IC(0) of Γ "
                "with the contact couplings (refactored every step)"),
         [](SceneSpec& s) -> Slot { return &s.numerics.preconditioner; }});
    // The preparation's own: Jacobi, so that prepared spheroids stay the same bits.
    prepAt(t, std::string("jacobi"));
    t.push_back({integer("numerics.triangles_per_cell", 80, 1280,
                         "initial triangles per cell (icosphere with 1, 2 or 3 subdivisions)",
                         {"80", "320", "1280"}),
                 [](SceneSpec& s) -> Slot { return &s.numerics.triangles_per_cell; }});
    prepShared(t);
    t.push_back({real("numerics.remesh_every_s", kClosed, 0, 1e7, kClosed, "s",
                      "remeshing interval τ_r; default 5 τ_shell; 0 disables remeshing", true),
                 [](SceneSpec& s) -> Slot { return &s.numerics.remesh_every_s; }});
    t.push_back({real("numerics.remesh_min_area_factor", kOpen, 0, 1, kOpen, "",
                      "collapse triangles smaller than factor · A_Δ (A_Δ = 4πr²/triangles)"),
                 [](SceneSpec& s) -> Slot { return &s.numerics.remesh_min_area_factor; }});
    readIf(t, remeshing, kRemeshing);
    t.push_back({real("numerics.remesh_max_area_factor", kOpen, 1, 100, kClosed, "",
                      "split triangles larger than factor · A_Δ"),
                 [](SceneSpec& s) -> Slot { return &s.numerics.remesh_max_area_factor; }});
    readIf(t, remeshing, kRemeshing);
    t.push_back({boolean("numerics.remesh_on_surface",
                         "remeshing's smoothing keeps vertices on the cell's surface; false: "
                         "moves them along their normals, which can push one into a neighbour"),
                 [](SceneSpec& s) -> Slot { return &s.numerics.remesh_on_surface; }});
    readIf(t, remeshing, kRemeshing);
    since(t, false);
    t.push_back({choice("numerics.remesh_repair", {"none", "rescue", "rescue-rebuild"},
                        "a sliver the remesher cannot collapse: rescue remeshes the cell again "
                        "allowing valence 3, rescue-rebuild then lays a fresh mesh on a cell that "
                        "still has one; none leaves it (it can invert)"),
                 [](SceneSpec& s) -> Slot { return &s.numerics.remesh_repair; }});
    readIf(t, remeshing, kRemeshing);
    since(t, std::string("none"));
    prepAt(t, std::string("none"));
    t.push_back({real("numerics.remesh_keep_out_um", kClosed, 0, 100, kClosed, "µm",
                      "refuse a collapse (or rebuild) that puts a vertex deeper than this inside "
                      "a touching cell; 0: off"),
                 [](SceneSpec& s) -> Slot { return &s.numerics.remesh_keep_out_um; }});
    readIf(t, remeshing, kRemeshing);
    readBy(t, kContacts);  // out of a touching cell: a single cell has none
    since(t, 0.0);
    prepAt(t, 0.0);
    t.push_back({choice("numerics.contact_quadrature", {"exact", "dunavant7", "centroid"},
                        "integration of the contact pressure over the overlap polygon"),
                 [](SceneSpec& s) -> Slot { return &s.numerics.contact_quadrature; }});
    readBy(t, kContacts);
    prepAt(t, std::string("exact"));
    t.push_back({real("numerics.max_volume_error", kOpen, 0, 1, kClosed, "",
                      "relative cell volume error |V − V*|/V* that fails a step"),
                 [](SceneSpec& s) -> Slot { return &s.numerics.max_volume_error; }});
    prepAt(t, 0.05);
    t.push_back({real("numerics.max_penetration_um", kOpen, 0, 100, kClosed, "µm",
                      "depth of one cell inside another that fails a step"),
                 [](SceneSpec& s) -> Slot { return &s.numerics.max_penetration_um; }});
    readBy(t, kContacts);
    prepAt(t, 1.0);
    t.push_back({choice("numerics.contact_law", {"supplement", "prisms", "prisms-overlap"},
                        "part of a facing pair's overlap polygon that carries the contact "
                        "pressure: supplement, all of it; prisms, where each triangle lies over "
                        "the other; prisms-overlap, the overlapping part within the prisms, the "
                        "adhesive part whole"),
                 [](SceneSpec& s) -> Slot { return &s.numerics.contact_law; }});
    readBy(t, kContacts);
    since(t, std::string("supplement"));
    prepAt(t, std::string("supplement"));
    t.push_back(
        {boolean(
             "numerics.tension_implicit",
             "the surface tension's out-of-plane stiffness implicit, as the contact "
             "springs' (contact-implicit integrators): holds Δt 2 s, where the explicit tension "
             "oscillates"),
         [](SceneSpec& s) -> Slot { return &s.numerics.tension_implicit; }});
    readIf(t, oneStageImplicit, kOneStageImplicit);
    since(t, false);
    prepAt(t, false);
    t.push_back({integer("numerics.max_oscillating_steps", 1, 1e6,
                         "consecutive steps of reversing contact velocities (explicit-scheme "
                         "instability) that fail a step"),
                 [](SceneSpec& s) -> Slot { return &s.numerics.max_oscillating_steps; }});
    readBy(t, kContacts);
    prepAt(t, std::int64_t{10});
    t.push_back({boolean("numerics.adaptive",
                         "retry a failed step at half the time step, down to numerics.dt_min_s; "
                         "false: the first failed step ends the run"),
                 [](SceneSpec& s) -> Slot { return &s.numerics.adaptive; }});
    since(t, true);
    prepAt(t, true);
    t.push_back({real("numerics.dt_min_s", kOpen, 0, 10, kClosed, "s",
                      "smallest time step of the adaptive schedule; default dt_s/64", true),
                 [](SceneSpec& s) -> Slot { return &s.numerics.dt_min_s; }});
    readIf(
        t, [](const SceneSpec& s) { return s.numerics.adaptive; },
        "read only by the adaptive step (numerics.adaptive = true), which this spec turns off "
        "(numerics.adaptive = false)");
    prepAt(t, std::nullopt);
    t.back().at_before = [](const SceneSpec& s) {
      return dtMinS(s.numerics) == defaultDtMinS(s.numerics.dt_s);
    };
    t.push_back({real("numerics.max_step_error_um", kClosed, 0, 100, kClosed, "µm",
                      "ros2 only: retry at half the time step a step whose embedded error "
                      "estimate exceeds this; 0 = off"),
                 [](SceneSpec& s) -> Slot { return &s.numerics.max_step_error_um; }});
    // ---- [scene]
    t.push_back({real("scene.axes_ratio", kClosed, 0.2, 5, kClosed, "",
                      "cell: start as an ellipsoid (q r, r, r/q) of equal volume; 1 = sphere"),
                 [](SceneSpec& s) -> Slot { return &s.scene_params.axes_ratio; }});
    readBy(t, scenes(SceneKind::Cell));
    prepAt(t, 1.3);
    t.push_back({real("scene.gap_um", kClosed, 0, 10, kClosed, "µm",
                      "doublet: initial gap between the two cells; fusion: between the two "
                      "spheroids; unset: min(0.05, 0.8 h0), h0 = √(w/k_AB) the adhesion range",
                      true),
                 [](SceneSpec& s) -> Slot { return &s.scene_params.gap_um; }});
    readBy(t, scenes(SceneKind::Doublet) | kFusionOnly);
    prepAt(t, std::nullopt);
    t.push_back(
        {integer("scene.n_cells", 1, 2000, "spheroid: number of cells N; fusion: N per spheroid"),
         [](SceneSpec& s) -> Slot { return &s.scene_params.n_cells; }});
    readBy(t, scenes(SceneKind::Spheroid) | kFusionOnly);
    prepOwn(t);
    t.push_back({integer("scene.n_cells_a", 0, 2000, "fusion: cells in spheroid A; 0 = n_cells"),
                 [](SceneSpec& s) -> Slot { return &s.scene_params.n_cells_a; }});
    readBy(t, kFusionOnly);
    prepAt(t, std::int64_t{0});
    t.push_back({integer("scene.n_cells_b", 0, 2000, "fusion: cells in spheroid B; 0 = n_cells"),
                 [](SceneSpec& s) -> Slot { return &s.scene_params.n_cells_b; }});
    readBy(t, kFusionOnly);
    prepAt(t, std::int64_t{0});
    t.push_back({real("scene.prep_dt_s", kOpen, 0, 10, kClosed, "s",
                      "fusion: time step of the spheroids' preparation (relaxation of the packed "
                      "cells), always with the contact-implicit integrator"),
                 [](SceneSpec& s) -> Slot { return &s.scene_params.prep_dt_s; }});
    readBy(t, kFusionOnly);
    prepShared(t);
    t.push_back({real("scene.prep_max_s", kClosed, 0, 1e5, kClosed, "s",
                      "fusion: longest relaxation of a spheroid's packed cells; 0 = none"),
                 [](SceneSpec& s) -> Slot { return &s.scene_params.prep_max_s; }});
    readBy(t, kFusionOnly);
    prepShared(t);
    t.push_back({real("scene.prep_min_s", kClosed, 0, 1e5, kClosed, "s",
                      "fusion: shortest relaxation of a spheroid (compaction is not declared "
                      "before it); weak adhesion (cells.alpha >= 0.8) needs 300/(1 - alpha) s"),
                 [](SceneSpec& s) -> Slot { return &s.scene_params.prep_min_s; }});
    readBy(t, kFusionOnly);
    since(t, 0.0);
    prepShared(t);
    t.push_back({real("scene.compact_rate_per_s", kOpen, 0, 1, kClosed, "1/s",
                      "fusion: a spheroid is prepared (compact) when its radius of "
                      "gyration changes by less than this (relative, per second) over 60 s"),
                 [](SceneSpec& s) -> Slot { return &s.scene_params.compact_rate_per_s; }});
    readBy(t, kFusionOnly);
    prepShared(t);
    t.push_back({boolean("scene.allow_uncompacted",
                         "fusion: fuse spheroids that are not compact after scene.prep_max_s "
                         "as they are; false: the job fails with preparation-failed"),
                 [](SceneSpec& s) -> Slot { return &s.scene_params.allow_uncompacted; }});
    readBy(t, kFusionOnly);
    since(t, false);
    prepAt(t, false);
    t.push_back({boolean("scene.polarity_from_preparation",
                         "fusion: each cell keeps the polarity its spheroid's preparation ended "
                         "with; false: polarities drawn afresh at t = 0 (a start-up kick to "
                         "every protrusion)"),
                 [](SceneSpec& s) -> Slot { return &s.scene_params.polarity_from_preparation; }});
    readBy(t, kFusionOnly);
    since(t, false);
    prepAt(t, false);
    // ---- [accuracy]
    t.push_back({real("accuracy.contact_angle_deg", kOpen, 0, 90, kClosed, "°",
                      "accuracy target instead of numerics: largest acceptable error of the "
                      "equilibrium contact angle; the cheapest preset that promises it runs",
                      true),
                 [](SceneSpec& s) -> Slot { return &s.accuracy.contact_angle_deg; }});
    label(t);
    prepAt(t, std::nullopt);
    t.push_back({real("accuracy.trajectory_deg", kOpen, 0, 90, kClosed, "°",
                      "accuracy target instead of numerics: largest acceptable RMS error of the "
                      "contact angle on its way to equilibrium, θ(t)",
                      true),
                 [](SceneSpec& s) -> Slot { return &s.accuracy.trajectory_deg; }});
    label(t);
    prepAt(t, std::nullopt);
    // ---- [observe]: probes (probe.h). They change nothing of the run: the preparation runs
    // without them, and the fingerprint leaves them out while off (at true it holds them, so that
    // a checkpoint without a probe's state is refused by a run that asks for the probe).
    t.push_back({boolean("observe.rigid_motion",
                         "probe: sample columns rigid_turn_deg, the angle of the rotation that "
                         "best carries the cells' centroids at t = 0 onto those now (Kabsch), "
                         "and rigid_drift_um, how far their mean moved"),
                 [](SceneSpec& s) -> Slot { return &s.observe.rigid_motion; }});
    readBy(t, scenes(SceneKind::Spheroid) | kFusionOnly);  // a turn needs three cells or more
    since(t, false);
    prepAt(t, false);
    t.push_back({boolean("observe.dissipation",
                         "probe: sample columns of the power (nW) each friction term dissipates "
                         "in the step that ends at the sample, vᵀΓ_term v (medium, cortex, "
                         "contact friction ∥ and ⊥, the contact springs' implicit part), the "
                         "power vᵀF of the forces and of the active ones, the terms' dissipation "
                         "of each cell's affine part of v and the cortex's of its one-ring "
                         "jitter, and the RMS speed of the cells' centroids, absolute and "
                         "relative to their contacting neighbours' (µm/min)"),
                 [](SceneSpec& s) -> Slot { return &s.observe.dissipation; }});
    since(t, false);
    prepAt(t, false);
    t.push_back({boolean("observe.msrd_by_depth",
                         "probe: the MSRD split by where the pair's cells are at the origin: "
                         "sample columns cells_surface and cells_buried (free fraction of its "
                         "surface below 0.05), curves msrd_surface, msrd_mixed, msrd_buried and "
                         "msrd_layer0, msrd_layer1, msrd_layer2plus (the shallower cell's depth "
                         "in the contact graph), and the classes' mixing times"),
                 [](SceneSpec& s) -> Slot { return &s.observe.msrd_by_depth; }});
    readBy(t, kFusionOnly);  // the MSRD is a fusion's
    since(t, false);
    prepAt(t, false);
    t.push_back({real("observe.msrd_by_depth_after_s", kClosed, 0, 1e7, kClosed, "s",
                      "observe.msrd_by_depth counts only origins at or after this time: the "
                      "split of a fused doublet's MSRD without the fusion's own flow"),
                 [](SceneSpec& s) -> Slot { return &s.observe.msrd_by_depth_after_s; }});
    readBy(t, kFusionOnly);
    readIf(
        t, [](const SceneSpec& s) { return s.observe.msrd_by_depth; },
        "read only with observe.msrd_by_depth = true, which this spec leaves off");
    since(t, 0.0);
    prepAt(t, 0.0);
    t.push_back({boolean("observe.shape",
                         "probe: sample columns of the cells' shape: the shape index of each "
                         "cell's mesh after Taubin smoothing (shape_index_smoothed_mean), the "
                         "elongation (elongation_mean), the contact fraction of its surface "
                         "(contact_fraction_mean) and the regression of the shape index on the "
                         "contact fraction over the cells (shape_on_contact_slope, _intercept, "
                         "_r)"),
                 [](SceneSpec& s) -> Slot { return &s.observe.shape; }});
    readBy(t, scenes(SceneKind::Spheroid) | kFusionOnly);  // the cells of an aggregate
    since(t, false);
    prepAt(t, false);
    t.push_back({boolean("observe.torque",
                         "probe: sample columns of the aggregate as a body in the step that ends "
                         "at the sample: the forces' net force and torque, the rigid part of the "
                         "solved velocity (rigid_speed_um_h, rigid_spin_deg_h), the torque the "
                         "medium exerts on it and the shares of the cortex, contact friction "
                         "and contact springs in it"),
                 [](SceneSpec& s) -> Slot { return &s.observe.torque; }});
    readBy(t, kFusionOnly);  // an aggregate that turns
    since(t, false);
    prepAt(t, false);
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

}  // namespace spec_internal

const std::vector<SpecField>& specFields() {
  static const std::vector<SpecField> fields = [] {
    std::vector<SpecField> f;
    for (const Entry& e : entries()) f.push_back(e.field);
    return f;
  }();
  return fields;
}

std::string unreadCondition(const SceneSpec& spec, std::string_view key) {
  const Entry* e = findEntry(key);
  if (!e || !e->read_if || e->read_if(spec)) return {};
  return e->read_if_text;
}

const SpecField* findField(std::string_view key) {
  const Entry* e = findEntry(key);
  if (!e) return nullptr;
  // Same index in specFields() as in entries().
  return &specFields()[static_cast<std::size_t>(e - entries().data())];
}

}  // namespace activefoam
