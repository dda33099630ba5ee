// Spec parsing: TOML, JSON, --set; every error names its key; JSON round trip.
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "activefoam/spec.h"
#include "activefoam/spec_io.h"

namespace activefoam {
namespace {

// Parse, then validate: every error a user would see for this document.
std::vector<SpecError> problems(std::string_view text, SpecFormat format = SpecFormat::Auto) {
  SpecParseResult r = parseSpecText(text, format);
  if (!r.ok()) return r.errors;
  return validate(*r.spec);
}

std::string joined(const std::vector<SpecError>& errors) {
  std::string s;
  for (const SpecError& e : errors) s += "  " + e.str() + "\n";
  return s;
}

struct InvalidCase {
  const char* name;
  const char* text;
  const char* field;  // the key the error must name
  const char* words;  // a fragment the message must contain ("" for any)
};

// clang-format off
const InvalidCase kInvalid[] = {
  {"negative dt", "scene = \"cell\"\n[numerics]\ndt_s = -1\n", "numerics.dt_s",
   "-1 is outside the allowed range (0, 10] s"},
  {"zero gamma", "scene = \"cell\"\n[cells]\ngamma = 0\n", "cells.gamma",
   "0 is outside the allowed range (0, 100] nN/µm"},
  {"nan gamma (TOML)", "scene = \"cell\"\n[cells]\ngamma = nan\n", "cells.gamma", "finite"},
  {"inf duration (TOML)", "scene = \"cell\"\nduration_s = inf\n", "duration_s", "finite"},
  {"-inf eta (TOML)", "scene = \"cell\"\ncells.eta = -inf\n", "cells.eta", "finite"},
  {"missing scene", "seed = 3\n", "scene", "missing"},
  {"missing scene in [scene]", "[scene]\nn_cells = 10\n", "scene", "missing"},
  {"unknown scene", "scene = \"triplet\"\n", "scene", "one of cell|doublet|spheroid|fusion"},
  {"unknown scene kind in table", "[scene]\nkind = \"blob\"\n", "scene.kind", "not one of"},
  {"scene as number", "scene = 3\n", "scene", "expected one of"},
  {"misspelt key", "scene = \"cell\"\n[cells]\ngama = 0.5\n", "cells.gama",
   "unknown key 'cells.gama'"},
  {"unknown top-level key", "scene = \"cell\"\ndurations = 10\n", "durations", "unknown key"},
  {"unknown table", "scene = \"cell\"\n[mesh]\nlevels = 2\n", "mesh", "unknown table"},
  {"unknown sub-table", "scene = \"cell\"\n[cells.extra]\nx = 1\n", "cells.extra", "unknown"},
  {"key where a table belongs", "scene = \"cell\"\ncells = 5\n", "cells", "expected a table"},
  {"table where a key belongs", "scene = \"cell\"\n[seed]\nx = 1\n", "seed", "got a table"},
  {"string for a number", "scene = \"cell\"\nseed = \"one\"\n", "seed", "expected an integer"},
  {"bool for a number", "scene = \"cell\"\n[cells]\nxi = true\n", "cells.xi", "expected a number"},
  {"array for a number", "scene = \"cell\"\n[cells]\nalpha = [0.4]\n", "cells.alpha", "array"},
  {"absurd cell count", "[scene]\nkind = \"spheroid\"\nn_cells = 1e9\n", "scene.n_cells",
   "outside the allowed range [1, 2000]"},
  {"absurd duration", "scene = \"cell\"\nduration_s = 1e12\n", "duration_s",
   "outside the allowed range"},
  {"triangles not an icosphere", "scene = \"cell\"\n[numerics]\ntriangles_per_cell = 100\n",
   "numerics.triangles_per_cell", "one of 80|320|1280"},
  {"alpha of 1", "scene = \"doublet\"\n[cells]\nalpha = 1\n", "cells.alpha", "[0, 1)"},
  {"negative p_a", "scene = \"cell\"\n[cells]\np_a = -0.1\n", "cells.p_a", "outside"},
  {"negative seed", "scene = \"cell\"\nseed = -1\n", "seed", "outside"},
  {"unknown integrator", "scene = \"cell\"\n[numerics]\nintegrator = \"explicit\"\n",
   "numerics.integrator", "semi-implicit|contact-implicit"},
  {"zero cg_tol", "scene = \"cell\"\n[numerics]\ncg_tol = 0\n", "numerics.cg_tol", "(0, 0.5]"},
  {"radius spread below 1", "scene = \"cell\"\n[cells]\nradius_gamma_k = 0.5\n",
   "cells.radius_gamma_k", "shape k"},
  {"sample interval beyond duration", "scene = \"cell\"\nduration_s = 10\nsample_every_s = 60\n",
   "sample_every_s", "duration_s"},
  {"too many steps", "scene = \"cell\"\n[numerics]\ndt_s = 1e-6\n", "numerics.dt_s",
   "steps exceeds"},
  {"remesh thresholds inverted",
   "scene = \"cell\"\n[numerics]\nremesh_min_area_factor = 0.5\nremesh_max_area_factor = 0.9\n",
   "numerics.remesh_max_area_factor", "outside"},
  {"reduced p_a out of range",
   "scene = \"cell\"\n[cells]\npa_reduced = 50\ngamma = 100\nradius_mean_um = 1\n",
   "cells.pa_reduced", "cells.p_a"},
  {"malformed TOML", "scene = \"cell\"\n[cells\ngamma = 1\n", "<toml>", "line 2"},
  {"malformed JSON", "{\n  \"scene\": \"cell\",\n  \"seed\": ,\n}\n", "<json>", "line 3"},
  {"JSON negative dt", R"({"scene": "cell", "numerics": {"dt_s": -1}})", "numerics.dt_s",
   "(0, 10] s"},
  {"JSON bool seed", R"({"scene": "cell", "seed": true})", "seed", "expected an integer"},
  {"JSON null for a required key", R"({"scene": "cell", "cells": {"gamma": null}})",
   "cells.gamma", "null"},
  {"JSON unknown table", R"({"scene": "cell", "solver": {"tol": 1}})", "solver",
   "unknown table"},
  {"JSON huge duration", R"({"scene": {"kind": "cell"}, "duration_s": 1e12})", "duration_s",
   "outside"},
  {"JSON number beyond double", R"({"scene": "cell", "cells": {"xi": 2, "gamma": 1e400}})",
   "cells.gamma", "number overflow parsing '1e400'"},
  {"JSON number beyond double, top level", "{\"scene\": \"cell\",\n \"duration_s\": -2E+999}",
   "duration_s", "outside the range"},
};
// clang-format on

TEST(SpecIo, InvalidSpecsNameTheField) {
  int checked = 0;
  for (const InvalidCase& c : kInvalid) {
    const std::vector<SpecError> errors = problems(c.text);
    bool named = false;
    for (const SpecError& e : errors)
      if (e.field == c.field && e.message.find(c.words) != std::string::npos) named = true;
    EXPECT_TRUE(named) << c.name << ": expected an error for '" << c.field << "' containing '"
                       << c.words << "', got:\n"
                       << joined(errors);
    for (const SpecError& e : errors)
      EXPECT_EQ(e.str().find('\n'), std::string::npos) << c.name << ": not one line";
    ++checked;
  }
  EXPECT_GE(checked, 20);
}

TEST(SpecIo, MoreInvalidSpecs) {
  // Fractional value for an integer key.
  auto errors = problems("[scene]\nkind = \"spheroid\"\nn_cells = 2.5\n");
  ASSERT_EQ(errors.size(), 1u) << joined(errors);
  EXPECT_EQ(errors[0].field, "scene.n_cells");
  EXPECT_NE(errors[0].message.find("not an integer"), std::string::npos);
  // Too many triangles in total: 2 × 2000 cells × 1280.
  errors = problems(
      "[scene]\nkind = \"fusion\"\nn_cells = 2000\n[numerics]\ntriangles_per_cell = 1280\n");
  ASSERT_EQ(errors.size(), 1u) << joined(errors);
  EXPECT_EQ(errors[0].field, "scene.n_cells");
  EXPECT_NE(errors[0].message.find("exceeds the limit"), std::string::npos);
}

TEST(SpecIo, EveryErrorIsReported) {
  const auto r = parseSpecText(
      "scene = \"cell\"\nseed = -4\n[cells]\ngamma = 0\ngama = 1\n[numerics]\ndt_s = 100\n");
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.errors.size(), 4u) << joined(r.errors);
  EXPECT_FALSE(r.spec);
}

TEST(SpecIo, MalformedInputGivesLineAndColumn) {
  auto r = parseSpecText("scene = \"cell\"\nseed = = 3\n", SpecFormat::Toml, SceneSpec{},
                         {true, "my.toml"});
  ASSERT_EQ(r.errors.size(), 1u);
  EXPECT_EQ(r.errors[0].field, "my.toml");
  EXPECT_NE(r.errors[0].message.find("line 2, column"), std::string::npos) << r.errors[0].str();
  r = parseSpecText("{\"scene\": \"cell\",\n \"seed\": 1,,}", SpecFormat::Json);
  ASSERT_EQ(r.errors.size(), 1u);
  EXPECT_NE(r.errors[0].message.find("line 2, column"), std::string::npos) << r.errors[0].str();
  EXPECT_EQ(r.errors[0].str().find('\n'), std::string::npos);
}

TEST(SpecIo, SceneAloneIsValid) {
  for (const char* text : {"scene = \"fusion\"\n", "{\"scene\": \"fusion\"}",
                           "[scene]\nkind = \"fusion\"\n", "{\"scene\": {\"kind\": \"fusion\"}}"}) {
    const auto r = parseSpecText(text);
    ASSERT_TRUE(r.ok()) << text << joined(r.errors);
    EXPECT_TRUE(r.scene_given);
    EXPECT_EQ(*r.spec, SceneSpec{}) << text;
    EXPECT_TRUE(validate(*r.spec).empty());
  }
}

TEST(SpecIo, SceneMayComeLater) {
  const auto r = parseSpecText("seed = 4\n", SpecFormat::Toml, SceneSpec{}, {false, ""});
  ASSERT_TRUE(r.ok()) << joined(r.errors);
  EXPECT_FALSE(r.scene_given);
  EXPECT_EQ(r.spec->seed, 4u);
}

constexpr const char* kToml = R"(# a doublet study
seed = 42
duration_s = 3600
sample_every_s = 30
snapshot_every_s = 0

[cells]
radius_mean_um = 9
radius_gamma_k = 0
gamma = 0.6
tau_gamma_s = 12.5
alpha = 0.5
pa_reduced = 0.25
tau_p_s = 300
l_eta_reduced = 0.4
xi_normal = 0.3
k_contact = 700

[numerics]
dt_s = 0.05
integrator = "semi-implicit"
cg_tol = 1e-4
preconditioner = "block-jacobi"
triangles_per_cell = 1280
remesh_every_s = 0
contact_quadrature = "dunavant7"

[scene]
kind = "doublet"  # scene = "doublet" at the top cannot coexist with this table
gap_um = 0.02
)";

constexpr const char* kJson = R"({
  "scene": "doublet", "seed": 42, "duration_s": 3600, "sample_every_s": 30,
  "snapshot_every_s": 0,
  "cells": {"radius_mean_um": 9, "radius_gamma_k": 0, "gamma": 0.6, "tau_gamma_s": 12.5,
            "alpha": 0.5, "pa_reduced": 0.25, "tau_p_s": 300, "l_eta_reduced": 0.4,
            "xi_normal": 0.3, "k_contact": 700},
  "numerics": {"dt_s": 0.05, "integrator": "semi-implicit", "cg_tol": 1e-4,
               "preconditioner": "block-jacobi", "triangles_per_cell": 1280,
               "remesh_every_s": 0, "contact_quadrature": "dunavant7"},
  "scene": {"kind": "doublet", "gap_um": 0.02}
})";

TEST(SpecIo, TomlAndJsonParseIdentically) {
  const auto t = parseSpecText(kToml);
  ASSERT_TRUE(t.ok()) << joined(t.errors);
  const auto j = parseSpecText(kJson);
  ASSERT_TRUE(j.ok()) << joined(j.errors);
  EXPECT_EQ(*t.spec, *j.spec);
  EXPECT_EQ(t.spec->scene, SceneKind::Doublet);
  EXPECT_EQ(t.spec->seed, 42u);
  EXPECT_EQ(t.spec->numerics.triangles_per_cell, 1280);
  EXPECT_EQ(t.spec->numerics.preconditioner, PreconditionerKind::BlockJacobi);
  EXPECT_EQ(*t.spec->cells.tau_gamma_s, 12.5);
  EXPECT_EQ(t.spec->scene_params.gap_um, 0.02);
  EXPECT_TRUE(validate(*t.spec).empty()) << joined(validate(*t.spec));
}

TEST(SpecIo, JsonRoundTripIsExact) {
  const auto t = parseSpecText(kToml);
  ASSERT_TRUE(t.ok());
  for (const SceneSpec& s : {SceneSpec{}, resolve(SceneSpec{}), *t.spec, resolve(*t.spec)}) {
    const nlohmann::json j = specToJson(s);
    // Every key is present (unset optional ones as null).
    for (const SpecField& f : specFields()) {
      if (f.key == "scene") {
        EXPECT_TRUE(j["scene"].contains("kind"));
        continue;
      }
      const auto dot = f.key.find('.');
      const bool present = dot == std::string::npos
                               ? j.contains(f.key)
                               : j[f.key.substr(0, dot)].contains(f.key.substr(dot + 1));
      EXPECT_TRUE(present) << f.key;
    }
    // Through text, as spec.json is written and read.
    const auto back = parseSpecText(j.dump(2));
    ASSERT_TRUE(back.ok()) << joined(back.errors);
    EXPECT_EQ(*back.spec, s);
    EXPECT_EQ(specToJson(*back.spec), j);
  }
  // A resolved spec states absolute values: everything set but the reduced forms.
  const nlohmann::json r = specToJson(resolve(*t.spec));
  EXPECT_TRUE(r["cells"]["tau_gamma_s"].is_null());
  EXPECT_TRUE(r["cells"]["pa_reduced"].is_null());
  EXPECT_TRUE(r["cells"]["l_eta_reduced"].is_null());
  EXPECT_DOUBLE_EQ(r["cells"]["eta"].get<double>(), 12.5 * 0.6);
  EXPECT_FALSE(r["cells"]["tau_k_s"].is_null());
  EXPECT_EQ(r["numerics"]["remesh_every_s"].get<double>(), 0.0);
  EXPECT_EQ(r["scene"]["kind"], "doublet");
}

TEST(SpecIo, SetOverrides) {
  SceneSpec s;
  EXPECT_EQ(applySetting(s, "numerics.dt_s=0.05"), std::nullopt);
  EXPECT_EQ(s.numerics.dt_s, 0.05);
  EXPECT_EQ(applySetting(s, " scene = doublet "), std::nullopt);
  EXPECT_EQ(s.scene, SceneKind::Doublet);
  EXPECT_EQ(applySetting(s, "scene.kind=\"spheroid\""), std::nullopt);
  EXPECT_EQ(s.scene, SceneKind::Spheroid);
  EXPECT_EQ(applySetting(s, "scene.n_cells=50"), std::nullopt);
  EXPECT_EQ(s.scene_params.n_cells, 50);
  EXPECT_EQ(applySetting(s, "seed=1e3"), std::nullopt);  // integral double
  EXPECT_EQ(s.seed, 1000u);
  EXPECT_EQ(applySetting(s, "cells.gamma=1"), std::nullopt);  // integer for a Real key
  EXPECT_EQ(s.cells.gamma, 1.0);
  EXPECT_EQ(applySetting(s, "cells.pa_reduced=+0.33"), std::nullopt);
  EXPECT_EQ(*s.cells.pa_reduced, 0.33);
  EXPECT_EQ(applySetting(s, "numerics.integrator=semi-implicit"), std::nullopt);
  EXPECT_EQ(s.numerics.integrator, IntegratorKind::SemiImplicit);

  const SceneSpec before = s;
  auto e = applySetting(s, "numerics.dt_s=-1");
  ASSERT_TRUE(e);
  EXPECT_EQ(e->str(), "numerics.dt_s: -1 is outside the allowed range (0, 10] s");
  e = applySetting(s, "cells.gamma=nan");
  ASSERT_TRUE(e);
  EXPECT_EQ(e->field, "cells.gamma");
  e = applySetting(s, "cells.gamma=abc");
  ASSERT_TRUE(e);
  EXPECT_EQ(e->str(), "cells.gamma: expected a number, got 'abc'");
  e = applySetting(s, "cells.gama=1");
  ASSERT_TRUE(e);
  EXPECT_EQ(e->field, "cells.gama");
  e = applySetting(s, "numerics.triangles_per_cell=100");
  ASSERT_TRUE(e);
  EXPECT_EQ(e->field, "numerics.triangles_per_cell");
  e = applySetting(s, "dt_s");
  ASSERT_TRUE(e);
  EXPECT_NE(e->message.find("key=value"), std::string::npos);
  e = applySetting(s, "=3");
  ASSERT_TRUE(e);
  EXPECT_EQ(s, before);

  const auto all = applySettings(SceneSpec{}, {"scene=cell", "duration_s=-1", "seed=x"});
  EXPECT_FALSE(all.ok());
  EXPECT_EQ(all.errors.size(), 2u) << joined(all.errors);
  EXPECT_TRUE(all.scene_given);
  const auto fine = applySettings(SceneSpec{}, {"duration_s=100", "sample_every_s=10"});
  ASSERT_TRUE(fine.ok());
  EXPECT_FALSE(fine.scene_given);
  EXPECT_EQ(fine.spec->duration_s, 100);
}

TEST(SpecIo, NullUnsetsOptionalKeys) {
  SceneSpec base;
  base.cells.tau_k_s = 3;
  const auto r =
      parseSpecText(R"({"scene": "cell", "cells": {"tau_k_s": null}})", SpecFormat::Json, base);
  ASSERT_TRUE(r.ok()) << joined(r.errors);
  EXPECT_FALSE(r.spec->cells.tau_k_s);
}

TEST(SpecIo, JsonMustBeAnObject) {
  const auto r = parseSpecText("[1, 2]", SpecFormat::Json);
  ASSERT_EQ(r.errors.size(), 1u);
  EXPECT_EQ(r.errors[0].field, "<json>");
  EXPECT_NE(r.errors[0].message.find("object"), std::string::npos);
}

TEST(SpecIo, TheDesignExampleWithSceneKeyAndSceneTable) {
  // A spec may write both `scene = "fusion"` and a [scene] table, which plain TOML forbids.
  const auto r = parseSpecText(
      "scene = \"fusion\"  # the kind\nseed = 3\n[cells]\nalpha = 0.5\n[scene]  # params\n"
      "n_cells = 40\nn_cells_b = 30\n[numerics]\ndt_s = 0.05\n");
  ASSERT_TRUE(r.ok()) << joined(r.errors);
  EXPECT_EQ(r.spec->scene, SceneKind::Fusion);
  EXPECT_EQ(r.spec->scene_params.n_cells, 40);
  EXPECT_EQ(r.spec->scene_params.n_cells_b, 30);
  EXPECT_EQ(r.spec->cells.alpha, 0.5);
  EXPECT_EQ(r.spec->numerics.dt_s, 0.05);
  // Errors inside that table still name scene.<key>, with the document's line numbers.
  auto bad = parseSpecText("scene = \"cell\"\n[scene]\naxes_ratio = 50\n");
  ASSERT_EQ(bad.errors.size(), 1u);
  EXPECT_EQ(bad.errors[0].field, "scene.axes_ratio");
  bad = parseSpecText("scene = \"cell\"\n[scene]\naxes_ratio = \n");
  ASSERT_EQ(bad.errors.size(), 1u);
  EXPECT_NE(bad.errors[0].message.find("line 3"), std::string::npos) << bad.errors[0].str();
  // The kind given both ways is an error.
  bad = parseSpecText("scene = \"cell\"\n[scene]\nkind = \"doublet\"\n");
  ASSERT_EQ(bad.errors.size(), 1u);
  EXPECT_NE(bad.errors[0].message.find("twice"), std::string::npos) << bad.errors[0].str();
}

TEST(SpecIo, FormatIsSniffed) {
  EXPECT_EQ(sniffSpecFormat("  \n{\"a\": 1}"), SpecFormat::Json);
  EXPECT_EQ(sniffSpecFormat("scene = \"cell\""), SpecFormat::Toml);
  EXPECT_EQ(sniffSpecFormat(""), SpecFormat::Toml);
}

TEST(SpecIo, FileErrorsNameTheFile) {
  const auto r = parseSpecFile("/nonexistent/dir/spec.toml");
  ASSERT_EQ(r.errors.size(), 1u);
  EXPECT_EQ(r.errors[0].field, "/nonexistent/dir/spec.toml");
  EXPECT_NE(r.errors[0].message.find("cannot read"), std::string::npos);
}

TEST(SpecIo, ValidateAndResolve) {
  SceneSpec s;
  s.cells.pa_reduced = 0.33;
  auto r = validateAndResolve(s);
  ASSERT_TRUE(r.ok());
  EXPECT_DOUBLE_EQ(r.spec->cells.p_a, 0.33 * 2 * 0.5 / 8.88);
  s.numerics.dt_s = 0;
  r = validateAndResolve(s);
  EXPECT_FALSE(r.ok());
  EXPECT_FALSE(r.spec);
  EXPECT_EQ(r.errors[0].field, "numerics.dt_s");
}

}  // namespace

// The adversarial corpus: a JSON key given twice kept the last value without a word
// (`"duration_s": 1, "duration_s": 2` ran for 2 s; a second "cells" object replaced the first).
// Each repeat is refused naming its dotted key; TOML's form `scene = NAME` beside a scene table
// stays allowed in JSON, unless the two disagree.
TEST(SpecIo, JsonKeysGivenTwiceAreRefusedNamingTheKey) {
  for (const auto& [text, key] : std::vector<std::pair<std::string, std::string>>{
           {R"({"scene": "cell", "duration_s": 1, "duration_s": 2})", "duration_s"},
           {R"({"scene": "cell", "cells": {"gamma": 0.5}, "cells": {"eta": 5}})", "cells"},
           {R"({"scene": "cell", "cells": {"gamma": 0.5, "gamma": 0.7}})", "cells.gamma"},
           {R"({"scene": "cell", "scene": "fusion"})", "scene"},
           {R"({"scene": "fusion", "scene": {"kind": "doublet"}})", "scene"}}) {
    const auto r = parseSpecText(text, SpecFormat::Json);
    ASSERT_EQ(r.errors.size(), 1u) << text << "\n" << joined(r.errors);
    EXPECT_EQ(r.errors[0].field, key) << text;
  }
  const auto merged = parseSpecText(R"({"scene": {"gap_um": 0.02}, "scene": "doublet"})");
  ASSERT_TRUE(merged.ok()) << joined(merged.errors);
  EXPECT_EQ(merged.spec->scene, SceneKind::Doublet);
  EXPECT_EQ(merged.spec->scene_params.gap_um, 0.02);
}

// A TOML value toml++ cannot read (1e400, an integer beyond 64 bits) was named by line and
// column only; the message names its key too. A JSON array (no format given) gets JSON's error,
// not TOML's.
TEST(SpecIo, UnreadableTomlValuesNameTheirKey) {
  auto r = parseSpecText("scene = \"cell\"\n[cells]\ngamma = 1e400\n", SpecFormat::Toml);
  ASSERT_EQ(r.errors.size(), 1u);
  EXPECT_NE(r.errors[0].message.find("(the value of cells.gamma)"), std::string::npos)
      << r.errors[0].str();
  r = parseSpecText("scene = \"cell\"\nseed = 99999999999999999999\n", SpecFormat::Toml);
  ASSERT_EQ(r.errors.size(), 1u);
  EXPECT_NE(r.errors[0].message.find("(the value of seed)"), std::string::npos)
      << r.errors[0].str();
  r = parseSpecText(R"([{"scene": "cell"}])");
  ASSERT_EQ(r.errors.size(), 1u);
  EXPECT_NE(r.errors[0].message.find("expected a JSON object at the top level, got array"),
            std::string::npos)
      << r.errors[0].str();
}

// [prepare] in every spelling TOML and JSON allow is the same table; written back only where a
// spec has one, it round-trips through spec.json; --set reaches it by its dotted key; its errors
// name the key as the document wrote it.
TEST(SpecIo, ThePrepareTableInEverySpellingAndBack) {
  const std::string head = "scene = \"fusion\"\n[cells]\nl_eta_reduced = 2\n";
  std::vector<SceneSpec> specs;
  for (const std::string& text : {head + "[prepare]\n\"cells.l_eta_reduced\" = 0.5\n",
                                  head + "[prepare]\ncells.l_eta_reduced = 0.5\n",
                                  head + "[prepare.cells]\nl_eta_reduced = 0.5\n",
                                  std::string(R"({"scene": "fusion", "cells": {"l_eta_reduced": 2},
                       "prepare": {"cells": {"l_eta_reduced": 0.5}}})"),
                                  std::string(R"({"scene": "fusion", "cells": {"l_eta_reduced": 2},
                       "prepare": {"cells.l_eta_reduced": 0.5}})")}) {
    const auto r = parseSpecText(text);
    ASSERT_TRUE(r.ok()) << text << "\n" << joined(r.errors);
    EXPECT_TRUE(validate(*r.spec).empty()) << joined(validate(*r.spec));
    specs.push_back(*r.spec);
  }
  for (const SceneSpec& s : specs) EXPECT_EQ(s, specs[0]);
  EXPECT_EQ(specs[0].prepare.at("cells.l_eta_reduced"), SpecValue(0.5));
  EXPECT_EQ(specs[0].cells.l_eta_reduced, 2.0);
  const auto settings = applySettings(
      SceneSpec{}, {"scene=fusion", "cells.l_eta_reduced=2", "prepare.cells.l_eta_reduced=0.5"});
  ASSERT_TRUE(settings.ok()) << joined(settings.errors);
  EXPECT_EQ(*settings.spec, specs[0]);

  // TOML → spec → JSON → spec, unresolved and resolved (what foam-run and foamd write).
  for (const SceneSpec& s : {specs[0], resolve(specs[0])}) {
    const nlohmann::json j = specToJson(s);
    ASSERT_TRUE(j.contains("prepare")) << j.dump();
    const auto back = parseSpecText(j.dump(2));
    ASSERT_TRUE(back.ok()) << joined(back.errors);
    EXPECT_EQ(*back.spec, s);
    EXPECT_EQ(specToJson(*back.spec), j);
  }
  const nlohmann::json r = specToJson(resolve(specs[0]));
  EXPECT_FALSE(r["prepare"]["cells"].contains("l_eta_reduced"));  // resolved into ξ, ξ⊥, ξ∥
  EXPECT_GT(r["prepare"]["cells"]["xi"].get<double>(), r["cells"]["xi"].get<double>());
  EXPECT_FALSE(specToJson(resolve(SceneSpec{})).contains("prepare"));  // written as before

  const std::pair<const char*, const char*> bad[] = {
      {"[prepare.cells]\ngama = 1\n", "prepare.cells.gama"},
      {"[prepare.numerics]\ncg_tol = 1e-4\n", "prepare.numerics.cg_tol"},
      {"[prepare]\n\"cells.alpha\" = 2\n", "prepare.cells.alpha"},
      {"[prepare]\ncells.alpha = [0.5]\n", "prepare.cells.alpha"},
      {"[prepare.bogus]\nx = 1\n", "prepare.bogus"},
      {"[prepare]\ncells = 1\n", "prepare.cells"},
      {"[prepare]\n\"cells.xi\" = 1\n[prepare.cells]\nxi = 2\n", "prepare.cells.xi"}};
  for (const auto& [table, key] : bad) {
    const auto e = problems("scene = \"fusion\"\n" + std::string(table));
    ASSERT_EQ(e.size(), 1u) << table << joined(e);
    EXPECT_EQ(e[0].field, key) << table;
  }
  const auto doublet = problems("scene = \"doublet\"\n[prepare.cells]\nalpha = 0.5\n");
  ASSERT_EQ(doublet.size(), 1u) << joined(doublet);
  EXPECT_EQ(doublet[0].field, "prepare.cells.alpha");
  EXPECT_NE(doublet[0].message.find("only the fusion scene"), std::string::npos);
  EXPECT_NE(problems("scene = \"fusion\"\n[prepar]\n")[0].message.find("did you mean [prepare]"),
            std::string::npos);
}
}  // namespace activefoam
