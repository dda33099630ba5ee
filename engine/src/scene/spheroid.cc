#include "activefoam/spheroid.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <limits>
#include <random>
#include <sstream>
#include <system_error>

#include "../integrate/bytes.h"
#include "activefoam/rng.h"
#include "activefoam/simulation.h"
#include "activefoam/step_loop.h"

namespace activefoam {
namespace {

namespace fs = std::filesystem;

// 02: polarity noise keyed by time (spheroids prepared before follow another realisation).
constexpr char kMagic[8] = {'A', 'F', 'S', 'P', 'H', 'R', '0', '2'};
constexpr double kWindowS = 60;  // compaction is judged over this much simulated time

std::string hex16(std::uint64_t h) {
  char buf[17];
  std::snprintf(buf, sizeof buf, "%016llx", static_cast<unsigned long long>(h));
  return buf;
}

fs::path cacheFile(const std::string& dir, const SceneSpec& prep) {
  return fs::path(dir) / ("spheroid-n" + std::to_string(prep.scene_params.n_cells) + "-" +
                          spheroidCacheKey(prep) + ".bin");
}

Vec3 volumeCentroid(const Geometry& g) {
  double vol = 0;
  Vec3 c = Vec3::Zero();
  for (std::size_t k = 0; k < g.cell_volume.size(); ++k) {
    vol += g.cell_volume[k];
    c += g.cell_volume[k] * g.cell_centroid[k];
  }
  return c / vol;
}

// How far B may move along −x before its surface meets A's: the smallest x-distance between a
// vertex of one and the other's surface straight across (rays parallel to x, triangles
// projected onto the yz plane). Only the facing bands (within `band` of the extremes) are
// searched: that is where two rounded aggregates first touch.
double clearanceAlongX(const CellSet& a, const CellSet& b, double band) {
  const double a_max = a.x.row(0).maxCoeff(), b_min = b.x.row(0).minCoeff();
  double best = std::numeric_limits<double>::infinity();
  // sign = +1: vertices of `from` lie to the right of `onto` (B's vertices onto A's triangles).
  auto cast = [&](const CellSet& from, const CellSet& onto, double sign) {
    std::vector<int> verts;
    for (int i = 0; i < from.numVertices(); ++i) {
      const double x = from.x(0, i);
      if (sign > 0 ? x < b_min + band : x > a_max - band) verts.push_back(i);
    }
    for (const Tri& f : onto.tri) {
      const Vec3 p0 = onto.x.col(f[0]), p1 = onto.x.col(f[1]), p2 = onto.x.col(f[2]);
      const double xmax = std::max({p0.x(), p1.x(), p2.x()});
      const double xmin = std::min({p0.x(), p1.x(), p2.x()});
      if (sign > 0 ? xmax < a_max - band : xmin > b_min + band) continue;
      const double ylo = std::min({p0.y(), p1.y(), p2.y()}),
                   yhi = std::max({p0.y(), p1.y(), p2.y()});
      const double zlo = std::min({p0.z(), p1.z(), p2.z()}),
                   zhi = std::max({p0.z(), p1.z(), p2.z()});
      // Barycentric coordinates in the yz projection.
      const double det =
          (p1.y() - p0.y()) * (p2.z() - p0.z()) - (p2.y() - p0.y()) * (p1.z() - p0.z());
      if (std::abs(det) < 1e-14) continue;  // edge-on to x
      for (int i : verts) {
        const Vec3 q = from.x.col(i);
        if (q.y() < ylo || q.y() > yhi || q.z() < zlo || q.z() > zhi) continue;
        const double l1 =
            ((q.y() - p0.y()) * (p2.z() - p0.z()) - (p2.y() - p0.y()) * (q.z() - p0.z())) / det;
        const double l2 =
            ((p1.y() - p0.y()) * (q.z() - p0.z()) - (q.y() - p0.y()) * (p1.z() - p0.z())) / det;
        if (l1 < 0 || l2 < 0 || l1 + l2 > 1) continue;
        const double x = p0.x() + l1 * (p1.x() - p0.x()) + l2 * (p2.x() - p0.x());
        best = std::min(best, sign * (q.x() - x));
      }
    }
  };
  cast(b, a, +1);
  cast(a, b, -1);
  return best;
}

}  // namespace

double radiusOfGyration(const CellSet& cells, const std::vector<double>& volumes,
                        const std::vector<Vec3>& centroids) {
  double vol = 0;
  Vec3 c = Vec3::Zero();
  for (int k = 0; k < cells.numCells(); ++k) {
    vol += volumes[k];
    c += volumes[k] * centroids[k];
  }
  c /= vol;
  double rg2 = 0;
  for (int k = 0; k < cells.numCells(); ++k) rg2 += volumes[k] * (centroids[k] - c).squaredNorm();
  return std::sqrt(rg2 / vol);
}

SceneSpec spheroidPrepSpec(const SceneSpec& spec, std::int64_t n_cells, std::uint64_t seed) {
  // A prepared spheroid is an initial condition: runs that differ only in their solver settings,
  // failure limits, contact law, repairs or fusion-only keys start from the same aggregates. The
  // key table says which keys the preparation fixes and at what (SpecField::prep); the mesh
  // settings and the cells' parameters shape the aggregates and stay, at the run's values or
  // those [prepare] gives instead.
  SceneSpec p = withPrepareValues(spec);
  p.numerics.pinned.bits = ~0u;  // the preset's name changes no value here
  for (const SpecField& f : specFields()) {
    if (f.prep != SpecField::Prep::Fixed) continue;
    if (f.prep_value)
      setField(p, f.key, *f.prep_value);
    else
      clearField(p, f.key);
  }
  p.numerics.pinned = {};
  p.scene = SceneKind::Spheroid;
  p.seed = seed;
  p.scene_params.n_cells = n_cells;
  p.numerics.dt_s = spec.scene_params.prep_dt_s;
  p.duration_s = spec.scene_params.prep_max_s;
  p.sample_every_s = kWindowS;
  p.snapshot_every_s = 0;
  return resolve(p);
}

CellSet placeholderCells(const SceneSpec& spec) {
  CellSet cells;
  const double r = spec.cells.radius_mean_um;
  const int tris = static_cast<int>(spec.numerics.triangles_per_cell);
  for (std::int64_t c = 0; c < sceneCellCount(spec); ++c)
    cells.addCell(ellipsoidCell(r, 1.0, tris, Vec3(3 * r * static_cast<double>(c), 0, 0)), r);
  return cells;
}

std::uint64_t spheroidSeed(std::uint64_t seed, int which) {
  Rng r(seed, 0x5350484552ULL + static_cast<std::uint64_t>(which));  // "SPHER" + which
  return r.next();
}

std::string spheroidCacheKey(const SceneSpec& prep) {
  std::uint64_t h = 1469598103934665603ULL;
  // The engine version is part of the key: a new version may relax spheroids differently.
  for (unsigned char c : std::string(ACTIVEFOAM_VERSION) + ";" + specFingerprint(prep)) {
    h ^= c;
    h *= 1099511628211ULL;
  }
  return hex16(h);
}

std::optional<PreparedSpheroid> SpheroidCache::load(const SceneSpec& prep) const {
  std::ifstream in(cacheFile(dir_, prep), std::ios::binary);
  if (!in) return std::nullopt;
  std::ostringstream ss;
  ss << in.rdbuf();
  const std::string data = ss.str();
  try {
    bytes::Reader r(data, "spheroid cache");
    for (char c : kMagic)
      if (r.pod<char>() != c) return std::nullopt;
    if (r.str() != specFingerprint(prep)) return std::nullopt;
    PreparedSpheroid s;
    s.relaxed_s = r.pod<double>();
    s.compact = r.pod<std::uint8_t>() != 0;
    s.radius_gyration_um = r.pod<double>();
    s.cells = deserializeCells(r.str());
    if (!r.done()) s.compaction_rate_per_s = r.pod<double>();  // absent in older files
    if (!r.done() || s.cells.numCells() != prep.scene_params.n_cells) return std::nullopt;
    s.from_cache = true;
    s.key = spheroidCacheKey(prep);
    return s;
  } catch (const std::invalid_argument&) {
    return std::nullopt;  // truncated or damaged: prepare again (and overwrite it)
  }
}

bool SpheroidCache::holds(const SceneSpec& prep) const {
  std::error_code ec;
  return fs::is_regular_file(cacheFile(dir_, prep), ec);
}

void SpheroidCache::store(const SceneSpec& prep, const PreparedSpheroid& s) const {
  std::error_code ec;
  fs::create_directories(dir_, ec);
  if (ec) throw std::runtime_error("spheroid cache: cannot create " + dir_ + ": " + ec.message());
  bytes::Writer w;
  for (char c : kMagic) w.pod(c);
  w.str(specFingerprint(prep));
  w.pod(s.relaxed_s);
  w.pod(static_cast<std::uint8_t>(s.compact));
  w.pod(s.radius_gyration_um);
  w.str(serializeCells(s.cells));
  w.pod(s.compaction_rate_per_s);
  const std::string data = w.take();
  const fs::path file = cacheFile(dir_, prep);
  // Unique temporary name per writer: two runs preparing the same spheroid do not collide.
  std::random_device entropy;
  const fs::path tmp =
      file.string() + ".tmp" + hex16((static_cast<std::uint64_t>(entropy()) << 32) ^ entropy());
  {
    std::ofstream out(tmp, std::ios::binary | std::ios::trunc);
    out.write(data.data(), static_cast<std::streamsize>(data.size()));
    out.close();
    if (!out) {
      fs::remove(tmp, ec);
      throw std::runtime_error("spheroid cache: cannot write " + tmp.string());
    }
  }
  fs::rename(tmp, file, ec);
  if (ec) {
    fs::remove(tmp, ec);
    throw std::runtime_error("spheroid cache: cannot rename into " + file.string());
  }
}

PreparedSpheroid prepareSpheroid(const SceneSpec& prep, const SpheroidCache* cache,
                                 const PrepObserver& obs) {
  auto log = [&](const std::string& s) {
    if (obs.on_log) obs.on_log(s);
  };
  const std::string key = spheroidCacheKey(prep);
  const std::string what = "spheroid of " + std::to_string(prep.scene_params.n_cells) +
                           " cells (seed " + std::to_string(prep.seed) + ", key " + key + ")";
  if (cache) {
    if (auto s = cache->load(prep)) {
      log("prepared " + what + " loaded from " + cache->dir());
      return *s;
    }
  }
  log("preparing " + what + ": relaxing for at most " + formatNumber(prep.scene_params.prep_max_s) +
      " s at dt = " + formatNumber(prep.numerics.dt_s) + " s");
  Simulation sim(prep);
  const double dt = prep.numerics.dt_s;
  const TimeStepper& clock = sim.stepper();  // in ticks: the adaptive schedule may halve steps
  const std::int64_t total = clock.ticksFor(prep.scene_params.prep_max_s);
  const std::int64_t window = clock.periodTicks(kWindowS);
  auto rg = [&] {
    return radiusOfGyration(sim.cells(), sim.geometry().cell_volume, sim.geometry().cell_centroid);
  };
  PreparedSpheroid out;
  double rg_prev = rg();
  const LoopResult loop = runSteps(sim, total, obs.cancel, [&](const StepReport& r) {
    if (!r.ok() || clock.ticks() % window != 0) return true;
    const double now = rg();
    // A one-cell spheroid (a 2 × 1 fusion: the cell doublet) has no aggregate to compact: its
    // radius of gyration is round-off, and dividing by it made its rate anything from 0 to inf.
    const double rate =
        prep.scene_params.n_cells > 1 ? std::abs(now - rg_prev) / now / kWindowS : 0.0;
    rg_prev = now;
    out.compaction_rate_per_s = rate;
    log("  relaxing: t = " + formatNumber(sim.time()) + " s, radius of gyration " +
        formatNumber(std::round(now * 1000) / 1000) +
        " µm, |dRg/dt|/Rg = " + formatNumber(std::round(rate * 1e8) / 1e8) + " /s");
    const double earliest = std::max(2 * kWindowS, prep.scene_params.prep_min_s);
    out.compact = sim.time() >= earliest - 0.5 * dt && rate < prep.scene_params.compact_rate_per_s;
    return !out.compact;
  });
  if (loop.end == LoopEnd::Cancelled) {
    PrepFailed e("cancelled while preparing the " + what);
    e.cancelled = true;
    throw e;
  }
  if (loop.end == LoopEnd::Failed) {
    PrepFailed e("preparing the " + what +
                 " failed: " + std::string(toString(loop.failed.failure)) + ": " +
                 loop.failed.reason + " (try a smaller scene.prep_dt_s)");
    e.volume_drift = loop.failed.failure == FailureKind::VolumeDrift;
    throw e;
  }
  out.relaxed_s = sim.time();
  out.radius_gyration_um = rg();
  out.cells = sim.cells();
  // Centre on the aggregate's volume centroid; velocities are not part of a prepared spheroid.
  out.cells.x.colwise() -= volumeCentroid(sim.geometry());
  out.cells.v.setZero();
  out.key = key;
  log((out.compact ? "compact after " : "not compact after the limit of ") +
      formatNumber(out.relaxed_s) + " s: radius of gyration " +
      formatNumber(std::round(out.radius_gyration_um * 1000) / 1000) + " µm");
  if (cache) {
    cache->store(prep, out);
    log("stored in " + cache->dir());
  }
  return out;
}

CellSet buildFusionCells(const SceneSpec& spec, const SpheroidCache* cache, const PrepObserver& obs,
                         std::vector<PreparedSpheroid>* info) {
  const SceneParams& sp = spec.scene_params;
  const std::int64_t na = sp.n_cells_a > 0 ? sp.n_cells_a : sp.n_cells;
  const std::int64_t nb = sp.n_cells_b > 0 ? sp.n_cells_b : sp.n_cells;
  // The default volume limit (5 %) is the preparation's own so that runs differing in their
  // limits share aggregates; a cell compressed or swollen past it at a stiff or motile point
  // (Fig. 10's γ = 1: 5.0 % at 5.8 s, at any step) would fail a run that declared it tolerates
  // more before the run starts. Such a spheroid is prepared under the run's limit instead, with
  // its own cache key (the limit halves steps, so the bits may differ); a spheroid that passes
  // at 5 % is the same as before. A cached looser preparation exists only because the default
  // one failed (preparations are deterministic), so it is taken without repeating the failure.
  auto prepare = [&](std::int64_t n, int which) {
    const SceneSpec prep = spheroidPrepSpec(spec, n, spheroidSeed(spec.seed, which));
    const double limit = spec.numerics.max_volume_error;
    if (!(limit > prep.numerics.max_volume_error)) return prepareSpheroid(prep, cache, obs);
    SceneSpec looser = prep;
    looser.numerics.max_volume_error = limit;
    if (cache && cache->holds(looser)) return prepareSpheroid(looser, cache, obs);
    try {
      return prepareSpheroid(prep, cache, obs);
    } catch (const PrepFailed& e) {
      if (!e.volume_drift) throw;
      if (obs.on_log)
        obs.on_log(std::string(e.what()) + "; preparing it again under the run's " +
                   "numerics.max_volume_error " + formatNumber(limit));
      try {
        return prepareSpheroid(looser, cache, obs);
      } catch (const PrepFailed& again) {
        if (again.cancelled) throw;
        throw PrepFailed(std::string(again.what()) + " (prepared again under the run's " +
                         "numerics.max_volume_error after failing at the preparation's " +
                         formatNumber(prep.numerics.max_volume_error) + ")");
      }
    }
  };
  PreparedSpheroid a = prepare(na, 0);
  PreparedSpheroid b = prepare(nb, 1);
  // A spheroid still compacting would fuse while it shrinks: θ(t) and the fits would mix the
  // two. prep_max_s = 0 asks for the packed cells as they are.
  if (sp.prep_max_s > 0 && !sp.allow_uncompacted)
    for (const PreparedSpheroid* s : {&a, &b})
      if (!s->compact)
        throw PrepFailed(
            std::string("spheroid ") + (s == &a ? "A" : "B") + " (" +
            std::to_string(s == &a ? na : nb) + " cells) is not compact after scene.prep_max_s = " +
            formatNumber(sp.prep_max_s) + " s: its radius of gyration changes by " +
            (std::isnan(s->compaction_rate_per_s)
                 ? std::string("a rate not measured (no 60 s window completed, or cached by an "
                               "earlier version)")
                 : formatNumber(std::round(s->compaction_rate_per_s * 1e8) / 1e8) + " /s") +
            ", the limit scene.compact_rate_per_s is " + formatNumber(sp.compact_rate_per_s) +
            " /s; raise scene.prep_max_s, or set scene.allow_uncompacted = true to fuse it as it "
            "is");
  // Touching: first the extremes gap_um apart, then B moved towards A until the closest points
  // straight across are gap_um apart (lumpy aggregates touch off their extremes).
  const double gap = initialGapUm(spec);
  double shift = a.cells.x.row(0).maxCoeff() - b.cells.x.row(0).minCoeff() + gap;
  b.cells.x.row(0).array() += shift;
  const double clearance = clearanceAlongX(a.cells, b.cells, 2 * spec.cells.radius_mean_um);
  b.cells.x.row(0).array() -= shift;
  if (std::isfinite(clearance)) shift -= clearance - gap;
  CellSet cells;
  Rng rng(spec.seed, 0);
  for (int s = 0; s < 2; ++s) {
    const CellSet& src = s == 0 ? a.cells : b.cells;
    for (int c = 0; c < src.numCells(); ++c) {
      TriMesh m = src.cellMesh(c);
      if (s == 1) m.x.row(0).array() += shift;
      cells.addCell(m, src.radius[c], s);
      cells.pi_integral.back() = src.pi_integral[c];
      if (sp.polarity_from_preparation) cells.polarity.back() = src.polarity[c];
    }
  }
  if (!sp.polarity_from_preparation)
    for (Vec3& p : cells.polarity) {
      const double z = 2 * rng.uniform() - 1, phi = 2 * M_PI * rng.uniform();
      const double r = std::sqrt(1 - z * z);
      p = Vec3(r * std::cos(phi), r * std::sin(phi), z);
    }
  if (info) *info = {std::move(a), std::move(b)};
  return cells;
}

}  // namespace activefoam
