// Which remesh operation puts a vertex of one cell inside its neighbour: replays a job's spec
// from a checkpoint (study_volume_drift's OUT_DIR/replay.ckpt) to just before the step that
// failed, then remeshes the two cells named with the run's remesh parameters and with one
// operation at a time switched off, and reports, for each variant, the operations done and the
// deepest vertex of each cell inside the other (generalised winding number > 1/2; depth = the
// distance to the other's surface), before and after.
//
//   OMP_NUM_THREADS=1 build/release/bench/study_remesh_overlap SPEC.json CKPT T_BEFORE CELL_A
//   CELL_B
//       [OBJ_PREFIX] [KEEP_OUT_UM]
//
// T_BEFORE: the time of the last accepted step before the failing one (the replay stops there).
// With OBJ_PREFIX the two cells' meshes before the remesh are written to OBJ_PREFIX-A.obj and
// OBJ_PREFIX-B.obj (full precision, with a "# radius_um R" line: tests/engine/data's format).
#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "activefoam/cellset.h"
#include "activefoam/remesh.h"
#include "activefoam/remesh_policy.h"
#include "activefoam/simulation.h"
#include "activefoam/spec_io.h"
#include "activefoam/spheroid.h"
#include "activefoam/step_guards.h"
#include "activefoam/step_loop.h"
#include "resolved_spec.h"

using namespace activefoam;

namespace {

struct Deepest {
  double depth = 0;
  int vertex = -1;
};

// The deepest vertex of mesh a inside mesh b.
Deepest deepestInside(const TriMesh& a, double ra, const TriMesh& b, double rb) {
  CellSet two;
  two.addCell(a, ra);
  two.addCell(b, rb);
  Deepest d;
  for (int i = 0; i < a.numVertices(); ++i) {
    const Vec3 p = a.x.col(i);
    if (windingNumber(two, 1, p) <= 0.5) continue;
    const double depth = distanceToSurface(two, 1, p);
    if (depth > d.depth) d = {depth, i};
  }
  return d;
}

double smallest(const TriMesh& m) {
  double s = 1e300;
  for (int t = 0; t < m.numTriangles(); ++t) s = std::min(s, triangleArea(m, t));
  return s;
}

void writeObj(const TriMesh& m, double radius, const std::string& path) {
  std::FILE* f = std::fopen(path.c_str(), "w");
  if (!f) return;
  std::fprintf(f, "# radius_um %.17g\n", radius);
  for (int i = 0; i < m.numVertices(); ++i)
    std::fprintf(f, "v %.17g %.17g %.17g\n", m.x(0, i), m.x(1, i), m.x(2, i));
  for (const Tri& t : m.tri) std::fprintf(f, "f %d %d %d\n", t[0] + 1, t[1] + 1, t[2] + 1);
  std::fclose(f);
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 6) {
    std::fprintf(stderr, "usage: study_remesh_overlap SPEC.json CKPT T_BEFORE CELL_A CELL_B\n");
    return 2;
  }
  const std::optional<SceneSpec> read = readResolvedSpec(argv[1]);
  if (!read) return 2;
  const SceneSpec spec = *read;
  std::ifstream in(argv[2], std::ios::binary);
  const std::string state((std::istreambuf_iterator<char>(in)), {});
  const double t_before = std::atof(argv[3]);
  const int ca = std::atoi(argv[4]), cb = std::atoi(argv[5]);

  Simulation sim(spec, placeholderCells(spec));
  sim.loadState(state);
  std::printf("checkpoint at t = %.6g s\n", sim.time());
  const LoopResult loop = runSteps(sim, sim.stepper().ticksFor(spec.duration_s), nullptr,
                                   [&](const StepReport&) { return sim.time() < t_before - 1e-9; });
  std::printf("replayed to t = %.8g s (%s)\n", sim.time(),
              loop.end == LoopEnd::Failed ? loop.failed.reason.c_str() : "ok");

  const CellSet& cells = sim.cells();
  const TriMesh a0 = cells.cellMesh(ca), b0 = cells.cellMesh(cb);
  const double ra = cells.radius[ca], rb = cells.radius[cb];
  if (argc > 6) {
    writeObj(a0, ra, std::string(argv[6]) + "-A.obj");
    writeObj(b0, rb, std::string(argv[6]) + "-B.obj");
  }
  // numerics.remesh_keep_out_um as the simulation sets it (KEEP_OUT_UM, default a quarter of
  // the interpenetration guard's depth): each cell kept out of the other.
  CellSet two;
  two.addCell(a0, ra);
  two.addCell(b0, rb);
  const double keep_out_um = argc > 7 ? std::atof(argv[7]) : spec.numerics.max_penetration_um / 4;
  auto keepOut = [&](RemeshParams& p, int other) {
    p.keep_out_um = keep_out_um;
    p.keep_out = [&two, other](const Vec3& x) {
      return windingNumber(two, other, x) > 0.5 ? distanceToSurface(two, other, x) : 0.0;
    };
  };
  // The run's remesh parameters (the keep-out's depth aside: a variant below).
  auto params = [&](double r) {
    RemeshParams rp = cellRemeshParams(spec.numerics, r);
    rp.keep_out_um = 0;
    return rp;
  };
  {
    const Deepest ab = deepestInside(a0, ra, b0, rb), ba = deepestInside(b0, rb, a0, ra);
    std::printf(
        "before: %d vertices / %d; deepest %d in %d: %.4f µm (v %d); %d in %d: %.4f µm "
        "(v %d)\n",
        a0.numVertices(), b0.numVertices(), ca, cb, ab.depth, ab.vertex, cb, ca, ba.depth,
        ba.vertex);
  }
  struct Variant {
    const char* name;
    std::function<void(RemeshParams&)> edit;
  };
  const std::vector<Variant> variants = {
      {"as run", [](RemeshParams&) {}},
      {"no rescue", [](RemeshParams& p) { p.rescue = false; }},
      {"no rebuild", [](RemeshParams& p) { p.rebuild_triangles = 0; }},
      {"no rescue, no rebuild",
       [](RemeshParams& p) {
         p.rescue = false;
         p.rebuild_triangles = 0;
       }},
      {"no smoothing", [](RemeshParams& p) { p.smooth_min_angle_deg = 0; }},
      {"no flips", [](RemeshParams& p) { p.flips = false; }},
      {"no collapses", [](RemeshParams& p) { p.min_area = 0; }},
      {"no splits", [](RemeshParams& p) { p.max_area = 0; }},
      {"no flip volume correction",
       [](RemeshParams& p) {
         p.flip_volume_correction = false;
         p.flip_max_volume = 1e-5;
       }},
  };
  for (std::size_t k = 0; k <= variants.size(); ++k) {
    const bool keep = k == variants.size();
    const Variant& var = keep ? variants[0] : variants[k];
    TriMesh a = a0, b = b0;
    RemeshParams pa = params(ra), pb = params(rb);
    var.edit(pa);
    var.edit(pb);
    if (keep) {
      keepOut(pa, 1);
      keepOut(pb, 0);
    }
    std::vector<int> mapa, mapb;
    const RemeshStats sa = remesh(a, pa, mapa), sb = remesh(b, pb, mapb);
    const Deepest ab = deepestInside(a, ra, b, rb), ba = deepestInside(b, rb, a, ra);
    // The deepest vertex's origin: the input vertices that became it.
    std::string from;
    for (std::size_t i = 0; i < mapa.size(); ++i)
      if (mapa[i] == ab.vertex) {
        const Vec3 p = a0.x.col(static_cast<int>(i));
        char buf[96];
        std::snprintf(buf, sizeof buf, " %zu (moved %.3f µm)", i, (a.x.col(ab.vertex) - p).norm());
        from += buf;
      }
    std::printf(
        "%-26s %d: s%d c%d f%d m%d rescue %d rebuild %d off %.2e kept out %d | %d: s%d c%d f%d m%d "
        "rescue %d rebuild %d off %.2e | %d in %d %.4f µm (v %d from%s) | %d in %d %.4f "
        "µm; smallest triangle %.3f of A_m\n",
        keep ? "keep out" : var.name, ca, sa.splits, sa.collapses, sa.flips, sa.smooths, sa.rescues,
        sa.rebuilds, sa.volume_offset, sa.kept_out, cb, sb.splits, sb.collapses, sb.flips,
        sb.smooths, sb.rescues, sb.rebuilds, sb.volume_offset, ca, cb, ab.depth, ab.vertex,
        from.empty() ? " a split" : from.c_str(), cb, ca, ba.depth, smallest(a) / pa.min_area);
  }
  return 0;
}
