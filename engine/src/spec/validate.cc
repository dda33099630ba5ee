// What may run and what is refused: validate() (ranges and cross-field rules),
// measuredUnstable() (time steps the stability study saw fail) and silentlyWrong() (settings
// that run but give a wrong answer).
#include "activefoam/spec.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <string>
#include <vector>

#include "spec_internal.h"

namespace activefoam {

using namespace spec_internal;

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
                  ", 90] ° (the finest: `reference`, docs/science/presets.md)");
      if (spec.accuracy.trajectory_deg && *spec.accuracy.trajectory_deg < tr)
        error("accuracy.trajectory_deg",
              formatNumber(*spec.accuracy.trajectory_deg) +
                  "° is finer than any preset promises; allowed [" + formatNumber(tr) +
                  ", 90] ° (the finest: `reference`, docs/science/presets.md)");
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
    if (c.tau_shell_s && c.tau_k_s && spec.numerics.remesh_every_s)
      error("cells.tau_shell_s",
            "is read by nothing here: it gives only the defaults of cells.tau_k_s and "
            "numerics.remesh_every_s, and this spec sets both");
    if (!c.tau_k_s)
      derived("cells.tau_k_s", "cells.tau_k_s", *r.cells.tau_k_s,
              "unset, and its default 2 τ_shell");
    if (!spec.numerics.remesh_every_s)
      derived("numerics.remesh_every_s", "numerics.remesh_every_s", *r.numerics.remesh_every_s,
              "unset, and its default 5 τ_shell");
  }

  // [prepare]: keys the preparation may run at values of its own (setField's check, for a table
  // filled otherwise), on a scene that prepares spheroids; and the preparation's spec passes the
  // rules the run's does (the values its keys derive included).
  for (const auto& [key, value] : spec.prepare) {
    SceneSpec scratch;
    const std::string name = "prepare." + key;
    if (auto e = setField(scratch, name, value))
      error(name, e->message);
    else if (spec.scene != SceneKind::Fusion)
      error(name, "only the fusion scene prepares spheroids, and this spec's scene is " +
                      std::string(toString(spec.scene)) + ": remove [prepare]");
  }
  if (!spec.prepare.empty() && errors.empty())
    for (const SpecError& e : validate(withPrepareValues(spec)))
      error("prepare." + e.field, e.message);
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
    // ros2's own map: 2 s ran everywhere (k_AB × 1/64 … 4, p_a r/2γ 0 … 1; and on
    // 1280 triangles in the doublet study), 4 s drifted out of volume everywhere.
    limit = 4.0;
    why = "ros2 was measured to fail from 4 s (volume-drift at every k_AB and motility of the map)";
    kind = "docs/study/stability-map.md";
  } else if (n.integrator == IntegratorKind::ContactImplicitConsistent &&
             n.triangles_per_cell < 1280) {
    // Its own map: 1 s ran at every k_AB × 1/64 … 4 and p_a r/2γ 0 … 1, 2 s
    // oscillated everywhere. But the motile 2 × 20 fusion at 1 s (ε_CG 1e-2) inverted triangles
    // at 53 and 86 min and died of a cell's volume error at 86 min, which the rollback cannot
    // undo: with motility the limit is 1 s, as contact-implicit's.
    // Those failures were the law's false overlaps (a pair of nearly perpendicular triangles
    // read micrometres deep beside them): with the overlap kept within the prisms the same
    // motile fusion ran 4 h at 1 s on seeds 1–3 without a step redone, so the bound
    // gets the map's 2 s.
    const bool bounded = n.contact_law != ContactLawKind::Supplement;
    const bool motile_limit = motile && !bounded;
    limit = motile_limit ? 1.0 : 2.0;
    why = motile_limit
              ? "contact-implicit-consistent was measured to fail from 1 s with motility (the "
                "2 × 20 fusion: inverted triangles, then a cell's volume error beyond "
                "numerics.max_volume_error after 86 min; with numerics.contact_law = "
                "prisms-overlap it ran at 1 s)"
              : "contact-implicit-consistent was measured to fail from 2 s (contact-oscillation "
                "at every k_AB of the map)";
    kind = motile_limit ? "docs/science/motion-convergence.md" : "docs/study/stability-map.md";
    adaptive_settles = !motile_limit;  // that run was adaptive: rejecting tries did not save it
    if (bounded && n.tension_implicit) {
      // The 2 s oscillation is the explicit tension's (docs/numerics.md): with its out-of-plane
      // stiffness implicit the doublet and the motile 2 × 20 fusion ran 2 s without a step
      // redone. 4 s held too, but damps a fifth of the cells' motion: not offered.
      limit = 4.0;
      why =
          "contact-implicit-consistent with numerics.tension_implicit ran 2 s on the doublet "
          "and the 2 × 20 fusion without a step redone; at 4 s it loses a fifth of the cells' "
          "motion";
      kind = "docs/numerics.md";
      adaptive_settles = false;  // 4 s held: the limit is the motion's, not stability's
    }
  } else {
    // contact-implicit. The first map (polarity noise keyed by step) failed at 1 s with
    // motility; the map with the noise keyed by time ran 1 s there and failed at 2 s: the
    // lower limit stays. The map with smoothing on the surface failed at 1 s without
    // motility too, at k_AB × 1, and 1 s is a draw there: with k_AB within ±3 % 3 of 6 runs
    // oscillated with the earlier smoothing, 4 of 6 with today's. contact-implicit-consistent
    // with 1280 triangles has no map: it gets contact-implicit's limit there.
    limit = 1.0;
    why = std::string(n.integrator == IntegratorKind::ContactImplicitConsistent
                          ? "contact-implicit-consistent has no stability map with 1280 "
                            "triangles per cell; contact-implicit was measured to fail from "
                          : "the contact-implicit integrator was measured to fail from ") +
          formatNumber(limit) + " s";
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
  // The preparation's α: [prepare] may give one.
  const double alpha = withPrepareValues(r).cells.alpha;
  const std::string alpha_key =
      r.prepare.count("cells.alpha") ? "prepare.cells.alpha" : "cells.alpha";
  if (spec.scene == SceneKind::Fusion && sp.prep_max_s > 0 && alpha >= kWeakAdhesionAlpha) {
    const double need = weakAdhesionPrepMinS(alpha);
    if (sp.prep_min_s < need)
      out.push_back(
          {"scene.prep_min_s",
           formatNumber(sp.prep_min_s) + " s lets a spheroid at " + alpha_key + " = " +
               formatNumber(alpha) +
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

}  // namespace activefoam
