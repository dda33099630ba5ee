// proto ↔ engine spec conversion (server/spec_convert.cc).
#include <gtest/gtest.h>

#include <google/protobuf/descriptor.h>

#include <algorithm>
#include <cmath>
#include <set>

#include "activefoam/spec.h"
#include "activefoam/spec_io.h"
#include "spec_convert.h"

using namespace activefoam;
using namespace activefoam::server;
namespace pb = google::protobuf;

namespace {

// Every leaf of the typed message, as a spec key.
void leaves(const pb::Descriptor* d, const std::string& prefix, std::set<std::string>& out) {
  for (int i = 0; i < d->field_count(); ++i) {
    const pb::FieldDescriptor* f = d->field(i);
    if (f->cpp_type() == pb::FieldDescriptor::CPPTYPE_MESSAGE) {
      const bool scene = f->containing_oneof() != nullptr;
      leaves(f->message_type(), scene ? "scene." : prefix + f->name() + ".", out);
      if (scene) out.insert("scene");
    } else {
      out.insert(prefix + f->name());
    }
  }
}

}  // namespace

TEST(SpecConvert, EveryProtoFieldIsAKeyAndEveryKeyHasAField) {
  std::set<std::string> proto;
  leaves(v1::SceneSpec::descriptor(), "", proto);
  std::set<std::string> keys;
  for (const SpecField& f : specFields()) keys.insert(f.key);
  for (const std::string& field : proto) {
    // [prepare] holds the [cells] and [numerics] messages again.
    const std::string k = field.rfind("prepare.", 0) == 0 ? field.substr(8) : field;
    if (keys.count(k)) continue;
    // A field without a key is a retired key's, still read from earlier clients and records.
    SceneSpec s;
    const bool numeric =
        k == "numerics.contact_max_facing_deg" || k == "numerics.contact_max_overlap_um";
    const SpecValue neutral = k == "numerics.contact_max_facing_deg" ? SpecValue(90.0)
                              : numeric                              ? SpecValue(0.0)
                                                                     : SpecValue(false);
    const auto retired = setRetiredField(s, k, neutral);
    EXPECT_TRUE(retired.has_value() && !*retired) << "proto field without key: " << k;
  }
  for (const std::string& k : keys) EXPECT_TRUE(proto.count(k)) << "key without proto field: " << k;
  for (const SpecField& f : specFields()) {
    if (f.prep == SpecField::Prep::Kept) {
      EXPECT_TRUE(proto.count("prepare." + f.key)) << f.key;
    }
  }
}

TEST(SpecConvert, TypedFieldsReachTheEngineSpec) {
  v1::SceneSpec m;
  m.mutable_cell()->set_axes_ratio(1.1);
  m.set_seed(7);
  m.set_duration_s(5);
  m.set_sample_every_s(1);
  m.mutable_cells()->set_gamma(0.7);
  m.mutable_numerics()->set_triangles_per_cell(80);
  m.mutable_numerics()->set_integrator(v1::INTEGRATOR_SEMI_IMPLICIT);
  m.mutable_numerics()->set_contact_quadrature(v1::CONTACT_QUADRATURE_DUNAVANT7);
  m.mutable_numerics()->set_preconditioner(v1::PRECONDITIONER_BLOCK_JACOBI);
  const ConvertResult r = convertSpec(m);
  ASSERT_TRUE(r.ok()) << errorText(r.errors);
  EXPECT_EQ(r.spec->scene, SceneKind::Cell);
  EXPECT_EQ(r.spec->seed, 7u);
  EXPECT_DOUBLE_EQ(r.spec->scene_params.axes_ratio, 1.1);
  EXPECT_DOUBLE_EQ(r.spec->cells.gamma, 0.7);
  EXPECT_EQ(r.spec->numerics.triangles_per_cell, 80);
  EXPECT_EQ(r.spec->numerics.integrator, IntegratorKind::SemiImplicit);
  EXPECT_EQ(r.spec->numerics.contact_quadrature, ContactQuadrature::Dunavant7);
  EXPECT_EQ(r.spec->numerics.preconditioner, PreconditionerKind::BlockJacobi);
}

// Every integrator of the engine has its proto value, both ways (the enum names map by spelling).
TEST(SpecConvert, EveryIntegratorCrossesTheProto) {
  for (IntegratorKind kind : {IntegratorKind::SemiImplicit, IntegratorKind::ContactImplicit,
                              IntegratorKind::Ros2, IntegratorKind::ContactImplicitConsistent}) {
    SceneSpec s;
    s.scene = SceneKind::Doublet;
    s.numerics.integrator = kind;
    s.numerics.dt_s = 0.005;  // within every integrator's stable range
    const SceneSpec resolved = resolve(s);
    const ConvertResult r = convertSpec(toProto(resolved));
    ASSERT_TRUE(r.ok()) << toString(kind) << ": " << errorText(r.errors);
    EXPECT_EQ(r.spec->numerics.integrator, kind) << toString(kind);
  }
  v1::SceneSpec m;
  m.mutable_doublet();
  m.mutable_numerics()->set_dt_s(0.5);
  m.mutable_numerics()->set_integrator(v1::INTEGRATOR_CONTACT_IMPLICIT_CONSISTENT);
  const ConvertResult r = convertSpec(m);
  ASSERT_TRUE(r.ok()) << errorText(r.errors);
  EXPECT_EQ(r.spec->numerics.integrator, IntegratorKind::ContactImplicitConsistent);
}

TEST(SpecConvert, RoundTripThroughProto) {
  SceneSpec s;
  s.scene = SceneKind::Doublet;
  s.seed = 3;
  s.duration_s = 10;
  s.sample_every_s = 2;
  s.snapshot_every_s = 5;
  s.cells.alpha = 0.5;
  s.numerics.triangles_per_cell = 80;
  s.numerics.dt_s = 0.2;         // 80 motile triangles: below the measured 0.25 s limit
  s.scene_params.gap_um = 0.03;  // inside h0 = 59 nm at α = 0.5
  const SceneSpec resolved = resolve(s);
  const ConvertResult r = convertSpec(toProto(resolved));
  ASSERT_TRUE(r.ok()) << errorText(r.errors);
  EXPECT_EQ(*r.spec, resolved);
}

TEST(SpecConvert, TextAndSettingsApplyOnTopOfTyped) {
  v1::SceneSpec m;
  m.mutable_cells()->set_gamma(0.7);
  const ConvertResult r = convertSpec(m, "scene = \"cell\"\nduration_s = 4\nsample_every_s = 1\n",
                                      {"cells.gamma=0.9", "seed=11"});
  ASSERT_TRUE(r.ok()) << errorText(r.errors);
  EXPECT_DOUBLE_EQ(r.spec->cells.gamma, 0.9);
  EXPECT_DOUBLE_EQ(r.spec->duration_s, 4);
  EXPECT_EQ(r.spec->seed, 11u);
}

// A [scene] key that the scene does not read is refused naming the key, the scene and the
// scenes that read it — from settings and from spec text alike; the same key on its scene runs.
TEST(SpecConvert, SceneKeysTheSceneDoesNotUseAreRefused) {
  ConvertResult r = convertSpec(v1::SceneSpec{}, "", {"scene=cell", "scene.n_cells=20"});
  ASSERT_FALSE(r.ok());
  ASSERT_EQ(r.errors.size(), 1u);
  EXPECT_EQ(r.errors[0].field, "scene.n_cells");
  EXPECT_EQ(r.errors[0].message,
            "not used by the cell scene (only by: spheroid, fusion); remove it, or run the "
            "scene it belongs to");
  r = convertSpec(v1::SceneSpec{}, "scene = \"doublet\"\n[scene]\nprep_max_s = 10\n", {});
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.errors[0].field, "scene.prep_max_s");
  r = convertSpec(v1::SceneSpec{}, "", {"scene=spheroid", "scene.n_cells=20"});
  EXPECT_TRUE(r.ok()) << errorText(r.errors);
  SceneSpec fusion;
  fusion.scene_params.n_cells = 20;
  fusion.scene_params.gap_um = 0.01;
  EXPECT_TRUE(activefoam::checkSceneKeys(
                  resolve(fusion), {"scene.n_cells", "scene.gap_um", "cells.alpha", "scene.kind"})
                  .empty());
  // A resolved spec lists every key; those at their defaults are not "set".
  SceneSpec cell;
  cell.scene = SceneKind::Cell;
  const SceneSpec resolved = resolve(cell);
  const std::vector<std::string> all = {"scene.n_cells", "scene.gap_um", "scene.prep_max_s",
                                        "scene.allow_uncompacted", "scene.axes_ratio"};
  EXPECT_TRUE(activefoam::checkSceneKeys(resolved, all).empty());
  SceneSpec odd = resolved;
  odd.scene_params.prep_max_s = 5;
  ASSERT_EQ(activefoam::checkSceneKeys(odd, all).size(), 1u);
  EXPECT_EQ(activefoam::checkSceneKeys(odd, all)[0].field, "scene.prep_max_s");
}

// A single cell has no contacts: adhesion, contact friction, the contact springs and motility
// are never built (Simulation::init), so their keys change nothing and are refused (such a run
// had the same bits as one without them). The same keys run on a doublet.
TEST(SpecConvert, ContactAndMotilityKeysOnASingleCellAreRefused) {
  for (const char* set : {"cells.alpha=0.5", "cells.k_contact=50", "cells.xi=0.5",
                          "cells.xi_normal=0.5", "cells.xi_tangential=0.1", "cells.p_a=0",
                          "cells.tau_p_s=60", "cells.pa_reduced=0.5", "cells.l_eta_reduced=1",
                          "numerics.contact_quadrature=centroid", "numerics.max_penetration_um=0.5",
                          "numerics.max_oscillating_steps=5", "numerics.contact_law=prisms"}) {
    const std::string key = std::string(set).substr(0, std::string(set).find('='));
    ConvertResult r = convertSpec(v1::SceneSpec{}, "", {"scene=cell", set});
    ASSERT_FALSE(r.ok()) << set;
    EXPECT_EQ(r.errors[0].field, key);
    EXPECT_NE(r.errors[0].message.find("not used by the cell scene (only by: doublet, spheroid, "
                                       "fusion)"),
              std::string::npos)
        << r.errors[0].message;
    r = convertSpec(v1::SceneSpec{}, "", {"scene=doublet", set});
    EXPECT_TRUE(r.ok()) << set << ": " << errorText(r.errors);
  }
  // The cell's own keys, a preset, and a resolved cell spec listing every key at its default.
  ConvertResult r = convertSpec(v1::SceneSpec{}, "",
                                {"scene=cell", "cells.gamma=0.6", "cells.eta=4",
                                 "numerics.preset=reference", "numerics.dt_s=0.2"});
  EXPECT_TRUE(r.ok()) << errorText(r.errors);
  SceneSpec cell;
  cell.scene = SceneKind::Cell;
  cell.cells.gamma = 0.7;
  applyPreset(cell.numerics, FidelityPreset::Reference);
  EXPECT_TRUE(activefoam::checkSceneKeys(
                  resolve(cell), {"cells.alpha", "cells.xi_normal", "cells.pa_reduced",
                                  "numerics.contact_quadrature", "numerics.max_penetration_um"})
                  .empty());
}

// numerics.contact_law (proto field 26) reaches the engine from the typed message and from
// settings, and so do the two switches of earlier versions (fields 21, 22), as the law they
// named; it is the scenes with contacts' only.
TEST(SpecConvert, TheContactLawTravelsAndSoDoItsEarlierSwitches) {
  v1::SceneSpec typed;
  typed.mutable_numerics()->set_contact_law(v1::CONTACT_LAW_PRISMS);
  ConvertResult r = convertSpec(typed, "", {"scene=doublet", "numerics.dt_s=0.5"});
  ASSERT_TRUE(r.ok()) << errorText(r.errors);
  EXPECT_EQ(r.spec->numerics.contact_law, ContactLawKind::Prisms);
  v1::SceneSpec old;
  old.mutable_numerics()->set_contact_within_prisms(false);
  old.mutable_numerics()->set_contact_prisms_overlap_only(false);
  r = convertSpec(old, "", {"scene=doublet", "numerics.dt_s=0.5"});
  ASSERT_TRUE(r.ok()) << errorText(r.errors);
  EXPECT_EQ(r.spec->numerics.contact_law, ContactLawKind::Supplement);
  r = convertSpec(v1::SceneSpec{}, "",
                  {"scene=doublet", "numerics.contact_law=supplement", "numerics.dt_s=0.5"});
  ASSERT_TRUE(r.ok()) << errorText(r.errors);
  EXPECT_EQ(r.spec->numerics.contact_law, ContactLawKind::Supplement);
  EXPECT_EQ(toProto(*r.spec).numerics().contact_law(), v1::CONTACT_LAW_SUPPLEMENT);
  r = convertSpec(v1::SceneSpec{}, "", {"scene=cell", "numerics.contact_law=prisms"});
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.errors[0].field, "numerics.contact_law");
}

TEST(SpecConvert, ThePolarityFromThePreparationTravelsAndIsTheFusionsOnly) {
  v1::SceneSpec typed;
  typed.mutable_fusion()->set_polarity_from_preparation(true);
  ConvertResult r = convertSpec(typed, "", {});
  ASSERT_TRUE(r.ok()) << errorText(r.errors);
  EXPECT_TRUE(r.spec->scene_params.polarity_from_preparation);
  r = convertSpec(v1::SceneSpec{}, "", {"scene=fusion", "scene.polarity_from_preparation=true"});
  ASSERT_TRUE(r.ok()) << errorText(r.errors);
  EXPECT_TRUE(r.spec->scene_params.polarity_from_preparation);
  r = convertSpec(v1::SceneSpec{}, "", {"scene=doublet", "scene.polarity_from_preparation=false"});
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.errors[0].field, "scene.polarity_from_preparation");
}

// [prepare] (field 24) travels typed, as text and as settings alike; the stored record and the
// record served back keep it; keys it cannot hold and scenes without a preparation are refused
// naming the key.
TEST(SpecConvert, ThePrepareTableTravelsAndIsTheFusionsOnly) {
  v1::SceneSpec typed;
  typed.mutable_fusion();
  typed.mutable_cells()->set_l_eta_reduced(2);
  typed.mutable_prepare()->mutable_cells()->set_l_eta_reduced(0.5);
  const ConvertResult r = convertSpec(typed);
  ASSERT_TRUE(r.ok()) << errorText(r.errors);
  SceneSpec want;
  want.cells.l_eta_reduced = 2;
  ASSERT_EQ(setField(want, "prepare.cells.l_eta_reduced", 0.5), std::nullopt);
  EXPECT_EQ(*r.spec, resolve(want));
  EXPECT_EQ(r.spec->prepare.count("cells.xi"), 1u);
  for (const ConvertResult& same :
       {convertSpec(v1::SceneSpec{},
                    "scene = \"fusion\"\n[cells]\nl_eta_reduced = 2\n"
                    "[prepare.cells]\nl_eta_reduced = 0.5\n"),
        convertSpec(v1::SceneSpec{}, "",
                    {"scene=fusion", "cells.l_eta_reduced=2", "prepare.cells.l_eta_reduced=0.5"}),
        convertSpec(toProto(*r.spec))}) {
    ASSERT_TRUE(same.ok()) << errorText(same.errors);
    EXPECT_EQ(*same.spec, *r.spec);
  }
  const std::string record = specToJson(*r.spec).dump();
  const SpecParseResult read = readRecord(record);
  ASSERT_TRUE(read.ok()) << errorText(read.errors);
  EXPECT_EQ(*read.spec, *r.spec);
  EXPECT_EQ(nlohmann::json::parse(resolvedRecordJson(record))["prepare"],
            nlohmann::json::parse(record)["prepare"]);

  v1::SceneSpec fixed = typed;
  fixed.mutable_prepare()->mutable_numerics()->set_cg_tol(1e-4);
  ConvertResult bad = convertSpec(fixed);
  ASSERT_FALSE(bad.ok());
  EXPECT_EQ(bad.errors[0].field, "prepare.numerics.cg_tol");
  v1::SceneSpec doublet;
  doublet.mutable_doublet();
  doublet.mutable_prepare()->mutable_cells()->set_alpha(0.5);
  bad = convertSpec(doublet);
  ASSERT_FALSE(bad.ok());
  EXPECT_EQ(bad.errors[0].field, "prepare.cells.alpha");
  EXPECT_NE(bad.errors[0].message.find("only the fusion scene"), std::string::npos);
}

// numerics.remesh_repair (proto field 27) reaches the engine from the typed message and from
// settings, in every scene (every scene remeshes); the switches of earlier versions (fields 23,
// 24) read as the policy they named.
TEST(SpecConvert, TheRemeshRepairTravelsAndSoDoItsEarlierSwitches) {
  v1::SceneSpec typed;
  typed.mutable_numerics()->set_remesh_repair(v1::REMESH_REPAIR_RESCUE);
  ConvertResult r = convertSpec(typed, "", {"scene=cell"});
  ASSERT_TRUE(r.ok()) << errorText(r.errors);
  EXPECT_EQ(r.spec->numerics.remesh_repair, RemeshRepair::Rescue);
  v1::SceneSpec old;
  old.mutable_numerics()->set_remesh_rescue(false);
  old.mutable_numerics()->set_remesh_rebuild(false);
  r = convertSpec(old, "", {"scene=cell"});
  ASSERT_TRUE(r.ok()) << errorText(r.errors);
  EXPECT_EQ(r.spec->numerics.remesh_repair, RemeshRepair::None);
  r = convertSpec(v1::SceneSpec{}, "", {"scene=fusion"});
  ASSERT_TRUE(r.ok()) << errorText(r.errors);
  EXPECT_EQ(r.spec->numerics.remesh_repair, RemeshRepair::RescueRebuild);
}

TEST(SpecConvert, TheRemeshKeepOutTravels) {
  v1::SceneSpec typed;
  typed.mutable_numerics()->set_remesh_keep_out_um(0.75);
  ConvertResult r = convertSpec(typed, "", {"scene=cell"});
  ASSERT_TRUE(r.ok()) << errorText(r.errors);
  EXPECT_EQ(r.spec->numerics.remesh_keep_out_um, 0.75);
  r = convertSpec(v1::SceneSpec{}, "", {"scene=fusion", "numerics.remesh_keep_out_um=0.5"});
  ASSERT_TRUE(r.ok()) << errorText(r.errors);
  EXPECT_EQ(r.spec->numerics.remesh_keep_out_um, 0.5);
  r = convertSpec(v1::SceneSpec{}, "", {"scene=fusion"});
  ASSERT_TRUE(r.ok()) << errorText(r.errors);
  EXPECT_EQ(r.spec->numerics.remesh_keep_out_um, 0);
  r = convertSpec(v1::SceneSpec{}, "", {"scene=fusion", "numerics.remesh_keep_out_um=-1"});
  ASSERT_FALSE(r.ok());
  EXPECT_NE(errorText(r.errors).find("numerics.remesh_keep_out_um"), std::string::npos)
      << errorText(r.errors);
}

// Keys read only under another key's setting (the key table's read_if): the remesher's five
// with remeshing off (remesh_every_s = 0: RemeshPolicy never remeshes), numerics.dt_min_s
// without the adaptive step, and numerics.remesh_keep_out_um on a single cell (nothing touches
// it) were accepted and changed nothing. Each is refused naming the key and the setting; the
// same keys run where they are read, and a resolved spec that lists them at the values they
// have unset passes.
TEST(SpecConvert, KeysReadOnlyUnderAnotherSettingAreRefusedWhereUnread) {
  const std::vector<std::string> remesh = {
      "numerics.remesh_min_area_factor=0.25", "numerics.remesh_max_area_factor=4",
      "numerics.remesh_on_surface=false", "numerics.remesh_repair=none",
      "numerics.remesh_keep_out_um=1"};
  for (const std::string& set : remesh) {
    const std::string key = set.substr(0, set.find('='));
    ConvertResult r =
        convertSpec(v1::SceneSpec{}, "", {"scene=doublet", "numerics.remesh_every_s=0", set});
    ASSERT_FALSE(r.ok()) << set;
    ASSERT_EQ(r.errors.size(), 1u) << errorText(r.errors);
    EXPECT_EQ(r.errors[0].field, key);
    EXPECT_EQ(r.errors[0].message,
              "not used: read only while remeshing is on (numerics.remesh_every_s > 0), which "
              "this spec turns off (numerics.remesh_every_s = 0); remove it, or change that "
              "setting");
    // In the spec text, before the key that turns remeshing off, alike.
    std::string value = set.substr(set.find('=') + 1);
    if (value == "none") value = "\"none\"";
    r = convertSpec(v1::SceneSpec{},
                    "scene = \"doublet\"\n[numerics]\n" + key.substr(9) + " = " + value +
                        "\nremesh_every_s = 0\n",
                    {});
    EXPECT_FALSE(r.ok()) << set;
    r = convertSpec(v1::SceneSpec{}, "", {"scene=doublet", set});
    EXPECT_TRUE(r.ok()) << set << ": " << errorText(r.errors);
    r = convertSpec(v1::SceneSpec{}, "", {"scene=doublet", "numerics.remesh_every_s=30", set});
    EXPECT_TRUE(r.ok()) << set << ": " << errorText(r.errors);
  }
  // At their defaults they change nothing either way.
  ConvertResult r =
      convertSpec(v1::SceneSpec{}, "",
                  {"scene=doublet", "numerics.remesh_every_s=0",
                   "numerics.remesh_max_area_factor=3", "numerics.remesh_keep_out_um=0"});
  EXPECT_TRUE(r.ok()) << errorText(r.errors);

  r = convertSpec(v1::SceneSpec{}, "",
                  {"scene=cell", "numerics.adaptive=false", "numerics.dt_min_s=0.001"});
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.errors[0].field, "numerics.dt_min_s");
  EXPECT_EQ(r.errors[0].message,
            "not used: read only by the adaptive step (numerics.adaptive = true), which this spec "
            "turns off (numerics.adaptive = false); remove it, or change that setting");
  r = convertSpec(v1::SceneSpec{}, "", {"scene=cell", "numerics.dt_min_s=0.001"});
  EXPECT_TRUE(r.ok()) << errorText(r.errors);

  r = convertSpec(v1::SceneSpec{}, "", {"scene=cell", "numerics.remesh_keep_out_um=1"});
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.errors[0].field, "numerics.remesh_keep_out_um");
  EXPECT_NE(r.errors[0].message.find("not used by the cell scene (only by: doublet, spheroid, "
                                     "fusion)"),
            std::string::npos)
      << r.errors[0].message;

  // A resolved spec (spec.json, what a Slurm task runs) lists every key: with remeshing and the
  // adaptive step off, at a Δt of its own (dt_min_s resolved to that Δt/64), it passes.
  SceneSpec fixed;
  fixed.scene = SceneKind::Doublet;
  fixed.numerics.remesh_every_s = 0;
  fixed.numerics.adaptive = false;
  fixed.numerics.dt_s = 0.05;
  const SceneSpec resolved = resolve(fixed);
  ASSERT_TRUE(resolved.numerics.dt_min_s.has_value());
  const std::vector<std::string> all = {
      "numerics.remesh_min_area_factor", "numerics.remesh_max_area_factor",
      "numerics.remesh_on_surface",      "numerics.remesh_repair",
      "numerics.remesh_keep_out_um",     "numerics.dt_min_s"};
  EXPECT_TRUE(activefoam::checkSceneKeys(resolved, all).empty())
      << errorText(activefoam::checkSceneKeys(resolved, all));
  SceneSpec odd = resolved;
  odd.numerics.dt_min_s = 0.01;
  ASSERT_EQ(activefoam::checkSceneKeys(odd, all).size(), 1u);
  EXPECT_EQ(activefoam::checkSceneKeys(odd, all)[0].field, "numerics.dt_min_s");
}

TEST(SpecConvert, MissingSceneNamesTheSceneKey) {
  ConvertResult r = convertSpec(v1::SceneSpec{});
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.errors[0].field, "scene");
}

// foamd refuses a step the stability study saw fail, naming the limit; --allow-unstable
// (ConvertOptions) lets an operator run it to measure exactly that, and changes nothing else.
TEST(SpecConvert, AStepBeyondTheMeasuredStableRangeIsRefusedUnlessAllowed) {
  const std::vector<std::string> settings = {"scene=fusion",
                                             "numerics.integrator=contact-implicit-consistent",
                                             "numerics.dt_s=1", "numerics.contact_law=supplement"};
  ConvertResult r = convertSpec(v1::SceneSpec{}, {}, settings);  // motile by default
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.errors[0].field, "numerics.dt_s");
  EXPECT_NE(r.errors[0].message.find("beyond the stable range"), std::string::npos)
      << r.errors[0].message;
  ConvertOptions allow;
  allow.allow_unstable = true;
  r = convertSpec(v1::SceneSpec{}, {}, settings, allow);
  ASSERT_TRUE(r.ok()) << errorText(r.errors);
  EXPECT_EQ(r.spec->numerics.dt_s, 1.0);
  // Other errors stand: the option is about the stability limits only.
  std::vector<std::string> bad = settings;
  bad.push_back("numerics.dt_s=-1");
  r = convertSpec(v1::SceneSpec{}, {}, bad, allow);
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.errors[0].field, "numerics.dt_s");
  bad = settings;
  bad.push_back("cells.alpha=0.9");
  bad.push_back("scene.gap_um=0.05");  // beyond the adhesion range: silently wrong, still refused
  r = convertSpec(v1::SceneSpec{}, {}, bad, allow);
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.errors[0].field, "scene.gap_um");
}

TEST(SpecConvert, AnAccuracyTargetPicksAPresetAndTheStoredSpecRecordsIt) {
  v1::SceneSpec m;
  m.mutable_doublet();
  m.set_duration_s(10);
  m.set_sample_every_s(1);
  m.mutable_accuracy()->set_contact_angle_deg(2);
  const ConvertResult r = convertSpec(m);
  ASSERT_TRUE(r.ok()) << errorText(r.errors);
  EXPECT_EQ(r.spec->numerics.preset, FidelityPreset::Standard);
  EXPECT_EQ(r.spec->numerics.dt_s, presetInfo(FidelityPreset::Standard).dt_s);
  const v1::SceneSpec stored = toProto(*r.spec);
  EXPECT_EQ(stored.numerics().preset(), v1::FIDELITY_PRESET_STANDARD);
  EXPECT_EQ(stored.accuracy().contact_angle_deg(), 2);
  const ConvertResult again = convertSpec(stored);  // a re-queued job reads it back
  ASSERT_TRUE(again.ok()) << errorText(again.errors);
  EXPECT_EQ(*again.spec, *r.spec);

  v1::SceneSpec p;  // a preset by name, one key of it overridden by a setting
  p.mutable_doublet();
  p.set_duration_s(10);
  p.set_sample_every_s(1);
  p.mutable_numerics()->set_preset(v1::FIDELITY_PRESET_REFERENCE);
  const ConvertResult ref = convertSpec(p, "", {"numerics.dt_s=0.2"});
  ASSERT_TRUE(ref.ok()) << errorText(ref.errors);
  EXPECT_EQ(ref.spec->numerics.cg_tol, 1e-3);
  EXPECT_EQ(ref.spec->numerics.dt_s, 0.2);

  m.mutable_accuracy()->set_trajectory_deg(0.01);  // finer than any preset
  const ConvertResult bad = convertSpec(m);
  ASSERT_FALSE(bad.ok());
  EXPECT_EQ(bad.errors[0].field, "accuracy.trajectory_deg");
}

// A gap the adhesion cannot close would "succeed" with cells that never touch: refused, naming
// the gap, the adhesion range and the keys it comes from. Unset, the gap lies inside the range.
TEST(SpecConvert, AGapBeyondTheAdhesionRangeIsRefusedAndTheDefaultIsInsideIt) {
  v1::SceneSpec m;
  m.mutable_doublet()->set_gap_um(0.05);
  m.set_duration_s(10);
  m.set_sample_every_s(1);
  m.mutable_cells()->set_alpha(0.9);  // h0 = √(0.1 γ / k_AB) = 26.5 nm
  ConvertResult r = convertSpec(m);
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.errors[0].field, "scene.gap_um");
  for (const char* part :
       {"h0 = √(w/k_AB) = 0.0265", "cells.alpha = 0.9", "cells.k_contact", "allowed [0, 0.0265"})
    EXPECT_NE(r.errors[0].message.find(part), std::string::npos) << r.errors[0].message;
  m.mutable_doublet()->clear_gap_um();
  r = convertSpec(m);
  ASSERT_TRUE(r.ok()) << errorText(r.errors);
  const double h0 = std::sqrt(0.1 * 0.5 / 71.1);
  EXPECT_DOUBLE_EQ(*r.spec->scene_params.gap_um, 0.8 * h0);
  m.mutable_cells()->clear_alpha();  // the defaults: h0 = 63 nm, the supplement's 50 nm gap
  r = convertSpec(m);
  ASSERT_TRUE(r.ok()) << errorText(r.errors);
  EXPECT_DOUBLE_EQ(*r.spec->scene_params.gap_um, 0.05);
}

// Weak adhesion: spheroids that count as compact before their junctions open would start the
// fusion from point contacts; refused naming scene.prep_min_s and the time it needs.
TEST(SpecConvert, AWeakAdhesionFusionWithoutALongEnoughRelaxationIsRefused) {
  v1::SceneSpec m;
  m.mutable_fusion()->set_n_cells(20);
  m.set_duration_s(10);
  m.set_sample_every_s(1);
  m.mutable_cells()->set_alpha(0.9);
  ConvertResult r = convertSpec(m);
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.errors[0].field, "scene.prep_min_s");
  EXPECT_NE(r.errors[0].message.find("= 3000 s"), std::string::npos) << r.errors[0].message;
  m.mutable_fusion()->set_prep_min_s(3000);
  m.mutable_fusion()->set_prep_max_s(3600);
  r = convertSpec(m);
  EXPECT_TRUE(r.ok()) << errorText(r.errors);
  EXPECT_EQ(r.spec->scene_params.prep_min_s, 3000);
}

TEST(SpecConvert, SettingsTheStabilityStudyMeasuredToFailAreRefusedNamingTheLimit) {
  v1::SceneSpec m;
  m.mutable_doublet();
  m.set_duration_s(10);
  m.set_sample_every_s(1);
  m.mutable_numerics()->set_integrator(v1::INTEGRATOR_SEMI_IMPLICIT);
  ConvertResult r = convertSpec(m);  // Δt 0.1 s: the explicit contact spring fails at 10 ms
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.errors[0].field, "numerics.dt_s");
  EXPECT_NE(r.errors[0].message.find("allowed (0, 0.01) s"), std::string::npos)
      << r.errors[0].message;
  m.mutable_numerics()->set_dt_s(0.005);
  r = convertSpec(m);
  EXPECT_TRUE(r.ok()) << errorText(r.errors);
  m.mutable_numerics()->set_integrator(v1::INTEGRATOR_CONTACT_IMPLICIT);
  m.mutable_numerics()->set_dt_s(1);  // contact-oscillation from 1 s, motile or not
  r = convertSpec(m);
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.errors[0].field, "numerics.dt_s");
  m.mutable_cells()->set_p_a(0);
  r = convertSpec(m);
  ASSERT_FALSE(r.ok());
  EXPECT_EQ(r.errors[0].field, "numerics.dt_s");
  m.mutable_numerics()->set_dt_s(0.5);
  r = convertSpec(m);
  EXPECT_TRUE(r.ok()) << errorText(r.errors);
}
