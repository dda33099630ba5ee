// The scene spec: defaults (docs/model.md §9), the key table, set/get, validate, resolve.
#include <cmath>
#include <set>

#include <gtest/gtest.h>

#include "activefoam/spec.h"

namespace activefoam {
namespace {

bool hasErrorFor(const std::vector<SpecError>& errors, const std::string& field) {
  for (const SpecError& e : errors)
    if (e.field == field) return true;
  return false;
}

std::string joined(const std::vector<SpecError>& errors) {
  std::string s;
  for (const SpecError& e : errors) s += e.str() + "\n";
  return s;
}

TEST(Spec, DefaultsAreTheDesignValues) {
  const SceneSpec s;
  EXPECT_EQ(s.scene, SceneKind::Fusion);
  EXPECT_EQ(s.seed, 1u);
  EXPECT_EQ(s.duration_s, 86400);
  EXPECT_EQ(s.sample_every_s, 60);
  EXPECT_EQ(s.snapshot_every_s, 600);
  EXPECT_EQ(s.cells.radius_mean_um, 8.88);
  EXPECT_EQ(s.cells.radius_gamma_k, 37);
  EXPECT_EQ(s.cells.gamma, 0.5);
  EXPECT_EQ(s.cells.eta, 5.0);
  EXPECT_EQ(s.cells.eta_m, 0.4);
  EXPECT_EQ(s.cells.bulk_modulus, 0.5);
  EXPECT_EQ(s.cells.alpha, 0.4375);
  EXPECT_EQ(s.cells.p_a, 0.0372);
  EXPECT_EQ(s.cells.tau_p_s, 600);
  EXPECT_EQ(s.cells.xi, 0.25);
  EXPECT_EQ(s.cells.k_contact, 71.1);
  EXPECT_EQ(s.cells.eps_n, 0.1);
  EXPECT_FALSE(s.cells.tau_k_s);
  EXPECT_FALSE(s.cells.tau_gamma_s);
  EXPECT_FALSE(s.cells.pa_reduced);
  EXPECT_FALSE(s.cells.l_eta_reduced);
  // The numerics: the `standard` preset, the figure studies' step.
  EXPECT_EQ(s.numerics.preset, FidelityPreset::Standard);
  EXPECT_EQ(s.numerics.dt_s, 1.0);
  EXPECT_EQ(s.numerics.integrator, IntegratorKind::ContactImplicitConsistent);
  EXPECT_EQ(s.numerics.cg_tol, 1e-2);
  EXPECT_EQ(s.numerics.contact_law, ContactLawKind::PrismsOverlap);
  EXPECT_EQ(s.numerics.remesh_repair, RemeshRepair::RescueRebuild);
  EXPECT_EQ(s.numerics.max_volume_error, 0.2);
  EXPECT_TRUE(s.scene_params.polarity_from_preparation);
  EXPECT_EQ(s.numerics.triangles_per_cell, 320);
  EXPECT_FALSE(s.numerics.remesh_every_s);
  EXPECT_DOUBLE_EQ(s.numerics.remesh_min_area_factor, 1.0 / 3.0);
  EXPECT_EQ(s.numerics.remesh_max_area_factor, 3.0);
  EXPECT_EQ(s.numerics.contact_quadrature, ContactQuadrature::Exact);
  EXPECT_EQ(s.scene_params.n_cells, 100);
  EXPECT_TRUE(validate(s).empty()) << joined(validate(s));
}

TEST(Spec, DerivedQuantitiesOfTheDefaults) {
  const CellParams c;
  EXPECT_NEAR(tauShell(c), 2.88675, 1e-5);  // η/(2√3 γ)
  EXPECT_NEAR(adhesionW(c), 0.28125, 1e-12);
  EXPECT_NEAR(contactRangeH0(c), std::sqrt(0.28125 / 71.1), 1e-12);     // ≈ 63 nm
  EXPECT_NEAR(std::acos(c.alpha) * 180 / M_PI, 64.06, 0.01);            // θ_c
  EXPECT_NEAR(c.p_a * c.radius_mean_um / (2 * c.gamma), 0.33, 0.001);   // Table 2
  EXPECT_NEAR(std::sqrt(c.eta / c.xi) / c.radius_mean_um, 0.50, 0.01);  // L_η/r
}

TEST(Spec, ResolveFillsDerivedDefaults) {
  const SceneSpec r = resolve(SceneSpec{});
  ASSERT_TRUE(r.cells.tau_k_s);
  EXPECT_NEAR(*r.cells.tau_k_s, 5.7735, 1e-4);  // 2 τ_shell
  ASSERT_TRUE(r.numerics.remesh_every_s);
  EXPECT_NEAR(*r.numerics.remesh_every_s, 14.43, 0.01);  // 5 τ_shell
  ASSERT_TRUE(r.cells.xi_normal && r.cells.xi_tangential);
  EXPECT_EQ(*r.cells.xi_normal, 0.25);
  EXPECT_EQ(*r.cells.xi_tangential, 0.25);
  EXPECT_TRUE(validate(r).empty()) << joined(validate(r));
}

TEST(Spec, ResolveKeepsExplicitValues) {
  SceneSpec s;
  s.cells.tau_k_s = 3.0;
  s.numerics.remesh_every_s = 0.0;  // remeshing off stays off
  s.cells.xi_normal = 1.0;
  const SceneSpec r = resolve(s);
  EXPECT_EQ(*r.cells.tau_k_s, 3.0);
  EXPECT_EQ(*r.numerics.remesh_every_s, 0.0);
  EXPECT_EQ(*r.cells.xi_normal, 1.0);
  EXPECT_EQ(*r.cells.xi_tangential, 0.25);
}

TEST(Spec, ReducedParametersBecomeAbsolute) {
  SceneSpec s;
  s.cells.tau_gamma_s = 20.0;
  s.cells.pa_reduced = 0.33;
  s.cells.l_eta_reduced = 0.25;
  ASSERT_TRUE(validate(s).empty()) << joined(validate(s));
  const SceneSpec r = resolve(s);
  EXPECT_DOUBLE_EQ(r.cells.eta, 20.0 * 0.5);
  EXPECT_DOUBLE_EQ(r.cells.p_a, 0.33 * 2 * 0.5 / 8.88);
  EXPECT_NEAR(r.cells.p_a, 0.0372, 1e-4);
  EXPECT_DOUBLE_EQ(r.cells.xi, 10.0 / std::pow(0.25 * 8.88, 2));
  // The result states absolute values only.
  EXPECT_FALSE(r.cells.tau_gamma_s);
  EXPECT_FALSE(r.cells.pa_reduced);
  EXPECT_FALSE(r.cells.l_eta_reduced);
  // Derived defaults use the resolved η.
  EXPECT_NEAR(*r.cells.tau_k_s, 2 * 10.0 / (2 * std::sqrt(3.0) * 0.5), 1e-12);
  EXPECT_EQ(*r.cells.xi_normal, r.cells.xi);
}

TEST(Spec, ReducedValuesWinOverAbsoluteOnes) {
  SceneSpec s;
  s.cells.p_a = 1.0;
  s.cells.pa_reduced = 0.444;  // Table 1's 50 Pa
  EXPECT_NEAR(resolve(s).cells.p_a, 0.05, 1e-4);
}

// Fig. 10 varies γ at fixed η and holds τ_shell at Table 1's γ_ref: the one key gives τ_K and τ_r
// the values the study's committed runs set by hand (bit for bit, so that they stay its runs).
TEST(Spec, ShellTimeGivesTauKAndTheRemeshIntervalWhereUnset) {
  SceneSpec s;
  s.cells.gamma = 1.0;
  s.cells.tau_gamma_s = 5;  // η = 5 at γ = 1: its own τ_shell is half the base one
  s.cells.tau_shell_s = 5.0 / (2 * std::sqrt(3.0) * 0.5);
  ASSERT_TRUE(validate(s).empty()) << joined(validate(s));
  SceneSpec r = resolve(s);
  EXPECT_EQ(*r.cells.tau_k_s, 5.773502691896258);
  EXPECT_EQ(*r.numerics.remesh_every_s, 14.433756729740645);
  EXPECT_FALSE(r.cells.tau_shell_s);  // what it gave is in τ_K and τ_r
  // At the run's own γ they would be half that.
  s.cells.tau_shell_s.reset();
  r = resolve(s);
  EXPECT_DOUBLE_EQ(*r.cells.tau_k_s, 5.773502691896258 / 2);
  EXPECT_DOUBLE_EQ(*r.numerics.remesh_every_s, 14.433756729740645 / 2);
  // Unset, the defaults are those of before the key, bit for bit.
  const CellParams c;
  EXPECT_EQ(*resolve(SceneSpec{}).cells.tau_k_s, 2.0 * (c.eta / (2.0 * std::sqrt(3.0) * c.gamma)));
  // A value given wins over it; given both, nothing reads it, and it is refused.
  s.cells.tau_shell_s = 4.0;
  s.cells.tau_k_s = 3.0;
  r = resolve(s);
  EXPECT_EQ(*r.cells.tau_k_s, 3.0);
  EXPECT_EQ(*r.numerics.remesh_every_s, 20.0);
  s.numerics.remesh_every_s = 10.0;
  const auto errors = validate(s);
  ASSERT_TRUE(hasErrorFor(errors, "cells.tau_shell_s")) << joined(errors);
  EXPECT_NE(joined(errors).find("sets both"), std::string::npos) << joined(errors);
  // The fingerprint of a spec without it is that of before the key (checkpoints resume).
  EXPECT_EQ(specFingerprint(SceneSpec{}).find("tau_shell"), std::string::npos);
  SceneSpec with;
  with.cells.tau_shell_s = 4.0;
  EXPECT_NE(specFingerprint(with), specFingerprint(SceneSpec{}));
}

TEST(Spec, ResolveIsIdempotent) {
  SceneSpec s;
  s.scene = SceneKind::Doublet;
  s.cells.tau_gamma_s = 12.0;
  s.cells.pa_reduced = 0.5;
  s.cells.l_eta_reduced = 0.7;
  s.cells.xi_tangential = 0.1;
  const SceneSpec once = resolve(s);
  EXPECT_EQ(resolve(once), once);
  EXPECT_EQ(resolve(SceneSpec{}), resolve(resolve(SceneSpec{})));
}

TEST(Spec, TableListsEveryKeyOnceInDesignOrder) {
  const auto& fields = specFields();
  ASSERT_GE(fields.size(), 38u);
  EXPECT_EQ(fields[0].key, "scene");
  EXPECT_EQ(fields[1].key, "seed");
  EXPECT_EQ(fields[2].key, "duration_s");
  EXPECT_EQ(fields[3].key, "sample_every_s");
  EXPECT_EQ(fields[4].key, "snapshot_every_s");
  EXPECT_EQ(fields[5].key, "cells.radius_mean_um");
  std::set<std::string> keys;
  std::string last_table;
  std::set<std::string> tables_done;
  for (const SpecField& f : fields) {
    EXPECT_TRUE(keys.insert(f.key).second) << "duplicate " << f.key;
    EXPECT_FALSE(f.help.empty()) << f.key;
    EXPECT_EQ(findField(f.key), &f);
    const auto dot = f.key.find('.');
    const std::string table = dot == std::string::npos ? "" : f.key.substr(0, dot);
    if (table != last_table) {  // tables are contiguous
      EXPECT_TRUE(tables_done.insert(table).second) << f.key;
      last_table = table;
    }
    if (f.type == FieldType::Choice) {
      EXPECT_FALSE(f.choices.empty()) << f.key;
    }
  }
  for (const char* k :
       {"cells.gamma", "cells.tau_gamma_s", "cells.pa_reduced", "cells.l_eta_reduced",
        "numerics.dt_s", "numerics.integrator", "numerics.triangles_per_cell",
        "numerics.remesh_every_s", "numerics.contact_quadrature", "scene.axes_ratio",
        "scene.gap_um", "scene.n_cells", "scene.n_cells_a", "scene.n_cells_b"})
    EXPECT_TRUE(keys.count(k)) << k;
  EXPECT_EQ(findField("scene.kind"), findField("scene"));
  EXPECT_EQ(findField("cells.gama"), nullptr);
}

TEST(Spec, RangeText) {
  EXPECT_EQ(findField("numerics.dt_s")->range(), "(0, 10]");
  EXPECT_EQ(findField("cells.gamma")->range(), "(0, 100]");
  EXPECT_EQ(findField("cells.alpha")->range(), "[0, 1)");
  EXPECT_EQ(findField("scene")->range(), "one of cell|doublet|spheroid|fusion");
  EXPECT_EQ(findField("numerics.triangles_per_cell")->range(), "one of 80|320|1280");
}

// A valid value of each key, different from the default where possible.
SpecValue sampleValue(const SpecField& f, const SpecValue& current) {
  if (f.type == FieldType::Boolean) return !std::get<bool>(current);
  if (f.type == FieldType::Choice)
    return f.choices.back() == std::get<std::string>(current) ? f.choices.front()
                                                              : f.choices.back();
  if (!f.choices.empty()) return std::int64_t{80};
  if (f.type == FieldType::Integer) {
    const auto v = static_cast<std::int64_t>(f.lo) + 1;
    return v;
  }
  return f.lo_open || f.lo == 0 ? f.lo + (f.hi - f.lo) * 0.01 + 0.125 : f.lo;
}

TEST(Spec, EveryFieldRoundTripsThroughSetAndGet) {
  for (const SpecField& f : specFields()) {
    SceneSpec s;
    const std::optional<SpecValue> before = getField(s, f.key);
    EXPECT_EQ(before.has_value(), !f.optional) << f.key;
    const SpecValue v = sampleValue(f, before.value_or(SpecValue{0.0}));
    ASSERT_EQ(setField(s, f.key, v), std::nullopt) << f.key;
    const std::optional<SpecValue> after = getField(s, f.key);
    ASSERT_TRUE(after) << f.key;
    EXPECT_EQ(*after, v) << f.key;
    // And the value written back gives the same spec.
    SceneSpec again;
    ASSERT_EQ(setField(again, f.key, *after), std::nullopt) << f.key;
    EXPECT_EQ(again, s) << f.key;
    if (f.optional) {
      EXPECT_EQ(clearField(s, f.key), std::nullopt);
      EXPECT_FALSE(getField(s, f.key)) << f.key;
    } else {
      EXPECT_NE(clearField(s, f.key), std::nullopt) << f.key;
    }
  }
}

TEST(Spec, SetFieldConvertsNumbers) {
  SceneSpec s;
  EXPECT_EQ(setField(s, "cells.gamma", std::int64_t{2}), std::nullopt);  // integer for Real
  EXPECT_EQ(s.cells.gamma, 2.0);
  EXPECT_EQ(setField(s, "scene.n_cells", 50.0), std::nullopt);  // integral double for Integer
  EXPECT_EQ(s.scene_params.n_cells, 50);
  EXPECT_EQ(setField(s, "seed", 9007199254740992.0), std::nullopt);  // 2^53
  EXPECT_EQ(s.seed, 9007199254740992ull);
  EXPECT_EQ(setField(s, "scene.kind", std::string("doublet")), std::nullopt);
  EXPECT_EQ(s.scene, SceneKind::Doublet);
  EXPECT_EQ(std::get<std::string>(*getField(s, "scene.kind")), "doublet");
  EXPECT_EQ(setField(s, "numerics.preconditioner", std::string("block-jacobi")), std::nullopt);
  EXPECT_EQ(s.numerics.preconditioner, PreconditionerKind::BlockJacobi);
  EXPECT_EQ(setField(s, "numerics.preconditioner", std::string("incomplete-cholesky")),
            std::nullopt);
  EXPECT_EQ(s.numerics.preconditioner, PreconditionerKind::IncompleteCholesky);
}

TEST(Spec, SetFieldErrorsNameTheKey) {
  SceneSpec s;
  const SceneSpec untouched = s;
  auto err = setField(s, "cells.gamma", 0.0);
  ASSERT_TRUE(err);
  EXPECT_EQ(err->field, "cells.gamma");
  EXPECT_EQ(err->str(), "cells.gamma: 0 is outside the allowed range (0, 100] nN/µm");

  err = setField(s, "numerics.dt_s", -1.0);
  ASSERT_TRUE(err);
  EXPECT_EQ(err->str(), "numerics.dt_s: -1 is outside the allowed range (0, 10] s");

  err = setField(s, "cells.gama", 1.0);
  ASSERT_TRUE(err);
  EXPECT_EQ(err->field, "cells.gama");
  EXPECT_NE(err->message.find("unknown key 'cells.gama'"), std::string::npos);
  EXPECT_NE(err->message.find("cells.gamma"), std::string::npos);  // the suggestion

  err = setField(s, "gamma", 1.0);
  ASSERT_TRUE(err);
  EXPECT_NE(err->message.find("cells.gamma"), std::string::npos);

  err = setField(s, "cells.eta", std::nan(""));
  ASSERT_TRUE(err);
  EXPECT_EQ(err->field, "cells.eta");
  EXPECT_NE(err->message.find("finite"), std::string::npos);

  err = setField(s, "duration_s", INFINITY);
  ASSERT_TRUE(err);
  EXPECT_EQ(err->field, "duration_s");

  err = setField(s, "scene.n_cells", 2.5);
  ASSERT_TRUE(err);
  EXPECT_NE(err->message.find("not an integer"), std::string::npos);

  err = setField(s, "scene.n_cells", 1e9);
  ASSERT_TRUE(err);
  EXPECT_EQ(err->str(), "scene.n_cells: 1e9 is outside the allowed range [1, 2000]");

  err = setField(s, "numerics.triangles_per_cell", std::int64_t{100});
  ASSERT_TRUE(err);
  EXPECT_EQ(err->str(), "numerics.triangles_per_cell: 100 is not one of 80|320|1280");

  err = setField(s, "scene", std::string("blob"));
  ASSERT_TRUE(err);
  EXPECT_EQ(err->str(), "scene: 'blob' is not one of cell|doublet|spheroid|fusion");

  err = setField(s, "scene", 3.0);
  ASSERT_TRUE(err);
  EXPECT_EQ(err->field, "scene");

  err = setField(s, "seed", std::string("one"));
  ASSERT_TRUE(err);
  EXPECT_EQ(err->str(), "seed: expected an integer, got 'one'");

  err = setField(s, "seed", -1.0);
  ASSERT_TRUE(err);
  EXPECT_EQ(err->field, "seed");

  err = setField(s, "cells.alpha", 1.0);
  ASSERT_TRUE(err);
  EXPECT_EQ(err->str(), "cells.alpha: 1 is outside the allowed range [0, 1)");

  err = setField(s, "cells.radius_gamma_k", 0.5);
  ASSERT_TRUE(err);
  EXPECT_EQ(err->field, "cells.radius_gamma_k");

  err = setField(s, "cells.xi", true);
  ASSERT_TRUE(err);
  EXPECT_EQ(err->field, "cells.xi");

  EXPECT_EQ(s, untouched);  // a failed set changes nothing
}

TEST(Spec, ValidateReportsEveryError) {
  SceneSpec s;
  s.numerics.dt_s = -1;
  s.cells.gamma = 0;
  s.cells.eta = std::nan("");
  s.scene_params.n_cells = 100000;
  const auto errors = validate(s);
  EXPECT_TRUE(hasErrorFor(errors, "numerics.dt_s")) << joined(errors);
  EXPECT_TRUE(hasErrorFor(errors, "cells.gamma")) << joined(errors);
  EXPECT_TRUE(hasErrorFor(errors, "cells.eta")) << joined(errors);
  EXPECT_TRUE(hasErrorFor(errors, "scene.n_cells")) << joined(errors);
  EXPECT_EQ(errors.size(), 4u) << joined(errors);
}

TEST(Spec, CrossFieldRules) {
  {
    SceneSpec s;
    s.duration_s = 30;  // sample_every_s = 60
    EXPECT_TRUE(hasErrorFor(validate(s), "sample_every_s"));
  }
  {
    SceneSpec s;
    s.sample_every_s = 0.01;  // < dt
    EXPECT_TRUE(hasErrorFor(validate(s), "sample_every_s"));
  }
  {
    SceneSpec s;
    s.snapshot_every_s = 0;  // none: fine
    EXPECT_TRUE(validate(s).empty());
    s.snapshot_every_s = 0.5;  // 172800 snapshots
    EXPECT_TRUE(hasErrorFor(validate(s), "snapshot_every_s"));
  }
  {
    SceneSpec s;
    s.numerics.dt_s = 1e-6;  // 8.64e10 steps
    EXPECT_TRUE(hasErrorFor(validate(s), "numerics.dt_s"));
  }
  {
    SceneSpec s;
    s.numerics.remesh_min_area_factor = 0.8;
    s.numerics.remesh_max_area_factor = 1.5;
    EXPECT_TRUE(hasErrorFor(validate(s), "numerics.remesh_max_area_factor"));
  }
  {
    SceneSpec s;  // fusion: 2 × 2000 cells × 320 triangles = 1.28e6: allowed
    s.scene_params.n_cells = 2000;
    EXPECT_TRUE(validate(s).empty()) << joined(validate(s));
    s.numerics.triangles_per_cell = 1280;  // 5.12e6 triangles
    EXPECT_TRUE(hasErrorFor(validate(s), "scene.n_cells"));
    s.scene = SceneKind::Cell;  // n_cells does not apply to one cell
    EXPECT_TRUE(validate(s).empty()) << joined(validate(s));
  }
  {
    SceneSpec s;
    s.cells.tau_gamma_s = 1e5;
    s.cells.gamma = 50;  // η = 5e6, beyond its range
    EXPECT_TRUE(hasErrorFor(validate(s), "cells.tau_gamma_s"));
  }
  {
    SceneSpec s;
    s.cells.pa_reduced = 50;
    s.cells.gamma = 100;
    s.cells.radius_mean_um = 1;  // p_a = 1e4 kPa
    EXPECT_TRUE(hasErrorFor(validate(s), "cells.pa_reduced"));
  }
  {
    SceneSpec s;
    s.cells.l_eta_reduced = 1e-3;  // ξ = 5/(0.00888)² ≈ 6.3e4
    EXPECT_TRUE(hasErrorFor(validate(s), "cells.l_eta_reduced"));
  }
  {
    SceneSpec s;
    s.cells.eta = 1e4;
    s.cells.gamma = 1e-3;  // τ_shell ≈ 2.9e6 s: default τ_K out of range
    EXPECT_TRUE(hasErrorFor(validate(s), "cells.tau_k_s")) << joined(validate(s));
    s.cells.tau_k_s = 10;
    s.numerics.remesh_every_s = 100;
    EXPECT_TRUE(validate(s).empty()) << joined(validate(s));
  }
}

TEST(Spec, FormatNumber) {
  EXPECT_EQ(formatNumber(0.1), "0.1");
  EXPECT_EQ(formatNumber(86400), "86400");
  EXPECT_EQ(formatNumber(1e7), "1e7");
  EXPECT_EQ(formatNumber(1e-5), "1e-5");
  EXPECT_EQ(formatNumber(-1), "-1");
  EXPECT_EQ(formatNumber(std::nan("")), "nan");
  EXPECT_EQ(formatNumber(1.0 / 3.0), "0.3333333333333333");
  EXPECT_EQ(std::stod(formatNumber(0.0372)), 0.0372);
}

TEST(Spec, SceneCellCount) {
  SceneSpec s;
  EXPECT_EQ(sceneCellCount(s), 200);
  s.scene_params.n_cells_a = 30;
  EXPECT_EQ(sceneCellCount(s), 130);
  s.scene = SceneKind::Spheroid;
  EXPECT_EQ(sceneCellCount(s), 100);
  s.scene = SceneKind::Doublet;
  EXPECT_EQ(sceneCellCount(s), 2);
}

TEST(Spec, EnumNamesAreTheChoices) {
  EXPECT_EQ(toString(SceneKind::Spheroid), "spheroid");
  EXPECT_EQ(toString(IntegratorKind::SemiImplicit), "semi-implicit");
  EXPECT_EQ(toString(PreconditionerKind::BlockJacobi), "block-jacobi");
  EXPECT_EQ(toString(PreconditionerKind::IncompleteCholesky), "incomplete-cholesky");
  EXPECT_EQ(toString(ContactQuadrature::Dunavant7), "dunavant7");
  EXPECT_EQ(toString(FidelityPreset::Reference), "reference");
}

// ---- fidelity presets and accuracy targets -----------------------------------------------------

TEST(SpecPresets, TheDefaultsAreTheStandardPreset) {
  NumericsParams n;
  n.dt_s = 7;
  n.triangles_per_cell = 80;
  applyPreset(n, FidelityPreset::Standard);
  EXPECT_EQ(n, NumericsParams{});
  EXPECT_EQ(SceneSpec{}.numerics.preset, FidelityPreset::Standard);
}

TEST(SpecPresets, CheapestFirstAndEachBuysAccuracy) {
  const auto& p = fidelityPresets();
  ASSERT_EQ(p.size(), 2u);
  EXPECT_EQ(p[0].preset, FidelityPreset::Standard);
  EXPECT_EQ(p[1].preset, FidelityPreset::Reference);
  for (std::size_t k = 1; k < p.size(); ++k) {
    EXPECT_LT(p[k].dt_s, p[k - 1].dt_s);
    EXPECT_LE(p[k].cg_tol, p[k - 1].cg_tol);
    EXPECT_LE(p[k].trajectory_error_deg, p[k - 1].trajectory_error_deg);
    EXPECT_LE(p[k].contact_angle_error_deg, p[k - 1].contact_angle_error_deg);
  }
  // The default is the figure studies' step; the reference the one it was judged against.
  EXPECT_EQ(p[0].integrator, IntegratorKind::ContactImplicitConsistent);
  EXPECT_EQ(p[0].contact_law, ContactLawKind::PrismsOverlap);
  EXPECT_EQ(p[1].contact_law, ContactLawKind::Supplement);
}

TEST(SpecPresets, ExplicitKeysWinInWhateverOrderTheyArrive) {
  SceneSpec a, b;
  ASSERT_EQ(setField(a, "numerics.preset", std::string("reference")), std::nullopt);
  ASSERT_EQ(setField(a, "numerics.dt_s", 0.25), std::nullopt);
  ASSERT_EQ(setField(b, "numerics.dt_s", 0.25), std::nullopt);
  ASSERT_EQ(setField(b, "numerics.preset", std::string("reference")), std::nullopt);
  for (const SceneSpec& s : {a, b}) {
    EXPECT_EQ(s.numerics.preset, FidelityPreset::Reference);
    EXPECT_EQ(s.numerics.dt_s, 0.25);
    EXPECT_EQ(s.numerics.cg_tol, 1e-3);
    EXPECT_EQ(s.numerics.contact_law, ContactLawKind::Supplement);
  }
  // draft is retired: refused, naming what to use.
  SceneSpec d;
  const auto error = setField(d, "numerics.preset", std::string("draft"));
  ASSERT_TRUE(error.has_value());
  EXPECT_EQ(error->field, "numerics.preset");
  EXPECT_NE(error->message.find("retired"), std::string::npos) << error->message;
  EXPECT_NE(error->message.find("standard"), std::string::npos) << error->message;
}

TEST(SpecPresets, AnAccuracyTargetPicksTheCheapestPresetThatMeetsIt) {
  auto pick = [](std::optional<double> angle, std::optional<double> trajectory) {
    SceneSpec s;
    if (angle) {
      EXPECT_EQ(setField(s, "accuracy.contact_angle_deg", *angle), std::nullopt);
    }
    if (trajectory) {
      EXPECT_EQ(setField(s, "accuracy.trajectory_deg", *trajectory), std::nullopt);
    }
    EXPECT_TRUE(validate(s).empty()) << joined(validate(s));
    return resolve(s);
  };
  const auto& standard = presetInfo(FidelityPreset::Standard);
  const auto& reference = presetInfo(FidelityPreset::Reference);
  EXPECT_EQ(pick(standard.contact_angle_error_deg + 1, {}).numerics.preset,
            FidelityPreset::Standard);
  EXPECT_EQ(pick({}, standard.trajectory_error_deg).numerics.preset, FidelityPreset::Standard);
  // The cheapest preset that states both errors within the targets.
  const FidelityPreset cheapest =
      standard.contact_angle_error_deg <= reference.contact_angle_error_deg &&
              standard.trajectory_error_deg <= reference.trajectory_error_deg
          ? FidelityPreset::Standard
          : FidelityPreset::Reference;
  const SceneSpec r = pick(reference.contact_angle_error_deg, reference.trajectory_error_deg);
  EXPECT_EQ(r.numerics.preset, cheapest);
  EXPECT_EQ(r.numerics.dt_s, presetInfo(cheapest).dt_s);
  EXPECT_EQ(resolve(r), r);  // idempotent
  // The choice is recorded: the resolved spec, read back key by key, validates and runs the same.
  SceneSpec back;
  for (const SpecField& f : specFields())
    if (const auto v = getField(r, f.key)) {
      ASSERT_EQ(setField(back, f.key, *v), std::nullopt);
    }
  EXPECT_TRUE(validate(back).empty()) << joined(validate(back));
  EXPECT_EQ(resolve(back), r);
}

TEST(SpecPresets, UnreachableTargetsAndConflictingNumericsAreErrorsNamingTheKey) {
  {
    SceneSpec s;
    ASSERT_EQ(setField(s, "accuracy.trajectory_deg", 0.01), std::nullopt);
    const auto errors = validate(s);
    ASSERT_TRUE(hasErrorFor(errors, "accuracy.trajectory_deg")) << joined(errors);
    EXPECT_NE(errors[0].message.find("allowed ["), std::string::npos) << errors[0].message;
  }
  {
    SceneSpec s;  // the target picks standard (Δt 1 s); Δt 0.1 s given as well
    ASSERT_EQ(setField(s, "accuracy.contact_angle_deg", 5.0), std::nullopt);
    ASSERT_EQ(setField(s, "numerics.dt_s", 0.1), std::nullopt);
    const auto errors = validate(s);
    ASSERT_TRUE(hasErrorFor(errors, "numerics.dt_s")) << joined(errors);
    EXPECT_NE(errors[0].message.find("'standard'"), std::string::npos) << errors[0].message;
  }
  {
    SceneSpec s;  // an explicit preset other than the target's choice
    ASSERT_EQ(setField(s, "accuracy.contact_angle_deg", 5.0), std::nullopt);
    ASSERT_EQ(setField(s, "numerics.preset", std::string("reference")), std::nullopt);
    EXPECT_TRUE(hasErrorFor(validate(s), "numerics.preset")) << joined(validate(s));
  }
  {
    SceneSpec s;  // explicit values that agree with the choice are fine
    ASSERT_EQ(setField(s, "accuracy.contact_angle_deg", 5.0), std::nullopt);
    ASSERT_EQ(setField(s, "numerics.dt_s", presetInfo(FidelityPreset::Standard).dt_s),
              std::nullopt);
    EXPECT_TRUE(validate(s).empty()) << joined(validate(s));
  }
}

TEST(SpecPresets, ThePresetNameAndTargetsAreNotInTheFingerprint) {
  // Only values run: a target that resolves to the standard preset's values runs as the
  // defaults do, and shares their checkpoints and prepared spheroids.
  SceneSpec a;
  ASSERT_EQ(setField(a, "accuracy.trajectory_deg", 10.0), std::nullopt);
  a = resolve(a);
  ASSERT_EQ(a.numerics.preset, FidelityPreset::Standard);
  EXPECT_EQ(specFingerprint(a), specFingerprint(resolve(SceneSpec{})));
  SceneSpec b;
  ASSERT_EQ(setField(b, "numerics.preset", std::string("reference")), std::nullopt);
  EXPECT_NE(specFingerprint(b), specFingerprint(SceneSpec{}));  // its values differ
}

// contact-implicit-consistent: a choice of its own, a spec of its own (checkpoints of the two
// contact-implicit steps do not mix), and contact-implicit's stability limits, saying so.
TEST(SpecIntegrator, ContactImplicitConsistentIsAKeyValueWithItsOwnFingerprintAndLimits) {
  SceneSpec s;
  s.scene = SceneKind::Doublet;
  s.numerics.contact_law = ContactLawKind::Supplement;  // the law its map was measured under
  ASSERT_FALSE(
      setField(s, "numerics.integrator", SpecValue(std::string("contact-implicit-consistent"))));
  EXPECT_EQ(s.numerics.integrator, IntegratorKind::ContactImplicitConsistent);
  SceneSpec pair = s;
  pair.numerics.integrator = IntegratorKind::ContactImplicit;
  EXPECT_NE(specFingerprint(resolve(s)), specFingerprint(resolve(pair)));
  // Its own stability map: 1 s ran at every k_AB and motility, 2 s oscillated everywhere; but
  // the motile fusion failed at 1 s, so with motility (p_a > 0 by default) the limit is 1 s.
  s.numerics.dt_s = 1;
  auto e = measuredUnstable(s);
  ASSERT_EQ(e.size(), 1u);
  EXPECT_EQ(e[0].field, "numerics.dt_s");
  EXPECT_NE(e[0].message.find("contact-implicit-consistent was measured to fail from 1 s with "
                              "motility"),
            std::string::npos)
      << e[0].message;
  EXPECT_NE(e[0].message.find("allowed (0, 1) s"), std::string::npos) << e[0].message;
  // The failing run was adaptive: the refusal must not suggest the adaptive step runs it.
  EXPECT_EQ(e[0].message.find("adaptive step would run it"), std::string::npos) << e[0].message;
  s.numerics.dt_s = 0.75;
  EXPECT_TRUE(measuredUnstable(s).empty());
  // The map's 2 s: runs at 1 s, refused from 2 s with the map's reason.
  auto expectTheMapsLimit = [](SceneSpec spec) {
    spec.numerics.dt_s = 1;
    EXPECT_TRUE(measuredUnstable(spec).empty());
    spec.numerics.dt_s = 2;
    const auto refused = measuredUnstable(spec);
    ASSERT_EQ(refused.size(), 1u);
    EXPECT_NE(refused[0].message.find("contact-implicit-consistent was measured to fail from 2 s"),
              std::string::npos)
        << refused[0].message;
  };
  // The motile failures were the law's false overlaps: with the overlap kept within the prisms
  // the map's 2 s applies; the prisms on the whole polygon alone were not measured at 1 s.
  SceneSpec bounded = s;
  bounded.numerics.contact_law = ContactLawKind::Supplement;
  bounded.numerics.dt_s = 1;
  EXPECT_FALSE(measuredUnstable(bounded).empty());
  bounded.numerics.contact_law = ContactLawKind::PrismsOverlap;
  expectTheMapsLimit(bounded);
  // Passive cells: the map's 2 s.
  SceneSpec passive = s;
  passive.cells.p_a = 0;
  expectTheMapsLimit(passive);
  // No map with 1280 triangles: contact-implicit's limit there, and the message says so.
  s.numerics.dt_s = 1;
  s.numerics.triangles_per_cell = 1280;
  e = measuredUnstable(s);
  ASSERT_EQ(e.size(), 1u);
  EXPECT_NE(e[0].message.find("no stability map with 1280"), std::string::npos) << e[0].message;
  s.numerics.dt_s = 0.5;
  EXPECT_TRUE(measuredUnstable(s).empty());
}

TEST(SpecPresets, MeasuredUnstableSettingsNameTheTimeStepAndItsLimit) {
  SceneSpec s;
  s.scene = SceneKind::Doublet;
  s.numerics.integrator = IntegratorKind::SemiImplicit;
  auto e = measuredUnstable(s);  // Δt 0.1 s
  ASSERT_EQ(e.size(), 1u);
  EXPECT_EQ(e[0].field, "numerics.dt_s");
  s.numerics.dt_s = 0.005;
  EXPECT_TRUE(measuredUnstable(s).empty());
  s.cells.k_contact *= 4;  // the explicit spring's limit scales like 1/k_AB
  EXPECT_EQ(measuredUnstable(s).size(), 1u);
  s.cells.k_contact /= 4;
  for (const PresetInfo& p : fidelityPresets()) {
    applyPreset(s.numerics, p.preset);
    EXPECT_TRUE(measuredUnstable(s).empty()) << toString(p.preset);  // motile doublet
  }
  s.numerics.integrator = IntegratorKind::ContactImplicit;
  s.numerics.contact_law = ContactLawKind::Supplement;
  s.numerics.dt_s = 1;
  EXPECT_EQ(measuredUnstable(s).size(), 1u);  // motile
  s.numerics.dt_s = 0.5;
  s.numerics.triangles_per_cell = 80;  // motile with 80 triangles: volume drift from 0.25 s
  e = measuredUnstable(s);
  ASSERT_EQ(e.size(), 1u);
  EXPECT_NE(e[0].message.find("allowed (0, 0.25) s"), std::string::npos) << e[0].message;
  EXPECT_NE(e[0].message.find("volume-drift"), std::string::npos) << e[0].message;
  s.numerics.dt_s = 0.25;
  EXPECT_EQ(measuredUnstable(s).size(), 1u);
  s.numerics.dt_s = 0.1;
  EXPECT_TRUE(measuredUnstable(s).empty());
  s.cells.p_a = 0;
  s.numerics.dt_s = 0.5;
  EXPECT_TRUE(measuredUnstable(s).empty());  // passive: 80 triangles ran at 0.5 s and 1 s
  s.cells.p_a = CellParams{}.p_a;
  // Passive cells too, since the map with smoothing on the surface (k_AB × 1 oscillated at 1 s,
  // a draw there: docs/study/README.md).
  s.numerics.dt_s = 1;
  s.cells.p_a = 0;
  s.numerics.triangles_per_cell = 320;
  e = measuredUnstable(s);
  ASSERT_EQ(e.size(), 1u);
  EXPECT_NE(e[0].message.find("the contact-implicit integrator was measured to fail from 1 s"),
            std::string::npos)
      << e[0].message;
  s.numerics.dt_s = 0.75;
  EXPECT_TRUE(measuredUnstable(s).empty());
  // ros2 has its own measured limit: 2 s ran everywhere in the map, 4 s drifted out of volume.
  s.cells.p_a = CellParams{}.p_a;
  s.numerics.integrator = IntegratorKind::Ros2;
  s.numerics.dt_s = 2;
  EXPECT_TRUE(measuredUnstable(s).empty());
  s.numerics.dt_s = 4;
  e = measuredUnstable(s);
  ASSERT_EQ(e.size(), 1u);
  EXPECT_NE(e[0].message.find("allowed (0, 4) s"), std::string::npos) << e[0].message;
  // With the adaptive step (the default) the refusal says what it would do instead.
  EXPECT_NE(e[0].message.find("adaptive step would run it"), std::string::npos) << e[0].message;
  s.numerics.adaptive = false;
  e = measuredUnstable(s);
  ASSERT_EQ(e.size(), 1u);
  EXPECT_EQ(e[0].message.find("adaptive"), std::string::npos) << e[0].message;
  s.numerics.adaptive = true;
  s.numerics.triangles_per_cell = 80;  // the 80-triangle motile limit holds for ros2 too
  s.numerics.dt_s = 0.5;
  e = measuredUnstable(s);
  ASSERT_EQ(e.size(), 1u);
  // A slow volume drift is not what rejecting steps cures: no adaptive hint there.
  EXPECT_EQ(e[0].message.find("adaptive"), std::string::npos) << e[0].message;
  s.scene = SceneKind::Cell;  // no contacts: none of these limits
  s.numerics.dt_s = 5;
  EXPECT_TRUE(measuredUnstable(s).empty());
}

// numerics.contact_law: the overlap within prisms by default (the figure studies' law); the
// supplement's law, the value of runs before the key, is left out of the fingerprint, so that
// their checkpoints and prepared spheroids stay valid; the others name it.
TEST(SpecFields, TheContactLawIsOneKeyLeftOutOfTheFingerprintAtTheSupplementsLaw) {
  SceneSpec s = resolve(SceneSpec{});
  EXPECT_EQ(s.numerics.contact_law, ContactLawKind::PrismsOverlap);
  EXPECT_NE(specFingerprint(s).find("numerics.contact_law=prisms-overlap;"), std::string::npos)
      << specFingerprint(s);
  ASSERT_EQ(setField(s, "numerics.contact_law", std::string("supplement")), std::nullopt);
  EXPECT_EQ(specFingerprint(s).find("contact_law"), std::string::npos) << specFingerprint(s);
  ASSERT_EQ(setField(s, "numerics.contact_law", std::string("prisms")), std::nullopt);
  EXPECT_NE(specFingerprint(s).find("numerics.contact_law=prisms;"), std::string::npos);
  const auto error = setField(s, "numerics.contact_law", std::string("facing"));
  ASSERT_TRUE(error.has_value());
  EXPECT_NE(error->message.find("supplement|prisms|prisms-overlap"), std::string::npos)
      << error->message;
}

// The contact law's switches of earlier versions read as the law they named, in either order;
// the facing bound and the saturated pressure read only at their neutral values (records of
// earlier jobs hold them there), anything else is refused naming what replaced them.
TEST(SpecFields, RetiredContactKeysReadAsTheLawTheyNamed) {
  auto law = [](std::vector<std::pair<std::string, SpecValue>> keys) {
    SceneSpec s = recordBase();
    for (const auto& [k, v] : keys) EXPECT_EQ(setField(s, k, v), std::nullopt) << k;
    return s.numerics.contact_law;
  };
  const std::string wp = "numerics.contact_within_prisms",
                    oo = "numerics.contact_prisms_overlap_only";
  EXPECT_EQ(law({{wp, false}, {oo, false}}), ContactLawKind::Supplement);
  EXPECT_EQ(law({{wp, true}, {oo, false}}), ContactLawKind::Prisms);
  EXPECT_EQ(law({{wp, true}, {oo, true}}), ContactLawKind::PrismsOverlap);
  EXPECT_EQ(law({{oo, true}, {wp, true}}), ContactLawKind::PrismsOverlap);
  SceneSpec s;
  EXPECT_EQ(setField(s, "numerics.contact_max_facing_deg", 90.0), std::nullopt);
  EXPECT_EQ(setField(s, "numerics.contact_max_overlap_um", std::int64_t{0}), std::nullopt);
  for (const auto& [key, bad] : std::vector<std::pair<std::string, double>>{
           {"numerics.contact_max_facing_deg", 60.0}, {"numerics.contact_max_overlap_um", 0.3}}) {
    const auto error = setField(s, key, bad);
    ASSERT_TRUE(error.has_value()) << key;
    EXPECT_EQ(error->field, key);
    EXPECT_NE(error->message.find("retired"), std::string::npos) << error->message;
    EXPECT_NE(error->message.find("numerics.contact_law"), std::string::npos) << error->message;
  }
}

// numerics.remesh_repair: rescue and rebuild by default (each changes only runs that need it);
// none, the remeshing before the key, is left out of the fingerprint. The two switches of
// earlier versions read as the policy they named.
TEST(SpecFields, TheRemeshRepairIsOnePolicyAndItsEarlierSwitchesReadAsIt) {
  SceneSpec s = resolve(SceneSpec{});
  EXPECT_EQ(s.numerics.remesh_repair, RemeshRepair::RescueRebuild);
  EXPECT_NE(specFingerprint(s).find("numerics.remesh_repair=rescue-rebuild;"), std::string::npos);
  ASSERT_EQ(setField(s, "numerics.remesh_repair", std::string("none")), std::nullopt);
  EXPECT_EQ(specFingerprint(s).find("remesh_repair"), std::string::npos);
  auto policy = [](std::vector<std::pair<std::string, bool>> keys) {
    SceneSpec r = recordBase();
    for (const auto& [k, v] : keys) EXPECT_EQ(setField(r, k, v), std::nullopt) << k;
    return r.numerics.remesh_repair;
  };
  const std::string rs = "numerics.remesh_rescue", rb = "numerics.remesh_rebuild";
  EXPECT_EQ(policy({}), RemeshRepair::None);
  EXPECT_EQ(policy({{rs, false}, {rb, false}}), RemeshRepair::None);
  EXPECT_EQ(policy({{rs, true}, {rb, false}}), RemeshRepair::Rescue);
  EXPECT_EQ(policy({{rs, true}, {rb, true}}), RemeshRepair::RescueRebuild);
  const auto error = setField(s, rs, 3.0);
  ASSERT_TRUE(error.has_value());
  EXPECT_NE(error->message.find("true or false"), std::string::npos) << error->message;
}

// Each key's history is one row of the table: the fingerprint leaves out exactly the keys at
// their `before` values and the labels, and the base of records holds every `before` value.
TEST(SpecFields, TheFingerprintAndTheRecordBaseComeFromTheTable) {
  const SceneSpec base = resolve(recordBase());
  const std::string fp = specFingerprint(base);
  for (const SpecField& f : specFields()) {
    const bool in = fp.find(f.key + "=") != std::string::npos;
    if (f.label) {
      EXPECT_FALSE(in) << f.key;
    } else if (f.before) {
      EXPECT_EQ(getField(base, f.key), f.before) << f.key;
      EXPECT_FALSE(in) << f.key;
    } else if (f.since_unset) {
      EXPECT_FALSE(getField(base, f.key)) << f.key;
      EXPECT_FALSE(in) << f.key;
    } else if (f.key != "numerics.dt_min_s") {
      EXPECT_TRUE(in) << f.key;  // set or not, every other key is in it
    }
  }
  // The figure studies' committed base point reads back to today's defaults but for what the
  // record names: its record holds the contact law's two switches.
  SceneSpec old = recordBase();
  ASSERT_EQ(setField(old, "numerics.contact_within_prisms", true), std::nullopt);
  ASSERT_EQ(setField(old, "numerics.contact_prisms_overlap_only", true), std::nullopt);
  EXPECT_EQ(old.numerics.contact_law, SceneSpec{}.numerics.contact_law);
}

// numerics.remesh_keep_out_um likewise for cells pressed against a neighbour: 0 (off) by
// default and out of the fingerprint then, in it when set; a depth below 0 is refused.
TEST(SpecFields, TheRemeshersKeepOutIsOffByDefaultAndInTheFingerprintWhenSet) {
  SceneSpec s = resolve(SceneSpec{});
  EXPECT_EQ(s.numerics.remesh_keep_out_um, 0);
  EXPECT_EQ(specFingerprint(s).find("keep_out"), std::string::npos);
  ASSERT_EQ(setField(s, "numerics.remesh_keep_out_um", 0.75), std::nullopt);
  EXPECT_TRUE(validate(s).empty()) << joined(validate(s));
  EXPECT_NE(specFingerprint(s).find("numerics.remesh_keep_out_um=0.75;"), std::string::npos)
      << specFingerprint(s);
  const auto error = setField(s, "numerics.remesh_keep_out_um", -0.5);
  ASSERT_TRUE(error.has_value());
  EXPECT_NE(error->str().find("numerics.remesh_keep_out_um"), std::string::npos) << error->str();
  EXPECT_NE(error->str().find("[0, 100]"), std::string::npos) << error->str();
}

}  // namespace
}  // namespace activefoam

namespace activefoam {
namespace {

// numerics.remesh_on_surface came in defaulting to true (the earlier smoothing moved vertices
// into neighbouring cells): the default's fingerprint names it, so that checkpoints and prepared
// spheroids of the earlier remeshing are not taken for today's; false, the earlier remeshing, is
// left out, so that theirs stay valid for a spec that asks for it.
TEST(SpecFields, RemeshingOnTheSurfaceIsTheDefaultAndTheEarlierRemeshingKeepsItsFingerprint) {
  SceneSpec s = resolve(SceneSpec{});
  EXPECT_TRUE(s.numerics.remesh_on_surface);
  EXPECT_NE(specFingerprint(s).find("numerics.remesh_on_surface=1;"), std::string::npos)
      << specFingerprint(s);
  ASSERT_EQ(setField(s, "numerics.remesh_on_surface", false), std::nullopt);
  EXPECT_TRUE(validate(s).empty()) << joined(validate(s));
  EXPECT_EQ(specFingerprint(s).find("remesh_on_surface"), std::string::npos);
  const auto error = setField(s, "numerics.remesh_on_surface", 1.5);
  ASSERT_TRUE(error.has_value());
  EXPECT_NE(error->message.find("true or false"), std::string::npos) << error->message;
}

// [prepare]: only keys the preparation takes from the run (Prep::Kept), each in its own range;
// every other key is refused saying why, the spec unchanged.
TEST(SpecPrepare, TheTableTakesOnlyKeptKeysWithinTheirRanges) {
  SceneSpec s;
  ASSERT_EQ(setField(s, "prepare.cells.l_eta_reduced", std::int64_t{1}), std::nullopt);
  EXPECT_EQ(getField(s, "prepare.cells.l_eta_reduced"), SpecValue(1.0));  // stored as the key's
  EXPECT_EQ(getField(s, "prepare.cells.gamma"), std::nullopt);
  const SceneSpec before = s;
  auto refused = [&](const char* key, const SpecValue& v, std::vector<std::string> words) {
    const auto e = setField(s, key, v);
    ASSERT_TRUE(e.has_value()) << key;
    EXPECT_EQ(e->field, key);
    for (const std::string& w : words)
      EXPECT_NE(e->message.find(w), std::string::npos) << key << ": " << e->message;
    EXPECT_EQ(s, before) << key;
  };
  refused("prepare.cells.gama", 1.0,
          {"unknown key 'cells.gama' in [prepare]", "prepare.cells.gamma"});
  refused("prepare.numerics.cg_tol", 1e-4,
          {"runs at 0.001 whatever the run's", "share aggregates"});
  refused("prepare.observe.dissipation", true, {"runs at false"});
  refused("prepare.seed", std::int64_t{3}, {"sets it itself"});
  refused("prepare.numerics.dt_s", 0.1, {"sets it itself", "scene.prep_dt_s"});
  refused("prepare.numerics.triangles_per_cell", std::int64_t{1280},
          {"the run's cells are the prepared ones", "give it in [numerics]"});
  refused("prepare.cells.radius_mean_um", 9.0, {"radii and meshes", "give it in [cells]"});
  refused("prepare.scene.prep_dt_s", 0.25, {"only the preparation reads it; give it in [scene]"});
  refused("prepare.cells.alpha", 1.5, {"1.5 is outside the allowed range [0, 1)"});
  refused("prepare.cells.alpha", std::string("x"), {"expected a number"});
  // The key table decides: every Kept key is taken at its default, every other refused.
  for (const SpecField& f : specFields()) {
    SceneSpec t;
    const auto v = getField(resolve(t), f.key);
    if (!v) continue;
    const auto e = setField(t, "prepare." + f.key, *v);
    EXPECT_EQ(e.has_value(), f.prep != SpecField::Prep::Kept) << f.key;
  }
  ASSERT_EQ(clearField(s, "prepare.cells.l_eta_reduced"), std::nullopt);
  EXPECT_TRUE(s.prepare.empty());
}

// Where nothing is prepared it is refused; what its values derive must be in range too.
TEST(SpecPrepare, ValidateRefusesItWithoutAPreparationAndChecksWhatItDerives) {
  SceneSpec d;
  d.scene = SceneKind::Doublet;
  ASSERT_EQ(setField(d, "prepare.cells.alpha", 0.5), std::nullopt);
  auto e = validate(d);
  ASSERT_EQ(e.size(), 1u) << joined(e);
  EXPECT_EQ(e[0].field, "prepare.cells.alpha");
  EXPECT_NE(e[0].message.find("only the fusion scene prepares spheroids"), std::string::npos)
      << e[0].message;
  d.scene = SceneKind::Fusion;
  EXPECT_TRUE(validate(d).empty()) << joined(validate(d));

  SceneSpec f;  // ξ = η/(0.001 r)² = 6.3e4 kPa·s/µm, beyond cells.xi's 1e4
  ASSERT_EQ(setField(f, "prepare.cells.l_eta_reduced", 1e-3), std::nullopt);
  e = validate(f);
  ASSERT_EQ(e.size(), 1u) << joined(e);
  EXPECT_EQ(e[0].field, "prepare.cells.l_eta_reduced");
  EXPECT_NE(e[0].message.find("gives cells.xi"), std::string::npos) << e[0].message;

  SceneSpec filled;  // a table filled by hand with a key it cannot hold
  filled.prepare["numerics.cg_tol"] = 1e-4;
  EXPECT_TRUE(hasErrorFor(validate(filled), "prepare.numerics.cg_tol"));

  // Weak adhesion asks a long preparation of the preparation's α, not the run's.
  SceneSpec weak;
  ASSERT_EQ(setField(weak, "prepare.cells.alpha", 0.9), std::nullopt);
  const auto w = silentlyWrong(weak);
  ASSERT_EQ(w.size(), 1u);
  EXPECT_NE(w[0].message.find("prepare.cells.alpha = 0.9"), std::string::npos) << w[0].message;
  weak.cells.alpha = 0.9;
  ASSERT_EQ(setField(weak, "prepare.cells.alpha", 0.5), std::nullopt);
  EXPECT_TRUE(silentlyWrong(weak).empty());
}

// resolve() applies the preparation's values as the run's would be applied: its own L_η/r gives
// it its own ξ, ξ⊥ and ξ∥, its own γ its τ_K and τ_r; the run keeps its own; what is left is what
// differs, so that a [prepare] at the run's values is no [prepare] at all.
TEST(SpecPrepare, ResolveDerivesThePreparationsValuesAndTheRunKeepsItsOwn) {
  SceneSpec s;
  s.cells.l_eta_reduced = 2;
  ASSERT_EQ(setField(s, "prepare.cells.l_eta_reduced", 0.5), std::nullopt);
  ASSERT_EQ(setField(s, "prepare.cells.gamma", 1.0), std::nullopt);
  const SceneSpec r = resolve(s);
  const double r_um = s.cells.radius_mean_um;
  auto xi = [&](double l, double eta) { return eta / (l * r_um * l * r_um); };
  EXPECT_DOUBLE_EQ(r.cells.xi, xi(2, s.cells.eta));
  EXPECT_EQ(*r.cells.xi_normal, r.cells.xi);
  EXPECT_EQ(*r.cells.tau_k_s, defaultTauKS(s.cells));
  const SceneSpec p = withPrepareValues(r);
  EXPECT_TRUE(p.prepare.empty());
  EXPECT_DOUBLE_EQ(p.cells.xi, xi(0.5, s.cells.eta));
  EXPECT_EQ(*p.cells.xi_normal, p.cells.xi);
  EXPECT_EQ(*p.cells.xi_tangential, p.cells.xi);
  EXPECT_EQ(p.cells.gamma, 1.0);
  CellParams stiff = s.cells;
  stiff.gamma = 1;
  EXPECT_EQ(*p.cells.tau_k_s, defaultTauKS(stiff));
  EXPECT_EQ(*p.numerics.remesh_every_s, defaultRemeshEveryS(stiff));
  EXPECT_FALSE(r.prepare.count("cells.l_eta_reduced"));  // resolved into what it gives
  EXPECT_EQ(resolve(r), r);
  // The run's values again: no table, the fingerprint of a spec without one.
  SceneSpec same = s;
  same.prepare.clear();
  const SceneSpec plain = resolve(same);
  ASSERT_EQ(setField(same, "prepare.cells.l_eta_reduced", 2.0), std::nullopt);
  EXPECT_TRUE(resolve(same).prepare.empty());
  EXPECT_EQ(specFingerprint(resolve(same)), specFingerprint(plain));
  // Without a table the fingerprint holds no trace of one; with one it adds its values after
  // every key's, which keep theirs.
  EXPECT_EQ(specFingerprint(plain).find("prepare"), std::string::npos);
  SceneSpec run = s;
  run.prepare.clear();
  const std::string without = specFingerprint(resolve(run));
  const std::string with = specFingerprint(r);
  EXPECT_EQ(with.substr(0, without.size()), without);
  EXPECT_NE(with.find("prepare.cells.xi="), std::string::npos) << with;
}

}  // namespace
}  // namespace activefoam
