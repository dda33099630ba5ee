// The fusion scene's machinery on small aggregates (fast enough for the sanitizer pass):
// prepared spheroids and their cache, placement, and a fusion run resumed from a checkpoint.
#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <optional>
#include <random>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "activefoam/spheroid.h"
#include "test_support.h"

using namespace activefoam;
using activefoam::testing::physicsColumns;
using activefoam::testing::smallFusionSpec;
namespace fs = std::filesystem;

namespace {

struct TempDir {
  fs::path path;
  TempDir() {
    std::random_device rd;
    path = fs::temp_directory_path() / ("af-cache-" + std::to_string(rd()) + std::to_string(rd()));
  }
  ~TempDir() {
    std::error_code ec;
    fs::remove_all(path, ec);
  }
};

// Two spherical cells of radius r side by side along x whose meshes overlap by `overlap` µm
// (negative: that far apart); `shift` receives the second one's offset.
CellSet sphereDoublet(double r, double overlap, double* shift = nullptr) {
  CellSet cells;
  TriMesh a = ellipsoidCell(r, 1.0, 320, Vec3::Zero());
  TriMesh b = ellipsoidCell(r, 1.0, 320, Vec3::Zero());
  const double dx = a.x.row(0).maxCoeff() - b.x.row(0).minCoeff() - overlap;
  b.x.row(0).array() += dx;
  cells.addCell(a, r);
  cells.addCell(b, r);
  if (shift != nullptr) *shift = dx;
  return cells;
}

}  // namespace

TEST(FusionScene, TwoLabelledSpheroidsPlacedTouchingAlongX) {
  const SceneSpec s = smallFusionSpec();
  std::vector<PreparedSpheroid> info;
  const CellSet cells = buildFusionCells(s, nullptr, {}, &info);
  ASSERT_EQ(cells.numCells(), 7);
  ASSERT_EQ(info.size(), 2u);
  EXPECT_EQ(info[0].cells.numCells(), 3);
  EXPECT_EQ(info[1].cells.numCells(), 4);
  for (int c = 0; c < 7; ++c) {
    EXPECT_EQ(cells.label[c], c < 3 ? 0 : 1);
    EXPECT_TRUE(checkClosedManifold(cells.cellMesh(c)).empty()) << c;
  }
  // B lies along +x from A and touches it: at least one contact pair joins the two spheroids,
  // none interpenetrates.
  Simulation sim(s, cells);
  Vec3 ca = Vec3::Zero(), cb = Vec3::Zero();
  for (int c = 0; c < 7; ++c)
    (c < 3 ? ca : cb) += sim.geometry().cell_centroid[c] / (c < 3 ? 3 : 4);
  EXPECT_GT(cb.x() - ca.x(), 0.8 * (cb - ca).norm());
  int across = 0;
  for (const ContactPair& p : sim.contacts().pairs) {
    EXPECT_GT(p.c.mean_gap, -0.1);
    if (cells.label[cells.tri_cell[p.ta]] != cells.label[cells.tri_cell[p.tb]]) ++across;
  }
  EXPECT_GT(across, 0);
  // The two spheroids come from different seeds.
  EXPECT_NE(spheroidSeed(s.seed, 0), spheroidSeed(s.seed, 1));
}

// scene.polarity_from_preparation: each cell starts the fusion with the polarity its spheroid's
// preparation ended with (no start-up kick to every protrusion), else one drawn afresh; the
// cells are the same either way, and the key is in the fingerprint only when set.
TEST(FusionScene, PolaritiesComeFromThePreparationOrAreDrawnAfresh) {
  SceneSpec s = smallFusionSpec();
  ASSERT_GT(s.cells.p_a, 0);  // motile: the preparation turns the polarities
  std::vector<PreparedSpheroid> info;
  const CellSet drawn = buildFusionCells(s, nullptr, {}, &info);
  s.scene_params.polarity_from_preparation = true;
  std::vector<PreparedSpheroid> info_kept;
  const CellSet kept = buildFusionCells(s, nullptr, {}, &info_kept);
  ASSERT_EQ(drawn.numCells(), 7);
  EXPECT_EQ(drawn.x, kept.x);
  int differ = 0;
  for (int c = 0; c < 7; ++c) {
    const CellSet& prep = info_kept[c < 3 ? 0 : 1].cells;
    const Vec3 p = prep.polarity[c < 3 ? c : c - 3];
    EXPECT_EQ(kept.polarity[c], p) << c;
    EXPECT_NEAR(p.norm(), 1, 1e-12) << c;
    EXPECT_NEAR(drawn.polarity[c].norm(), 1, 1e-12) << c;
    if (drawn.polarity[c] != p) ++differ;
  }
  EXPECT_EQ(differ, 7);
  // Not the default's UnitX everywhere: the preparation's own polarities, cell by cell.
  EXPECT_NE(info_kept[0].cells.polarity[0], info_kept[0].cells.polarity[1]);
  EXPECT_NE(info_kept[0].cells.polarity[0], Vec3::UnitX());
  SceneSpec off = s;
  off.scene_params.polarity_from_preparation = false;
  EXPECT_NE(specFingerprint(s).find("polarity_from_preparation"), std::string::npos);
  // Off, the key is left out: checkpoints and prepared spheroids of earlier versions stay valid.
  EXPECT_EQ(specFingerprint(off).find("polarity_from_preparation"), std::string::npos);
}

TEST(SpheroidCache, ReusesPreparationsByKeyAndIgnoresDamagedFiles) {
  TempDir dir;
  const SpheroidCache cache(dir.path.string());
  const SceneSpec s = smallFusionSpec();
  const SceneSpec prep = spheroidPrepSpec(s, 3, 11);
  const PreparedSpheroid first = prepareSpheroid(prep, &cache);
  EXPECT_FALSE(first.from_cache);
  EXPECT_GT(first.relaxed_s, 0);
  const PreparedSpheroid again = prepareSpheroid(prep, &cache);
  EXPECT_TRUE(again.from_cache);
  ASSERT_EQ(again.cells.x.cols(), first.cells.x.cols());
  EXPECT_EQ(again.cells.x, first.cells.x);  // bit-identical
  EXPECT_EQ(again.cells.tri, first.cells.tri);
  EXPECT_EQ(again.relaxed_s, first.relaxed_s);

  // Whatever shapes the spheroid is in the key; sampling and run length of the fusion are not.
  SceneSpec other = s;
  other.cells.alpha = 0.5;
  EXPECT_NE(spheroidCacheKey(spheroidPrepSpec(other, 3, 11)), spheroidCacheKey(prep));
  EXPECT_NE(spheroidCacheKey(spheroidPrepSpec(s, 3, 12)), spheroidCacheKey(prep));
  EXPECT_NE(spheroidCacheKey(spheroidPrepSpec(s, 4, 11)), spheroidCacheKey(prep));
  other = s;
  other.duration_s = 500;
  other.sample_every_s = 7;
  EXPECT_EQ(spheroidCacheKey(spheroidPrepSpec(other, 3, 11)), spheroidCacheKey(prep));
  // Nor are the fusion run's solver settings (a study varies them from the same aggregates);
  // the mesh is.
  other = s;
  other.numerics.dt_s = 0.1;
  other.numerics.cg_tol = 1e-6;
  other.numerics.preconditioner = PreconditionerKind::BlockJacobi;
  other.numerics.contact_quadrature = ContactQuadrature::Centroid;
  EXPECT_EQ(spheroidCacheKey(spheroidPrepSpec(other, 3, 11)), spheroidCacheKey(prep));
  // Nor the contact law's experimental bounds: a run with one starts from its reference's
  // aggregates (they are prepared under the supplement's law, docs/model.md §7.3).
  for (ContactLawKind law :
       {ContactLawKind::Supplement, ContactLawKind::Prisms, ContactLawKind::PrismsOverlap}) {
    other.numerics.contact_law = law;
    EXPECT_EQ(spheroidCacheKey(spheroidPrepSpec(other, 3, 11)), spheroidCacheKey(prep));
    EXPECT_EQ(spheroidPrepSpec(other, 3, 11).numerics.contact_law, ContactLawKind::Supplement);
  }
  // Nor the remesher's repairs of locked cells.
  for (RemeshRepair r : {RemeshRepair::None, RemeshRepair::Rescue, RemeshRepair::RescueRebuild}) {
    other.numerics.remesh_repair = r;
    EXPECT_EQ(spheroidCacheKey(spheroidPrepSpec(other, 3, 11)), spheroidCacheKey(prep));
    EXPECT_EQ(spheroidPrepSpec(other, 3, 11).numerics.remesh_repair, RemeshRepair::None);
  }
  // Nor the collapses' keep-out.
  other.numerics.remesh_keep_out_um = 0.75;
  EXPECT_EQ(spheroidCacheKey(spheroidPrepSpec(other, 3, 11)), spheroidCacheKey(prep));
  EXPECT_EQ(spheroidPrepSpec(other, 3, 11).numerics.remesh_keep_out_um, 0);
  // The preparation's preconditioner is its own, Jacobi, whatever the run's (the presets' is
  // block-Jacobi): prepared aggregates keep their bits and cache keys.
  EXPECT_EQ(prep.numerics.preconditioner, PreconditionerKind::Jacobi);
  EXPECT_EQ(spheroidPrepSpec(other, 3, 11).numerics.preconditioner, PreconditionerKind::Jacobi);
  other.numerics.triangles_per_cell = s.numerics.triangles_per_cell == 80 ? 320 : 80;
  EXPECT_NE(spheroidCacheKey(spheroidPrepSpec(other, 3, 11)), spheroidCacheKey(prep));

  // A damaged file reads as absent: prepared again, and the file is replaced.
  ASSERT_EQ(std::distance(fs::directory_iterator(dir.path), fs::directory_iterator()), 1);
  const fs::path file = fs::directory_iterator(dir.path)->path();
  fs::resize_file(file, fs::file_size(file) / 2);
  EXPECT_FALSE(cache.load(prep).has_value());
  const PreparedSpheroid redone = prepareSpheroid(prep, &cache);
  EXPECT_FALSE(redone.from_cache);
  EXPECT_EQ(redone.cells.x, first.cells.x);  // deterministic in its seed
  EXPECT_TRUE(cache.load(prep).has_value());
}

// [prepare]: a controlled experiment prepares one aggregate at the base point and runs each
// configuration from it. Two runs differing in their own L_η/r but not in the preparation's start
// from the same cells bit for bit, the second loading what the first prepared; without [prepare]
// their preparations differ. The run keeps its own ξ, ξ⊥ and ξ∥.
TEST(FusionScene, PrepareValuesGiveRunsDifferingInTheirOwnValuesTheSameAggregates) {
  TempDir dir;
  const SpheroidCache cache(dir.path.string());
  auto fusion = [](double l_eta, std::optional<double> prep_l_eta) {
    SceneSpec s = activefoam::testing::smallFusionBase();
    s.cells.l_eta_reduced = l_eta;
    if (prep_l_eta) {
      EXPECT_EQ(setField(s, "prepare.cells.l_eta_reduced", *prep_l_eta), std::nullopt);
    }
    EXPECT_TRUE(validate(s).empty());
    return resolve(s);
  };
  const SceneSpec a = fusion(2, 0.5), b = fusion(1, 0.5), base = fusion(0.5, std::nullopt);
  ASSERT_GT(a.cells.p_a, 0);  // motile: the friction shapes the relaxation
  EXPECT_NE(a.cells.xi, b.cells.xi);
  EXPECT_EQ(a.cells.xi_normal, a.cells.xi);
  EXPECT_EQ(a.cells.xi_tangential, a.cells.xi);
  for (const char* key : {"cells.xi", "cells.xi_normal", "cells.xi_tangential"}) {
    EXPECT_EQ(getField(a, std::string("prepare.") + key), getField(base, key)) << key;
    EXPECT_EQ(getField(b, std::string("prepare.") + key), getField(base, key)) << key;
  }
  EXPECT_EQ(a.prepare.size(), 3u);  // only what differs from the run
  EXPECT_EQ(spheroidPrepSpec(a, 3, 11), spheroidPrepSpec(base, 3, 11));
  EXPECT_EQ(spheroidPrepSpec(b, 3, 11), spheroidPrepSpec(base, 3, 11));
  EXPECT_NE(specFingerprint(a), specFingerprint(fusion(2, std::nullopt)));

  std::vector<PreparedSpheroid> info_a, info_b;
  const CellSet cells_a = buildFusionCells(a, &cache, {}, &info_a);
  const CellSet cells_b = buildFusionCells(b, &cache, {}, &info_b);
  for (int k = 0; k < 2; ++k) {
    EXPECT_FALSE(info_a[k].from_cache) << k;
    EXPECT_TRUE(info_b[k].from_cache) << k;  // loaded, not prepared again
    EXPECT_EQ(info_b[k].key, info_a[k].key);
  }
  EXPECT_EQ(cells_a.x, cells_b.x);
  EXPECT_EQ(cells_a.tri, cells_b.tri);
  EXPECT_EQ(cells_a.polarity, cells_b.polarity);
  EXPECT_EQ(cells_a.pi_integral, cells_b.pi_integral);

  // Without [prepare] each run prepares at its own ξ: other aggregates.
  std::vector<PreparedSpheroid> own_a, own_b;
  const CellSet plain_a = buildFusionCells(fusion(2, std::nullopt), &cache, {}, &own_a);
  const CellSet plain_b = buildFusionCells(fusion(1, std::nullopt), &cache, {}, &own_b);
  EXPECT_FALSE(own_a[0].from_cache);
  EXPECT_NE(own_a[0].key, info_a[0].key);
  EXPECT_NE(own_a[0].key, own_b[0].key);
  ASSERT_EQ(plain_a.x.cols(), plain_b.x.cols());
  EXPECT_NE(plain_a.x, plain_b.x);
}

// A spheroid still compacting would fuse while it shrinks: unless the spec allows
// it, the job fails with preparation-failed, naming the rate reached and the limit — also when
// the uncompacted spheroid comes from the cache.
// Soft cells (K = 0.02 nN/µm² against the default 0.5) are compressed past the preparation's
// default 5 % volume limit by their tension and packing, at any step: a run that tolerates 30 %
// prepares them under its own limit, the other fails naming the drift. Cells that pass at 5 %
// keep the default preparation's key and bits.
TEST(FusionScene, APreparationFailingAtTheDefaultVolumeLimitFollowsTheRunsLooserLimit) {
  TempDir dir;
  const SpheroidCache cache(dir.path.string());
  SceneSpec s = smallFusionSpec();
  s.cells.bulk_modulus = 0.02;
  s.scene_params.prep_max_s = 60;
  s = resolve(s);
  ASSERT_EQ(s.numerics.max_volume_error, 0.05);
  try {
    buildFusionCells(s, &cache);
    FAIL() << "the soft cells passed the 5 % limit: the test no longer reaches the fallback";
  } catch (const PrepFailed& e) {
    EXPECT_TRUE(e.volume_drift);
    EXPECT_NE(std::string(e.what()).find("volume-drift"), std::string::npos) << e.what();
  }
  SceneSpec tolerant = s;
  tolerant.numerics.max_volume_error = 0.3;
  std::vector<std::string> lines;
  PrepObserver po;
  po.on_log = [&](const std::string& l) { lines.push_back(l); };
  std::vector<PreparedSpheroid> info;
  const CellSet cells = buildFusionCells(tolerant, &cache, po, &info);
  ASSERT_EQ(cells.numCells(), 7);
  for (int k = 0; k < 2; ++k) {
    const SceneSpec prep = spheroidPrepSpec(tolerant, k == 0 ? 3 : 4, spheroidSeed(5, k));
    EXPECT_EQ(prep.numerics.max_volume_error, 0.05);  // the key of the default preparation
    SceneSpec looser = prep;
    looser.numerics.max_volume_error = 0.3;
    EXPECT_EQ(info[k].key, spheroidCacheKey(looser)) << k;
    EXPECT_FALSE(info[k].from_cache);
  }
  bool said = false;
  for (const std::string& l : lines)
    said |= l.find("preparing it again under the run's numerics.max_volume_error 0.3") !=
            std::string::npos;
  EXPECT_TRUE(said);
  // Prepared under the looser limit, every cell is within it.
  Simulation sim(tolerant, cells);
  double worst = 0;
  for (int c = 0; c < 7; ++c)
    worst =
        std::max(worst, std::abs(sim.geometry().cell_volume[c] / sim.cells().target_volume[c] - 1));
  EXPECT_LT(worst, 0.3);
  // Again: taken from the cache as the looser preparation, without repeating the failure.
  lines.clear();
  std::vector<PreparedSpheroid> again;
  const CellSet cached = buildFusionCells(tolerant, &cache, po, &again);
  EXPECT_EQ(cached.x, cells.x);
  for (int k = 0; k < 2; ++k) {
    EXPECT_TRUE(again[k].from_cache);
    EXPECT_EQ(again[k].key, info[k].key);
  }
  for (const std::string& l : lines) EXPECT_EQ(l.find("failed"), std::string::npos) << l;

  // Stiff cells pass at 5 %: a looser run limit leaves their preparation (key, bits) alone.
  SceneSpec stiff = smallFusionSpec();
  std::vector<PreparedSpheroid> base, loose;
  const CellSet at5 = buildFusionCells(stiff, nullptr, {}, &base);
  stiff.numerics.max_volume_error = 0.3;
  const CellSet at30 = buildFusionCells(stiff, nullptr, {}, &loose);
  EXPECT_EQ(at30.x, at5.x);
  for (int k = 0; k < 2; ++k) EXPECT_EQ(loose[k].key, base[k].key);
}

TEST(FusionScene, AnUncompactedSpheroidFailsThePreparationNamingItsRate) {
  TempDir dir;
  SceneSpec s = smallFusionSpec();
  s.scene_params.allow_uncompacted = false;
  s.scene_params.prep_max_s = 70;  // one 60 s window measured; compact needs ≥ 120 s
  RunObserver obs;
  obs.spheroid_cache_dir = dir.path.string();
  for (int pass = 0; pass < 2; ++pass) {  // prepared, then from the cache
    const RunSummary r = runScene(s, obs);
    EXPECT_EQ(r.failure, FailureKind::PreparationFailed) << r.reason;
    EXPECT_EQ(r.steps, 0);
    for (const char* part :
         {"spheroid A (3 cells) is not compact after scene.prep_max_s = 70 s", "changes by ",
          "the limit scene.compact_rate_per_s is 5e-5 /s", "scene.allow_uncompacted = true"})
      EXPECT_NE(r.reason.find(part), std::string::npos) << part << "\n" << r.reason;
    EXPECT_EQ(r.reason.find("not measured"), std::string::npos) << r.reason;
  }
  s.scene_params.allow_uncompacted = true;
  const RunSummary r = runScene(s, obs);
  EXPECT_TRUE(r.ok()) << r.reason;
  s.scene_params.allow_uncompacted = false;  // no relaxation asked for: the packed cells
  s.scene_params.prep_max_s = 0;
  EXPECT_TRUE(runScene(s, obs).ok());
}

// The cell doublet (2 × 1): a one-cell spheroid has no aggregate to compact, and its radius of
// gyration is round-off; the compaction rate divided by it used to fail one seed's preparation
// at random ("changes by inf /s") and pass another's.
TEST(FusionScene, AOneCellSpheroidIsCompactOnceRelaxedAndTheDoubletRuns) {
  for (std::uint64_t seed : {2u, 5u, 11u}) {
    SceneSpec s = smallFusionSpec(seed, 1, 1, 20, 10);
    s.scene_params.allow_uncompacted = false;
    s.scene_params.prep_max_s = 600;
    std::vector<PreparedSpheroid> info;
    const CellSet cells = buildFusionCells(s, nullptr, {}, &info);
    EXPECT_EQ(cells.numCells(), 2);
    ASSERT_EQ(info.size(), 2u);
    for (const PreparedSpheroid& p : info) {
      EXPECT_TRUE(p.compact) << "seed " << seed;
      EXPECT_EQ(p.compaction_rate_per_s, 0.0) << "seed " << seed;
      // relaxed for the two windows the criterion needs, not to prep_max_s
      EXPECT_LT(p.relaxed_s, 200.0) << "seed " << seed;
    }
    const RunSummary r = runScene(s, RunObserver{});
    EXPECT_TRUE(r.ok()) << "seed " << seed << ": " << r.reason;
  }
}

// Weak adhesion keeps the radius of gyration still while the junctions open (docs/validation.md):
// scene.prep_min_s holds the compaction back, and a weak-adhesion fusion that could start
// before weakAdhesionPrepMinS(α) is named (foamd refuses it, foam-run warns).
TEST(FusionScene, PrepMinHoldsCompactionBackAndWeakAdhesionAsksForIt) {
  SceneSpec s = smallFusionSpec();
  s.scene_params.prep_max_s = 600;
  s.scene_params.compact_rate_per_s = 1;  // any rate: compact at the earliest time allowed
  const SceneSpec quick = spheroidPrepSpec(s, 3, 7);
  const PreparedSpheroid q = prepareSpheroid(quick, nullptr);
  EXPECT_TRUE(q.compact);
  EXPECT_DOUBLE_EQ(q.relaxed_s, 120);  // two 60 s windows
  s.scene_params.prep_min_s = 300;
  const SceneSpec held = spheroidPrepSpec(s, 3, 7);
  EXPECT_NE(spheroidCacheKey(held), spheroidCacheKey(quick));
  const PreparedSpheroid h = prepareSpheroid(held, nullptr);
  EXPECT_TRUE(h.compact);
  EXPECT_DOUBLE_EQ(h.relaxed_s, 300);
  // At 0 the key is the one of versions before the key existed (cached spheroids stay valid).
  EXPECT_EQ(specFingerprint(quick).find("prep_min_s"), std::string::npos);

  s.scene_params.prep_min_s = 700;  // beyond prep_max_s
  const std::vector<SpecError> e = validate(s);
  ASSERT_EQ(e.size(), 1u);
  EXPECT_EQ(e[0].field, "scene.prep_min_s");
  EXPECT_NE(e[0].message.find("exceeds scene.prep_max_s = 600 s"), std::string::npos)
      << e[0].message;

  SceneSpec weak;
  weak.cells.alpha = 0.9;
  EXPECT_TRUE(validate(weak).empty());
  EXPECT_DOUBLE_EQ(weakAdhesionPrepMinS(0.9), 3000);
  EXPECT_DOUBLE_EQ(weakAdhesionPrepMinS(0.8), 1500);
  EXPECT_DOUBLE_EQ(weakAdhesionPrepMinS(0.75), 0);
  std::vector<SpecError> w = silentlyWrong(weak);
  ASSERT_EQ(w.size(), 1u);
  EXPECT_EQ(w[0].field, "scene.prep_min_s");
  for (const char* part : {"cells.alpha = 0.9", "at least 300/(1 - cells.alpha) = 3000 s",
                           "scene.prep_max_s (now 1800 s) at least as long"})
    EXPECT_NE(w[0].message.find(part), std::string::npos) << part << "\n" << w[0].message;
  weak.scene_params.prep_max_s = 3000;
  weak.scene_params.prep_min_s = 3000;
  EXPECT_TRUE(silentlyWrong(weak).empty());
  weak.scene_params.prep_min_s = 0;
  weak.scene_params.allow_uncompacted = true;  // about prep_max_s running out, not this
  EXPECT_EQ(silentlyWrong(weak).size(), 1u);
  weak.scene_params.prep_max_s = 0;  // the packed cells, no relaxation asked for
  EXPECT_TRUE(silentlyWrong(weak).empty());
  EXPECT_TRUE(silentlyWrong(SceneSpec{}).empty());  // the defaults (α = 0.4375)
  SceneSpec doublet;
  doublet.scene = SceneKind::Doublet;  // no spheroids to prepare
  doublet.cells.alpha = 0.9;
  EXPECT_TRUE(silentlyWrong(doublet).empty());
}

TEST(FusionScene, SamplesFitsAndResumeFromCheckpoint) {
  TempDir dir;
  const SceneSpec s = smallFusionSpec();
  const auto cols = sampleColumns(s);
  ASSERT_EQ(cols[5], "dt_min_s");
  ASSERT_EQ(cols[6], "steps_rejected");
  ASSERT_EQ(cols[7], "theta_deg");
  std::vector<Sample> full;
  std::vector<std::string> logs;
  std::string state;
  double state_t = -1;
  RunObserver obs;
  obs.spheroid_cache_dir = dir.path.string();
  obs.on_log = [&](const std::string& l) { logs.push_back(l); };
  obs.on_sample = [&](const Sample& x) { full.push_back(x); };
  obs.checkpoint_every_s = 4;
  obs.on_checkpoint = [&](double t, const std::string& st) {
    if (state_t < 0) state_t = t, state = st;
  };
  const RunSummary a = runScene(s, obs);
  ASSERT_TRUE(a.ok()) << a.reason;
  ASSERT_EQ(full.size(), 11u);
  for (const Sample& x : full) {
    ASSERT_EQ(x.values.size(), cols.size());
    EXPECT_TRUE(std::isfinite(x.values[7])) << "theta at t=" << x.values[0];
    EXPECT_GE(x.values[7], 0);
    EXPECT_LE(x.values[7], 90);
  }
  ASSERT_EQ(a.fits.size(), 3u);
  EXPECT_EQ(a.fits[0].first, "eq1");
  // Placed touching with adhesion: in contact throughout, so fused or arrested, and fitted.
  EXPECT_TRUE(a.outcome == "fused" || a.outcome == "arrested")
      << a.outcome << ": " << a.outcome_why;
  EXPECT_EQ(cols.back(), "contact_area_ab_um2");
  for (const Sample& x : full) EXPECT_GT(x.values.back(), 0) << "t=" << x.values[0];
  std::map<std::string, double> fin(a.final_values.begin(), a.final_values.end());
  for (const char* k :
       {"mixing_time_s", "mixing_time_less_rotation_s", "mixing_less_rotation_reached",
        "msrd_end_less_rotation_um2", "turn_end_deg"})
    EXPECT_TRUE(fin.count(k)) << k;
  EXPECT_TRUE(std::isfinite(fin["msrd_end_less_rotation_um2"]));
  EXPECT_GE(fin["turn_end_deg"], 0);
  EXPECT_LE(fin["turn_end_deg"], 180);
  // Two preparations of 10 s (no 60 s window): preparing, compact or not, stored.
  EXPECT_EQ(logs.size(), 6u);

  // Resumed from the checkpoint at t = 4 s: the same samples after it, the same fits.
  ASSERT_EQ(state_t, 4);
  std::vector<Sample> rest;
  RunObserver obs2;
  obs2.on_sample = [&](const Sample& x) { rest.push_back(x); };
  const RunSummary b = runScene(s, obs2, &state);
  ASSERT_TRUE(b.ok()) << b.reason;
  const auto pf = physicsColumns(full), pr = physicsColumns(rest);
  ASSERT_EQ(pr.size(), 6u);
  for (std::size_t k = 0; k < pr.size(); ++k) EXPECT_EQ(pr[k], pf[k + 5]) << k;
  ASSERT_EQ(b.fits.size(), a.fits.size());
  for (std::size_t k = 0; k < a.fits.size(); ++k) {
    EXPECT_EQ(b.fits[k].second.ok, a.fits[k].second.ok);
    EXPECT_EQ(b.fits[k].second.value, a.fits[k].second.value);
  }
  EXPECT_EQ(b.final_values, a.final_values);
  EXPECT_EQ(b.outcome, a.outcome);
  EXPECT_EQ(b.outcome_why, a.outcome_why);

  // The second run from scratch reuses both prepared spheroids and reproduces the first.
  std::vector<Sample> again;
  logs.clear();
  obs.on_sample = [&](const Sample& x) { again.push_back(x); };
  obs.on_checkpoint = nullptr;
  ASSERT_TRUE(runScene(s, obs).ok());
  ASSERT_EQ(logs.size(), 2u);
  EXPECT_NE(logs[0].find("loaded"), std::string::npos) << logs[0];
  EXPECT_EQ(physicsColumns(again), pf);
}

// Cells that really overlap stop the run with `interpenetration`: a vertex of one lies deeper
// than the limit inside the other.
TEST(Interpenetration, OverlappingCellsStopTheRunTouchingOnesDoNot) {
  SceneSpec s = activefoam::testing::cellSpec(1.0, 320);
  s.scene = SceneKind::Doublet;
  s.numerics.max_penetration_um = 0.5;
  s = resolve(s);
  const double r = s.cells.radius_mean_um;
  // Meshes 3 µm into each other (area-weighted mean gap −0.8 µm; the deepest pair −2 µm), and
  // 50 nm apart. The check runs on the current contacts; the stiff contact-implicit springs
  // would push the first apart within one step.
  for (const double overlap : {3.0, -0.05}) {
    Simulation sim(s, sphereDoublet(r, overlap));
    const std::string why = sim.interpenetration();
    if (overlap > 0) {
      EXPECT_NE(why.find("cells 0 and 1 interpenetrate: vertex"), std::string::npos) << why;
    } else {
      EXPECT_EQ(why, "");
      EXPECT_FALSE(sim.contacts().pairs.empty());
    }
  }
}

// The winding number and the distance the guard's depth is made of, on a sphere's mesh: 1 inside,
// 0 outside (also within 0.05 µm of the surface), and the distance to the inscribed polyhedron
// within its sagitta of the distance to the sphere.
TEST(Interpenetration, WindingNumberAndDistanceOnACellsMesh) {
  CellSet cells;
  cells.addCell(ellipsoidCell(7.0, 1.0, 320, Vec3(1, 2, 3)), 7.0);
  const double r = (cells.x.col(0) - Vec3(1, 2, 3)).norm();  // the vertices' sphere
  std::mt19937 rng(5);
  std::normal_distribution<double> n01;
  double max_edge = 0;
  for (const Tri& t : cells.tri)
    for (int k = 0; k < 3; ++k)
      max_edge = std::max(max_edge, (cells.x.col(t[k]) - cells.x.col(t[(k + 1) % 3])).norm());
  const double sagitta = max_edge * max_edge / (4 * r);  // circumradius ≤ edge/√3, generously
  for (int i = 0; i < 200; ++i) {
    const Vec3 dir = Vec3(n01(rng), n01(rng), n01(rng)).normalized();
    const double rho = std::uniform_real_distribution<double>(0, 2 * r)(rng);
    const Vec3 p = Vec3(1, 2, 3) + rho * dir;
    const double w = windingNumber(cells, 0, p);
    if (rho < r - sagitta - 0.05) {
      EXPECT_NEAR(w, 1.0, 1e-9) << rho;
    } else if (rho > r + 0.05) {
      EXPECT_NEAR(w, 0.0, 1e-9) << rho;
    }
    const double d = distanceToSurface(cells, 0, p);
    EXPECT_LE(d, std::abs(rho - r) + sagitta + 1e-9) << rho;
    EXPECT_GE(d, std::abs(rho - r) - sagitta - 1e-9) << rho;
  }
  // On a vertex: distance 0.
  EXPECT_NEAR(distanceToSurface(cells, 0, cells.x.col(17)), 0.0, 1e-12);
}

// The depth the guard reports is that of the other cell's vertices inside the sphere's mesh
// (reference: r − |x − c|, within the polyhedron's sagitta); it stops at depths beyond the
// limit only.
TEST(Interpenetration, TheReportedDepthIsTheDeepestVertexInsideTheOtherCell) {
  SceneSpec s = activefoam::testing::cellSpec(1.0, 320);
  s.scene = SceneKind::Doublet;
  s = resolve(s);
  const double r = s.cells.radius_mean_um;
  for (const double overlap : {0.4, 0.8, 1.6, 2.4}) {
    double shift = 0;
    const CellSet cells = sphereDoublet(r, overlap, &shift);
    // The analytic depth of b's vertices in a's sphere (that of its vertices), and of a's in b's.
    const double rv = cells.x.col(0).norm();
    double reference = 0;
    for (int i = 0; i < cells.numVertices(); ++i) {
      const Vec3 c = cells.vertex_cell[i] == 1 ? Vec3::Zero() : Vec3(shift, 0, 0);
      reference = std::max(reference, rv - (cells.x.col(i) - c).norm());
    }
    Simulation sim(s, cells);
    PenetrationScratch scratch;
    for (const double limit : {0.5 * reference, 1.5 * reference}) {
      const std::string why = interpenetration(sim.cells(), sim.contacts(), limit, 0, scratch);
      if (limit > reference) {
        EXPECT_EQ(why, "") << overlap;
        continue;
      }
      const auto at = why.find(" lies ");
      ASSERT_NE(at, std::string::npos) << overlap << ": " << why;
      const double depth = std::stod(why.substr(at + 6));
      EXPECT_NEAR(depth, reference, 0.15) << overlap << ": " << why;
    }
  }
}

// A deep mean gap alone does not stop a run: what the oblique bisectors of a junction read
// (−0.4 … −1.1 µm where no vertex is inside the other cell, the 24 h fusion's end) is not an
// overlap. Here the touching doublet's pairs are given a mean gap of −3 µm by hand.
TEST(Interpenetration, ADeepMeanGapWithNoVertexInsideIsNoOverlap) {
  SceneSpec s = activefoam::testing::cellSpec(1.0, 320);
  s.scene = SceneKind::Doublet;
  s.numerics.max_penetration_um = 0.5;
  s = resolve(s);
  Simulation sim(s, sphereDoublet(s.cells.radius_mean_um, -0.05));
  ContactList faked = sim.contacts();
  ASSERT_FALSE(faked.pairs.empty());
  for (ContactPair& p : faked.pairs) p.c.mean_gap = -3.0;
  PenetrationScratch scratch;
  EXPECT_EQ(interpenetration(sim.cells(), faked, 0.5, 0, scratch), "");
  // The same cells moved 1.5 µm into each other do stop it.
  CellSet deep = sim.cells();
  for (int i = deep.cell_vertex_begin[1]; i < deep.numVertices(); ++i) deep.x(0, i) -= 1.55;
  Simulation moved(s, deep);
  EXPECT_NE(interpenetration(moved.cells(), moved.contacts(), 0.5, 0, scratch), "");
}

// The failure says how the deepest vertex's surface lies against the cell it is inside: two
// membranes pressed into each other face each other; at p_a r/2γ = 1, α 0.3 one cell's sheet
// slid through its neighbour's and faced the same way (docs/science/fig8-pa1-probe/), where the
// contact has nothing to push it back with.
TEST(Interpenetration, SaysWhetherTheMembranesCrossedOrWerePressedIn) {
  SceneSpec s = activefoam::testing::cellSpec(1.0, 320);
  s.scene = SceneKind::Doublet;
  s = resolve(s);
  const double r = s.cells.radius_mean_um;
  const auto cosineIn = [](const std::string& why) {
    const auto at = why.find("(cosine ");
    return at == std::string::npos ? 0.0 : std::stod(why.substr(at + 8));
  };
  PenetrationScratch scratch;
  Simulation pressed(s, sphereDoublet(r, 1.6));
  const std::string in = interpenetration(pressed.cells(), pressed.contacts(), 0.5, 0, scratch);
  EXPECT_NE(in.find(": pressed in"), std::string::npos) << in;
  EXPECT_LT(cosineIn(in), -0.9) << in;

  // A larger cell B whose sphere holds most of A: B's membrane crosses A's along a circle where
  // their outward normals agree (no facing pair there), and A's far side lies 7 µm inside B,
  // facing the way B's surface does. A contact pair is given by hand so that the guard looks.
  CellSet crossed;
  crossed.addCell(ellipsoidCell(r, 1.0, 320, Vec3::Zero()), r);
  crossed.addCell(ellipsoidCell(1.35 * r, 1.0, 320, Vec3(-0.45 * r, 0, 0)), 1.35 * r);
  ContactList faked;
  ContactPair pair{};
  pair.ta = crossed.cell_tri_begin[0];
  pair.tb = crossed.cell_tri_begin[1];
  pair.c.mean_gap = -3.0;
  pair.c.area = 1.0;
  faked.pairs.push_back(pair);
  const std::string through = interpenetration(crossed, faked, 0.5, 0, scratch);
  EXPECT_NE(through.find("vertex"), std::string::npos) << through;
  EXPECT_NE(through.find(": the membranes have crossed"), std::string::npos) << through;
  EXPECT_GT(cosineIn(through), 0.9) << through;
}

// With the step's start (adaptive stepping keeps it) the guard fails a step only if it deepened
// an overlap beyond the limit: an overlap the step began with, and made no deeper, is not the
// step's doing, and halving the step could not take it out.
TEST(Interpenetration, AStepThatDidNotDeepenTheOverlapPasses) {
  SceneSpec s = activefoam::testing::cellSpec(1.0, 320);
  s.scene = SceneKind::Doublet;
  s = resolve(s);
  const double r = s.cells.radius_mean_um;
  const CellSet start = sphereDoublet(r, 1.6);
  PenetrationScratch scratch;
  for (const double end : {1.2, 1.6, 2.0}) {
    Simulation sim(s, sphereDoublet(r, end));
    const std::string strict = interpenetration(sim.cells(), sim.contacts(), 0.5, 0, scratch);
    EXPECT_NE(strict.find("cells 0 and 1 interpenetrate"), std::string::npos) << end;
    const std::string why = interpenetration(sim.cells(), sim.contacts(), 0.5, 0, scratch, &start);
    if (end <= 1.6) {
      EXPECT_EQ(why, "") << end;
    } else {
      EXPECT_NE(why.find("µm at the step's start"), std::string::npos) << why;
      // Whether the step remeshed either cell (its remesher moves vertices without looking at
      // the neighbours); an empty list: none was due.
      const std::vector<char> second_only{0, 1}, none;
      const std::string r =
          interpenetration(sim.cells(), sim.contacts(), 0.5, 0, scratch, &start, &second_only);
      EXPECT_NE(r.find("the step did not remesh cell 0; the step remeshed cell 1"),
                std::string::npos)
          << r;
      EXPECT_NE(interpenetration(sim.cells(), sim.contacts(), 0.5, 0, scratch, &start, &none)
                    .find("did not remesh cell 0; the step did not remesh cell 1"),
                std::string::npos);
    }
  }
}
