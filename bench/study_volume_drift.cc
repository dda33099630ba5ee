// How a cell's volume error runs away: replays a job's spec (a resolved spec.json, e.g. a failed
// run's, from `foam show`/the store) through runScene, keeping checkpoints of the last samples;
// when the run fails (or reaches `until_s`), restores the checkpoint `lead_s` before the end and
// steps again from it, logging every step of the cells that end worst: their volume error ε,
// the PI integral I, the pressure and its three parts (2γ/r, −Kε, −(K/τ_K)I), contact area,
// mesh quality, remeshing and the step's length. Same spec, same bits: the replay fails where
// the run did (checked: the failure's reason is printed for both).
//
//   OMP_NUM_THREADS=1 build/release/bench/study_volume_drift SPEC.json OUT_DIR [lead_s]
//       [until_s] [cache_dir] [frames_from_s] [replay_to_s]
// OUT_DIR/steps.csv: one row per accepted step and cell; OUT_DIR/cell_C_T.obj: the surfaces of
// cells beyond 2 % every 10 s of the replay (and at its end), for a viewer; from frames_from_s
// on, OUT_DIR/frame_T.bin: every vertex's position and last velocity and every triangle, after
// each step; OUT_DIR/scan.csv: every step's pairs read deeper than 0.3 µm and those among them
// whose triangles are apart. With replay_to_s the replay runs to that time (not the run's end,
// e.g. the whole run with until_s = 60 s) and writes no per-cell log.
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <deque>
#include <filesystem>
#include <fstream>
#include <limits>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include "activefoam/contact_geometry.h"
#include "activefoam/mesh.h"
#include "activefoam/run.h"
#include "activefoam/simulation.h"
#include "activefoam/spec_io.h"
#include "activefoam/spheroid.h"
#include "activefoam/step_loop.h"
#include "resolved_spec.h"

using namespace activefoam;
namespace fs = std::filesystem;

namespace {

double volumeError(const Simulation& sim, int c) {
  const double v0 = sim.cells().target_volume[c];
  return (sim.geometry().cell_volume[c] - v0) / v0;
}

// The smallest ratio of a triangle's height on its longest edge to that edge (0: a sliver) and
// the smallest dot product of a triangle's normal with its cell's outward direction there.
struct Quality {
  double min_aspect = 1, min_normal_dot = 1;
  int triangles = 0;
};
Quality quality(const Simulation& sim, int c) {
  const CellSet& cells = sim.cells();
  const Geometry& g = sim.geometry();
  Quality q;
  q.triangles = cells.cell_tri_begin[c + 1] - cells.cell_tri_begin[c];
  for (int t = cells.cell_tri_begin[c]; t < cells.cell_tri_begin[c + 1]; ++t) {
    const Tri& f = cells.tri[t];
    double longest = 0;
    Vec3 mid = Vec3::Zero();
    for (int k = 0; k < 3; ++k) {
      longest = std::max(longest, (cells.x.col(f[(k + 1) % 3]) - cells.x.col(f[k])).norm());
      mid += cells.x.col(f[k]) / 3;
    }
    if (longest > 0) q.min_aspect = std::min(q.min_aspect, 2 * g.tri_area[t] / longest / longest);
    const Vec3 out = (mid - g.cell_centroid[c]).normalized();
    q.min_normal_dot = std::min(q.min_normal_dot, g.tri_normal[t].dot(out));
  }
  return q;
}

// The distance between two triangles (0 when they intersect): the least of the corner–triangle
// distances both ways and the edge–edge distances, and 0 when an edge of one crosses the other.
double segmentDistance(const Vec3& p0, const Vec3& p1, const Vec3& q0, const Vec3& q1) {
  const Vec3 d1 = p1 - p0, d2 = q1 - q0, r = p0 - q0;
  const double a = d1.squaredNorm(), e = d2.squaredNorm(), f = d2.dot(r), c = d1.dot(r),
               b = d1.dot(d2), den = a * e - b * b;
  double s = den > 1e-300 ? std::clamp((b * f - c * e) / den, 0.0, 1.0) : 0.0;
  double t = e > 0 ? (b * s + f) / e : 0.0;
  if (t < 0) {
    t = 0;
    s = a > 0 ? std::clamp(-c / a, 0.0, 1.0) : 0.0;
  } else if (t > 1) {
    t = 1;
    s = a > 0 ? std::clamp((b - c) / a, 0.0, 1.0) : 0.0;
  }
  return (p0 + s * d1 - (q0 + t * d2)).norm();
}
bool segmentCrosses(const Vec3& p0, const Vec3& p1, const std::array<Vec3, 3>& t) {
  const Vec3 n = (t[1] - t[0]).cross(t[2] - t[0]);
  const double d0 = n.dot(p0 - t[0]), d1 = n.dot(p1 - t[0]);
  if (d0 * d1 > 0 || d0 == d1) return false;
  const Vec3 x = p0 + d0 / (d0 - d1) * (p1 - p0);
  for (int k = 0; k < 3; ++k)
    if (n.dot((t[(k + 1) % 3] - t[k]).cross(x - t[k])) < 0) return false;
  return true;
}
double triangleDistance(const std::array<Vec3, 3>& a, const std::array<Vec3, 3>& b) {
  double d = std::numeric_limits<double>::infinity();
  for (int i = 0; i < 3; ++i) {
    if (segmentCrosses(a[i], a[(i + 1) % 3], b) || segmentCrosses(b[i], b[(i + 1) % 3], a))
      return 0;
    d = std::min(d, (a[i] - closestOnTriangle(a[i], b[0], b[1], b[2])).norm());
    d = std::min(d, (b[i] - closestOnTriangle(b[i], a[0], a[1], a[2])).norm());
    for (int j = 0; j < 3; ++j)
      d = std::min(d, segmentDistance(a[i], a[(i + 1) % 3], b[j], b[(j + 1) % 3]));
  }
  return d;
}

void writeObj(const Simulation& sim, int c, const fs::path& path) {
  const CellSet& cells = sim.cells();
  std::ofstream o(path);
  o.precision(9);
  const int v0 = cells.cell_vertex_begin[c];
  for (int v = v0; v < cells.cell_vertex_begin[c + 1]; ++v)
    o << "v " << cells.x(0, v) << ' ' << cells.x(1, v) << ' ' << cells.x(2, v) << '\n';
  for (int t = cells.cell_tri_begin[c]; t < cells.cell_tri_begin[c + 1]; ++t)
    o << "f " << cells.tri[t][0] - v0 + 1 << ' ' << cells.tri[t][1] - v0 + 1 << ' '
      << cells.tri[t][2] - v0 + 1 << '\n';
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 3) {
    std::fprintf(stderr,
                 "usage: study_volume_drift SPEC.json OUT_DIR [lead_s] [until_s] [cache_dir]\n");
    return 2;
  }
  const std::optional<SceneSpec> read = readResolvedSpec(argv[1]);
  if (!read) return 2;
  SceneSpec spec = *read;
  const fs::path out = argv[2];
  const double lead = argc > 3 ? std::atof(argv[3]) : 120;
  if (argc > 4 && std::atof(argv[4]) > 0) spec.duration_s = std::atof(argv[4]);
  fs::create_directories(out);

  // 1. The run as the job ran it, keeping the checkpoints of the last few samples; the one
  // the replay starts from is kept in OUT_DIR/replay.ckpt, and a later call with it there
  // replays from it at once.
  std::deque<std::pair<double, std::string>> kept;
  const fs::path ckpt = out / "replay.ckpt";
  if (fs::exists(ckpt)) {
    std::ifstream in(ckpt, std::ios::binary);
    kept.emplace_back(0, std::string(std::istreambuf_iterator<char>(in), {}));
  } else {
    const std::size_t keep = static_cast<std::size_t>(std::ceil(lead / spec.sample_every_s)) + 2;
    RunObserver obs;
    obs.checkpoint_every_s = spec.sample_every_s;
    obs.on_checkpoint = [&](double t, const std::string& state) {
      kept.emplace_back(t, state);
      while (kept.size() > keep) kept.pop_front();
    };
    obs.spheroid_cache_dir = argc > 5 ? argv[5] : "";
    obs.on_log = [](const std::string& line) { std::fprintf(stderr, "log: %s\n", line.c_str()); };
    double last_print = -1e9;
    obs.on_progress = [&](double t, std::int64_t, std::int64_t) {
      if (t - last_print >= 600) {
        std::fprintf(stderr, "run: t = %.0f s\n", t);
        last_print = t;
      }
    };
    const RunSummary run = runScene(spec, obs);
    std::printf("run: t = %.6g s, %lld steps, %s%s\n", run.t_s, static_cast<long long>(run.steps),
                run.ok() ? "reached its end" : "failed: ", run.reason.c_str());
    if (kept.empty()) return 1;
    while (kept.size() > 1 && kept[1].first <= run.t_s - lead) kept.pop_front();
    std::ofstream(ckpt, std::ios::binary) << kept.front().second;
  }

  // 2. The replay from that checkpoint, every step logged.
  Simulation sim(spec, placeholderCells(spec));
  sim.loadState(kept.front().second);
  std::printf("replay from t = %.6g s\n", sim.time());

  const int n = sim.cells().numCells();
  std::ofstream csv(out / "steps.csv");
  csv.precision(10);
  csv << "t_s,dt_s,rejected,cg_iters,remesh_ops,remesh_volume_jump,cell,eps,pi_integral,"
         "pressure,p_laplace,p_k,p_i,contact_area_frac,neighbours,min_aspect,min_normal_dot,"
         "triangles\n";
  const double K = spec.cells.bulk_modulus;
  const double tau_k = tauKS(spec.cells);
  double next_obj = sim.time();
  const double frames_from = argc > 6 ? std::atof(argv[6]) : 1e300;
  // The per-cell log is ~40 rows a step: only for short replays (replay_to_s unset).
  const double replay_to = argc > 7 ? std::atof(argv[7]) : 0;
  const bool with_log = replay_to <= 0;
  // int32 vertices, triangles; float64 x[3V], v[3V]; int32 tri[3T], tri_cell[T], vertex_cell[V];
  // float64 f[3V]; the pairs
  auto frame = [&] {
    const CellSet& c = sim.cells();
    char name[64];
    std::snprintf(name, sizeof name, "frame_%.4f.bin", sim.time());
    std::ofstream o(out / name, std::ios::binary);
    const std::int32_t nv = static_cast<std::int32_t>(c.x.cols()),
                       nt = static_cast<std::int32_t>(c.tri.size());
    o.write(reinterpret_cast<const char*>(&nv), 4);
    o.write(reinterpret_cast<const char*>(&nt), 4);
    o.write(reinterpret_cast<const char*>(c.x.data()), 24 * static_cast<std::streamsize>(nv));
    o.write(reinterpret_cast<const char*>(c.v.data()), 24 * static_cast<std::streamsize>(nv));
    for (const Tri& f : c.tri)
      for (int k : f) {
        const std::int32_t i = k;
        o.write(reinterpret_cast<const char*>(&i), 4);
      }
    o.write(reinterpret_cast<const char*>(c.tri_cell.data()), 4 * static_cast<std::streamsize>(nt));
    o.write(reinterpret_cast<const char*>(c.vertex_cell.data()),
            4 * static_cast<std::streamsize>(nv));
    // The force on every vertex at this state (what the next step solves for), and the active
    // contact pairs: int32 count, then per pair int32 ta, tb and float64 area, mean gap.
    Eigen::Matrix3Xd f(3, nv);
    sim.computeForces(f);
    o.write(reinterpret_cast<const char*>(f.data()), 24 * static_cast<std::streamsize>(nv));
    const std::int32_t np = static_cast<std::int32_t>(sim.contacts().pairs.size());
    o.write(reinterpret_cast<const char*>(&np), 4);
    for (const ContactPair& p : sim.contacts().pairs) {
      const std::int32_t ab[2] = {p.ta, p.tb};
      const double ag[2] = {p.c.area, p.c.mean_gap};
      o.write(reinterpret_cast<const char*>(ab), 8);
      o.write(reinterpret_cast<const char*>(ag), 16);
    }
  };
  auto log = [&](const StepReport& r) {
    std::vector<std::set<int>> nb(static_cast<std::size_t>(n));
    for (const ContactPair& p : sim.contacts().pairs) {
      const int a = sim.cells().tri_cell[p.ta], b = sim.cells().tri_cell[p.tb];
      nb[a].insert(b);
      nb[b].insert(a);
    }
    for (int c = 0; c < n; ++c) {
      const double eps = volumeError(sim, c);
      const double I = sim.cells().pi_integral[c];
      const double r_c = sim.cells().radius[c];
      const Quality q = quality(sim, c);
      csv << sim.time() << ',' << r.dt << ',' << r.rejected << ',' << r.cg.iterations << ','
          << r.remesh_ops << ',' << r.remesh_volume_jump << ',' << c << ',' << eps << ',' << I
          << ',' << sim.pressure(c) << ',' << 2 * spec.cells.gamma / r_c << ',' << -K * eps << ','
          << (tau_k > 0 ? -K / tau_k * I : 0.0) << ','
          << sim.contacts().cell_contact_area[c] / sim.geometry().cell_area[c] << ','
          << nb[c].size() << ',' << q.min_aspect << ',' << q.min_normal_dot << ',' << q.triangles
          << '\n';
    }
    if (sim.time() >= next_obj - 1e-9) {
      for (int c = 0; c < n; ++c)
        if (std::abs(volumeError(sim, c)) > 0.02)
          writeObj(
              sim, c,
              out / ("cell_" + std::to_string(c) + "_" +
                     std::to_string(static_cast<long long>(std::llround(sim.time()))) + ".obj"));
      next_obj += 10;
    }
  };
  // Every step: the pairs read deeper than 0.3 µm (≈ 5 h0; the ordinary deepest junction pair
  // reads −0.05 … −0.27 µm), how many of them are triangles that do not touch at all (their
  // true distance ≥ h0 — the bisector gap of an oblique pair, docs/science/motion-convergence.md),
  // and the deepest such pair: its gap, area, n̂_A·n̂_B, true distance and |force| = k |∫ g dS|.
  std::ofstream scan(out / "scan.csv");
  scan.precision(8);
  scan << "t_s,dt_s,pairs,deep,deep_apart,worst_gap_um,worst_area_um2,worst_facing_dot,"
          "worst_distance_um,worst_force_nN,deep_apart_force_nN,area_um2,area_deep_um2,"
          "area_mid_um2,area_shallow_um2,prisms_keep_deep_um2,prisms_keep_mid_um2,"
          "prisms_keep_shallow_um2,deep_false,deep_false_force_nN,deep_false_max_nN\n";
  // What numerics.contact_law = prisms would keep of this step's pairs, by the pair's mean gap
  // under the run's law: deeper than 0.3 µm, 0.3 µm to 0, 0 to h0.
  ContactLaw prisms;
  prisms.k = spec.cells.k_contact;
  prisms.h0 = contactRangeH0(spec.cells);
  prisms.kind = ContactLawKind::Prisms;
  auto scanStep = [&](const StepReport& r) {
    const CellSet& c = sim.cells();
    int deep = 0, apart = 0;
    double area[3] = {0, 0, 0}, kept[3] = {0, 0, 0};
    // A deep pair is "false" when, over each other (within prisms), its triangles are not
    // 0.3 µm into each other: its depth was read beside them.
    int deep_false = 0;
    double false_force = 0, false_max = 0;
    double worst_gap = 0, worst_area = 0, worst_dot = 0, worst_dist = 0, worst_force = 0,
           apart_force = 0;
    for (const ContactPair& p : sim.contacts().pairs) {
      const std::array<Vec3, 3> a{c.x.col(c.tri[p.ta][0]), c.x.col(c.tri[p.ta][1]),
                                  c.x.col(c.tri[p.ta][2])};
      const std::array<Vec3, 3> b{c.x.col(c.tri[p.tb][0]), c.x.col(c.tri[p.tb][1]),
                                  c.x.col(c.tri[p.tb][2])};
      const int cls = p.c.mean_gap < -0.3 ? 0 : p.c.mean_gap < 0 ? 1 : 2;
      area[cls] += p.c.area;
      const TriangleContact q =
          computeTriangleContact(a, b, prisms, spec.numerics.contact_quadrature);
      if (q.active) kept[cls] += q.area;
      if (cls != 0) continue;
      ++deep;
      const double force = prisms.k * std::abs(p.c.mean_gap) * p.c.area;
      if (!(q.active && q.mean_gap < -0.3)) {
        ++deep_false;
        false_force += force;
        false_max = std::max(false_max, force);
      }
      const double dist = triangleDistance(a, b);
      if (dist < prisms.h0) continue;
      ++apart;
      apart_force += force;
      if (p.c.mean_gap < worst_gap) {
        worst_gap = p.c.mean_gap;
        worst_area = p.c.area;
        worst_dot = sim.geometry().tri_normal[p.ta].dot(sim.geometry().tri_normal[p.tb]);
        worst_dist = dist;
        worst_force = force;
      }
    }
    scan << sim.time() << ',' << r.dt << ',' << sim.contacts().pairs.size() << ',' << deep << ','
         << apart << ',' << worst_gap << ',' << worst_area << ',' << worst_dot << ',' << worst_dist
         << ',' << worst_force << ',' << apart_force << ',' << area[0] + area[1] + area[2] << ','
         << area[0] << ',' << area[1] << ',' << area[2] << ',' << kept[0] << ',' << kept[1] << ','
         << kept[2] << ',' << deep_false << ',' << false_force << ',' << false_max << '\n';
  };
  const LoopResult loop =
      runSteps(sim, sim.stepper().ticksFor(replay_to > 0 ? replay_to : spec.duration_s), nullptr,
               [&](const StepReport& r) {
                 if (r.rejected > 0)
                   std::printf("t = %.6g s: %d tries rejected: %s\n", sim.time(), r.rejected,
                               r.rejected_reason.c_str());
                 if (r.ok()) scanStep(r);
                 if (r.ok() && with_log) log(r);
                 if (r.ok() && sim.time() >= frames_from - 1e-9) frame();
                 return true;
               });
  if (loop.end == LoopEnd::Failed) {
    std::printf("replay failed at t = %.6g s: %s\n", sim.time(), loop.failed.reason.c_str());
    for (int c = 0; c < n; ++c)
      if (std::abs(volumeError(sim, c)) > 0.02)
        writeObj(sim, c, out / ("cell_" + std::to_string(c) + "_end.obj"));
  } else {
    std::printf("replay reached t = %.6g s\n", sim.time());
  }
  return 0;
}
