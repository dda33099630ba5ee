// Adaptive time step on fusions that die at a fixed step: 2 × 20-cell fusions at Δt = 0.5 s
// (320 triangles, contact-implicit, Table 1/2 defaults otherwise) for 1500 simulated seconds, over
// the supplement's study ranges p_a r/2γ ∈ {0, 0.33, 0.66} and L_η/r ∈ {0.25, 0.5, 1.0}, for
// several seeds. Each run reports whether it finished, its rejected tries, the shortest step it
// took, and the first rejection: where the same run without the adaptive step
// (numerics.adaptive = false) ends — up to that step the two runs are
// the same run (tests/engine/test_adaptive_step.cc).
//
// Run (about 2 CPU hours; shards split the rows between processes, e.g. 0/2 and 1/2 on the
// 2-core machine; prepared spheroids are shared through the cache):
//   OMP_NUM_THREADS=1 build/release/bench/study_adaptive_fusion OUT.csv CACHE_DIR
//       [seeds=1,2] [duration_s=1500] [shard=0/1] [cg_tol=1e-3]
// cg_tol: ε_CG of every run (1e-3 by default, where the fixed-step failures were seen; 1e-2 is
// the contact-implicit step at Δt 0.5 s of the studies: docs/study/adaptive-fusion.md has both).
// One CSV row per run, appended as each run ends (a rerun skips rows already in OUT.csv);
// bench/report_adaptive_fusion.py turns the CSVs into the table of docs/study/adaptive-fusion.md.
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include "activefoam/observables.h"
#include "activefoam/simulation.h"
#include "activefoam/spheroid.h"
#include "forked.h"

using namespace activefoam;

namespace {

struct Outcome {
  char failure[32] = "";
  char first_kind[32] = "";
  double t_end = 0, first_t = -1, dt_min = 0, wall = 0, theta_end = 0;
  long long steps = 0, rejected = 0;
};

Outcome runOne(const SceneSpec& s, const SpheroidCache& cache) {
  Outcome o;
  const CellSet cells = buildFusionCells(s, &cache, {});
  Simulation sim(s, cells);
  const auto t0 = std::chrono::steady_clock::now();
  const std::int64_t total = sim.stepper().ticksFor(s.duration_s);
  o.dt_min = s.numerics.dt_s;
  while (sim.stepper().ticks() < total) {
    const double t = sim.time();
    const StepReport r = sim.step();
    if (r.rejected > 0 && o.first_t < 0) {
      o.first_t = t;
      std::snprintf(o.first_kind, sizeof o.first_kind, "%s",
                    std::string(toString(r.rejected_kind)).c_str());
    }
    o.dt_min = std::min(o.dt_min, r.dt);
    if (!r.ok()) {
      std::snprintf(o.failure, sizeof o.failure, "%s", std::string(toString(r.failure)).c_str());
      break;
    }
  }
  o.wall = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  o.t_end = sim.time();
  o.steps = sim.steps();
  o.rejected = sim.stepsRejected();
  const FusionAngle fa = fusionAngle(sim.cells(), sim.contacts());
  o.theta_end = fa.ok ? fa.theta_deg : std::nan("");
  return o;
}

std::vector<long> parseList(const std::string& text) {
  std::vector<long> out;
  std::stringstream ss(text);
  for (std::string x; std::getline(ss, x, ',');) out.push_back(std::atol(x.c_str()));
  return out;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 3) {
    std::fprintf(stderr,
                 "usage: study_adaptive_fusion OUT.csv CACHE_DIR [seeds=1,2] [duration_s=1500] "
                 "[shard=0/1] [cg_tol=1e-3]\n");
    return 2;
  }
  const std::string out_path = argv[1];
  const SpheroidCache cache(argv[2]);
  const std::vector<long> seeds = parseList(argc > 3 ? argv[3] : "1,2");
  const double duration = argc > 4 ? std::atof(argv[4]) : 1500;
  int shard = 0, shards = 1;
  if (argc > 5 && std::sscanf(argv[5], "%d/%d", &shard, &shards) != 2) return 2;
  const double cg_tol = argc > 6 ? std::atof(argv[6]) : 1e-3;
  if (!(cg_tol > 0 && cg_tol < 1)) {
    std::fprintf(stderr, "cg_tol must be in (0, 1), got %s\n", argv[6]);
    return 2;
  }

  std::set<std::string> done;
  {
    std::ifstream in(out_path);
    std::string line;
    while (std::getline(in, line)) {
      std::stringstream ss(line);
      std::string a, b, c;
      std::getline(ss, a, ',');
      std::getline(ss, b, ',');
      std::getline(ss, c, ',');
      done.insert(a + "," + b + "," + c);
    }
  }
  FILE* out = std::fopen(out_path.c_str(), "a");
  if (!out) return 1;
  if (done.empty())
    std::fprintf(out,
                 "pa_reduced,l_eta_reduced,seed,outcome,t_end_s,steps,steps_rejected,dt_min_s,"
                 "first_rejection_t_s,first_rejection_kind,theta_end_deg,wall_s\n");
  int row = 0;
  for (double pa : {0.0, 0.33, 0.66})
    for (double leta : {0.25, 0.5, 1.0})
      for (long seed : seeds) {
        if (row++ % shards != shard) continue;
        char key[64];
        std::snprintf(key, sizeof key, "%g,%g,%ld", pa, leta, seed);
        if (done.count(key)) continue;
        SceneSpec s;
        s.scene = SceneKind::Fusion;
        s.seed = static_cast<std::uint64_t>(seed);
        s.scene_params.n_cells = 20;
        s.duration_s = duration;
        s.cells.pa_reduced = pa;
        s.cells.l_eta_reduced = leta;
        s.numerics.dt_s = 0.5;
        s.numerics.triangles_per_cell = 320;
        s.numerics.integrator = IntegratorKind::ContactImplicit;
        s.numerics.cg_tol = cg_tol;
        s = resolve(s);
        const auto o = bench::runForked([&] { return runOne(s, cache); });
        if (!o) {
          std::fprintf(out, "%s,crashed,,,,,,,,\n", key);
        } else {
          std::fprintf(out, "%s,%s,%.6g,%lld,%lld,%.6g,%.6g,%s,%.4g,%.1f\n", key,
                       o->failure[0] ? o->failure : "finished", o->t_end, o->steps, o->rejected,
                       o->dt_min, o->first_t, o->first_kind[0] ? o->first_kind : "none",
                       o->theta_end, o->wall);
        }
        std::fflush(out);
        std::fprintf(stderr, "%s done\n", key);
      }
  std::fclose(out);
  return 0;
}
