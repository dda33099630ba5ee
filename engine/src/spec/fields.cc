// The key table: every key of the scene spec with its type, range, unit, help and the place its
// value lives in a SceneSpec (docs/model.md §9). Adding a key is one entry here.
#include "activefoam/spec.h"

#include <string>
#include <utility>
#include <vector>

#include "spec_internal.h"

namespace activefoam {

using namespace spec_internal;

namespace {

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
    t.push_back(
        {choice("numerics.integrator",
                {"semi-implicit", "contact-implicit", "ros2", "contact-implicit-consistent"},
                "semi-implicit: forces explicit, friction implicit; contact-implicit: "
                "also the contact springs' normal stiffness, one spring per pair (the "
                "cells' motion depends on Δt); ros2: two stages, second order, the "
                "consistent stiffness (two solves per step); contact-implicit-consistent: "
                "one stage with the consistent stiffness (motion converged in Δt; more CG "
                "iterations)"),
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
    t.push_back({boolean("numerics.remesh_on_surface",
                         "remeshing's smoothing keeps vertices on the cell's surface and "
                         "restores the volume by one normal offset of the whole cell; false: "
                         "by moving the smoothed vertex along its normal (earlier versions), "
                         "which can push it into a neighbouring cell"),
                 [](SceneSpec& s) -> Slot { return &s.numerics.remesh_on_surface; }});
    t.push_back({boolean("numerics.remesh_rescue",
                         "a cell's remesh that leaves a triangle below half of the collapse area "
                         "runs again, allowing collapses that leave a vertex of valence 3; false: "
                         "such collapses are always refused (earlier versions), which can lock a "
                         "shrinking triangle among vertices of valence 4 until it inverts"),
                 [](SceneSpec& s) -> Slot { return &s.numerics.remesh_rescue; }});
    t.push_back({boolean("numerics.remesh_rebuild",
                         "a cell's remesh that still leaves a triangle below half of the collapse "
                         "area rebuilds the cell's mesh: a fresh icosphere of triangles_per_cell "
                         "laid on its surface from its centroid; false: the cell keeps its mesh "
                         "(earlier versions), and a sliver the remesher cannot remove can flatten "
                         "until it inverts"),
                 [](SceneSpec& s) -> Slot { return &s.numerics.remesh_rebuild; }});
    t.push_back({real("numerics.remesh_keep_out_um", kClosed, 0, 100, kClosed, "µm",
                      "a collapse that would put the merged vertex deeper than this inside a "
                      "cell this one touches (and deeper than the vertices it merges) is "
                      "refused, and so is a rebuild that would put a touching cell's vertex "
                      "that deep inside this one; 0: off, every such collapse is done (earlier "
                      "versions), and a "
                      "remesh can push a pressed cell's vertex into its neighbour past the "
                      "interpenetration guard at every step length"),
                 [](SceneSpec& s) -> Slot { return &s.numerics.remesh_keep_out_um; }});
    t.push_back({choice("numerics.contact_quadrature", {"exact", "dunavant7", "centroid"},
                        "integration of the contact pressure over the overlap polygon"),
                 [](SceneSpec& s) -> Slot { return &s.numerics.contact_quadrature; }});
    t.push_back({real("numerics.max_volume_error", kOpen, 0, 1, kClosed, "",
                      "relative cell volume error |V − V*|/V* that stops the run as failed"),
                 [](SceneSpec& s) -> Slot { return &s.numerics.max_volume_error; }});
    t.push_back({real("numerics.max_penetration_um", kOpen, 0, 100, kClosed, "µm",
                      "depth of a vertex of one cell inside another that stops the run as failed "
                      "(after halving the step to numerics.dt_min_s)"),
                 [](SceneSpec& s) -> Slot { return &s.numerics.max_penetration_um; }});
    t.push_back({real("numerics.contact_max_facing_deg", kOpen, 0, 90, kClosed, "°",
                      "triangle pairs touch only when their normals face each other within this "
                      "angle of antiparallel; 90: every facing pair"),
                 [](SceneSpec& s) -> Slot { return &s.numerics.contact_max_facing_deg; }});
    t.push_back({real("numerics.contact_max_overlap_um", kClosed, 0, 10, kClosed, "µm",
                      "overlap of two triangles beyond which the contact pressure stops "
                      "growing (at least the adhesion range h0); 0: it grows without bound"),
                 [](SceneSpec& s) -> Slot { return &s.numerics.contact_max_overlap_um; }});
    t.push_back({boolean("numerics.contact_within_prisms",
                         "a pair's contact keeps only the points where each triangle lies over "
                         "the other (inside its normal prism); false: the whole overlap of their "
                         "projections on the bisector plane"),
                 [](SceneSpec& s) -> Slot { return &s.numerics.contact_within_prisms; }});
    t.push_back({boolean("numerics.contact_prisms_overlap_only",
                         "with numerics.contact_within_prisms: only the overlapping part of a "
                         "pair's contact (gap < 0) is kept within the prisms, the adhesive part "
                         "whole; false: the whole contact"),
                 [](SceneSpec& s) -> Slot { return &s.numerics.contact_prisms_overlap_only; }});
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
    t.push_back({boolean("scene.polarity_from_preparation",
                         "fusion: each cell keeps the polarity its spheroid's preparation ended "
                         "with; false: polarities drawn afresh at t = 0 (a start-up kick to "
                         "every protrusion)"),
                 [](SceneSpec& s) -> Slot { return &s.scene_params.polarity_from_preparation; }});
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

}  // namespace spec_internal

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

}  // namespace activefoam
