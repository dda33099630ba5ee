// Step cost of the single-cell engine and its split by phase, for 1 cell and for 200 separate
// cells (no contacts) at 320 triangles per cell; the packed aggregates' steps and kernels at 1
// and 2 threads; the contact kernels on the reference fusion when its spheroids are cached
// (ACTIVEFOAM_REFERENCE_CACHE). Run: build/release/bench/bench_step
// Cells start as 1.3 ellipsoids so the solver works on a relaxing, not a resting, state.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <map>
#include <memory>
#include <string>

#include <benchmark/benchmark.h>

#include "activefoam/simulation.h"
#include "activefoam/spheroid.h"
#include "activefoam/threads.h"

using namespace activefoam;

namespace {

SceneSpec benchSpec(int triangles) {
  SceneSpec s;
  s.scene = SceneKind::Cell;
  s.numerics.triangles_per_cell = triangles;
  s.cells.tau_k_s = defaultTauKS(s.cells);
  s.numerics.remesh_every_s = defaultRemeshEveryS(s.cells);
  return s;
}

// n cells on a cubic lattice 3r apart: separate, as in a dilute suspension.
CellSet separateCells(int n, int triangles) {
  CellSet cells;
  const double r = 8.88;
  const int side = static_cast<int>(std::ceil(std::cbrt(n)));
  for (int k = 0; k < n; ++k) {
    const Vec3 c(3 * r * (k % side), 3 * r * ((k / side) % side), 3 * r * (k / (side * side)));
    cells.addCell(ellipsoidCell(r, 1.3, triangles, c), r);
  }
  return cells;
}

void BM_Step(benchmark::State& state) {
  const int n = static_cast<int>(state.range(0));
  const int tris = static_cast<int>(state.range(1));
  Simulation sim(benchSpec(tris), separateCells(n, tris));
  double iters = 0;
  std::int64_t steps = 0;
  for (auto _ : state) {
    const StepReport r = sim.step();
    if (!r.ok()) state.SkipWithError(r.reason.c_str());
    iters += r.cg.iterations;
    ++steps;
  }
  const PhaseTimes& t = sim.phaseTimes();
  const double per = 1e3 / static_cast<double>(steps);  // ms per step
  state.counters["cg_iters"] = iters / steps;
  state.counters["forces_ms"] = t.forces * per;
  state.counters["matrix_ms"] = t.matrix * per;
  state.counters["solve_ms"] = t.solve * per;
  state.counters["geometry_ms"] = t.geometry * per;
  state.counters["remesh_ms"] = t.remesh * per;
  state.counters["vertices"] = sim.cells().numVertices();
}
BENCHMARK(BM_Step)->Args({1, 320})->Args({200, 320})->Unit(benchmark::kMillisecond)->MinTime(2.0);

// Kernels in isolation on a relaxing 200-cell state.
void BM_Forces(benchmark::State& state) {
  Simulation sim(benchSpec(320), separateCells(static_cast<int>(state.range(0)), 320));
  Eigen::Matrix3Xd f;
  for (auto _ : state) benchmark::DoNotOptimize(sim.computeForces(f));
}
BENCHMARK(BM_Forces)->Arg(1)->Arg(200)->Unit(benchmark::kMicrosecond);

void BM_FrictionAssembly(benchmark::State& state) {
  Simulation sim(benchSpec(320), separateCells(static_cast<int>(state.range(0)), 320));
  sim.prepareFriction();  // the pattern is built once; steps only overwrite values
  for (auto _ : state) {
    sim.prepareFriction();
    benchmark::DoNotOptimize(sim.frictionMatrix().matrix().nonZeros());
  }
}
BENCHMARK(BM_FrictionAssembly)->Arg(1)->Arg(200)->Unit(benchmark::kMicrosecond);

void BM_Remesh(benchmark::State& state) {
  Simulation sim(benchSpec(320), separateCells(static_cast<int>(state.range(0)), 320));
  for (auto _ : state) benchmark::DoNotOptimize(sim.remeshAll().remesh_ops);
}
BENCHMARK(BM_Remesh)->Arg(1)->Arg(200)->Unit(benchmark::kMicrosecond);

// A 100-cell aggregate packed at contact: cells on FCC sites inside a ball, neighbours 0.99·2r
// apart (slightly pressed together), relaxed 30 s with contacts before timing, so every cell has
// flattened contacts with its ~12 neighbours ("cells packed at contact").
CellSet packedAggregate(int n, int triangles) {
  const double r = 8.88, a = 0.99 * 2 * r * std::sqrt(2.0);  // FCC cube edge: neighbours a/√2
  std::vector<Vec3> sites;
  const Vec3 basis[4] = {{0, 0, 0}, {0.5, 0.5, 0}, {0.5, 0, 0.5}, {0, 0.5, 0.5}};
  for (int i = -4; i <= 4; ++i)
    for (int j = -4; j <= 4; ++j)
      for (int k = -4; k <= 4; ++k)
        for (const Vec3& b : basis) sites.push_back(a * (Vec3(i, j, k) + b));
  std::sort(sites.begin(), sites.end(), [](const Vec3& p, const Vec3& q) {
    return p.squaredNorm() < q.squaredNorm() ||
           (p.squaredNorm() == q.squaredNorm() &&
            std::lexicographical_compare(p.data(), p.data() + 3, q.data(), q.data() + 3));
  });
  CellSet cells;
  for (int c = 0; c < n; ++c) cells.addCell(ellipsoidCell(r, 1.0, triangles, sites[c]), r);
  return cells;
}

SceneSpec aggregateSpec(bool implicit) {
  SceneSpec spec = benchSpec(320);
  spec.scene = SceneKind::Doublet;  // any multi-cell scene: contacts on
  spec.numerics.integrator =
      implicit ? IntegratorKind::ContactImplicit : IntegratorKind::SemiImplicit;
  if (!implicit) spec.numerics.dt_s = 0.002;  // within the explicit scheme's limit
  return spec;
}

// The aggregate of n cells relaxed 30 s (once per process, then restored from its checkpoint
// for every thread count), or nullptr if it failed.
std::unique_ptr<Simulation> relaxedAggregate(int n, bool implicit, std::string* why) {
  static std::map<std::pair<int, bool>, std::string> states;
  const SceneSpec spec = aggregateSpec(implicit);
  auto sim = std::make_unique<Simulation>(spec, packedAggregate(n, 320));
  auto it = states.find({n, implicit});
  if (it == states.end()) {
    setThreads(2);
    const int warm = static_cast<int>(std::lround(30.0 / spec.numerics.dt_s));
    for (int k = 0; k < warm; ++k)
      if (const StepReport r = sim->step(); !r.ok()) {
        *why = r.reason;
        return nullptr;
      }
    it = states.emplace(std::make_pair(n, implicit), sim->saveState()).first;
    sim = std::make_unique<Simulation>(spec, packedAggregate(n, 320));
  }
  if (std::string e = sim->loadState(it->second); !e.empty()) {
    *why = e;
    return nullptr;
  }
  return sim;
}

// Arguments: cells, contact-implicit (1) or semi-implicit (0), threads.
void BM_StepAggregate(benchmark::State& state) {
  const int n = static_cast<int>(state.range(0));
  std::string why;
  auto sim = relaxedAggregate(n, state.range(1) != 0, &why);
  if (!sim) {
    state.SkipWithError(why.c_str());
    return;
  }
  setThreads(static_cast<int>(state.range(2)));
  const PhaseTimes t0 = sim->phaseTimes();
  double iters = 0, pairs = 0;
  std::int64_t steps = 0;
  for (auto _ : state) {
    const StepReport r = sim->step();
    if (!r.ok()) state.SkipWithError(r.reason.c_str());
    iters += r.cg.iterations;
    pairs += r.contacts;
    ++steps;
  }
  const PhaseTimes& t = sim->phaseTimes();
  const double per = 1e3 / static_cast<double>(steps);
  const double contacts_ms = (t.contacts - t0.contacts) * per;
  const double total_ms =
      (t.geometry + t.contacts + t.forces + t.matrix + t.solve + t.remesh - t0.geometry -
       t0.contacts - t0.forces - t0.matrix - t0.solve - t0.remesh) *
      per;
  state.counters["cg_iters"] = iters / steps;
  state.counters["pairs"] = pairs / steps;
  state.counters["contacts_ms"] = contacts_ms;
  state.counters["ns_per_pair"] = 1e6 * contacts_ms / (pairs / steps);
  state.counters["contact_share"] = contacts_ms / total_ms;
  state.counters["forces_ms"] = (t.forces - t0.forces) * per;
  state.counters["matrix_ms"] = (t.matrix - t0.matrix) * per;
  state.counters["solve_ms"] = (t.solve - t0.solve) * per;
  state.counters["geometry_ms"] = (t.geometry - t0.geometry) * per;
  state.counters["remesh_ms"] = (t.remesh - t0.remesh) * per;
}
BENCHMARK(BM_StepAggregate)
    ->ArgsProduct({{100, 200}, {1}, {1, 2}})
    ->Unit(benchmark::kMillisecond)
    ->Iterations(50);

// The timed bodies of the contact kernels, shared by the aggregate and the reference scene.
void timeCouplingProduct(benchmark::State& state, Simulation& sim) {  // y = Γ v
  sim.prepareFriction();
  const Eigen::Index m = 3 * static_cast<Eigen::Index>(sim.cells().numVertices());
  Eigen::VectorXd v = Eigen::VectorXd::Ones(m), y(m);
  for (auto _ : state) {
    sim.applyFriction(v.data(), y.data());
    benchmark::DoNotOptimize(y.data());
  }
  state.counters["pairs"] = static_cast<double>(sim.contacts().pairs.size());
}

void timeDetection(benchmark::State& state, const Simulation& sim) {
  const SceneSpec& spec = sim.spec();
  const ContactLaw law{spec.cells.k_contact, contactRangeH0(spec.cells)};
  CandidateCache cache(0.4);
  ContactList out;
  detectContacts(sim.cells(), sim.geometry(), law, spec.numerics.contact_quadrature, out,
                 &cache);  // builds the lists: the loop times the per-step filter + narrow phase
  for (auto _ : state) {
    detectContacts(sim.cells(), sim.geometry(), law, spec.numerics.contact_quadrature, out, &cache);
    benchmark::DoNotOptimize(out.pairs.data());
  }
  state.counters["pairs"] = static_cast<double>(out.pairs.size());
}

// Kernels of one step on the relaxed aggregate, at 1 and 2 threads. Arguments: cells, threads.
void BM_CouplingProduct(benchmark::State& state) {  // block product + contact product
  std::string why;
  auto sim = relaxedAggregate(static_cast<int>(state.range(0)), true, &why);
  if (!sim) return state.SkipWithError(why.c_str());
  setThreads(static_cast<int>(state.range(1)));
  timeCouplingProduct(state, *sim);
}
BENCHMARK(BM_CouplingProduct)
    ->ArgsProduct({{100, 200}, {1, 2}})
    ->Unit(benchmark::kMicrosecond)
    ->MinTime(1.0);

void BM_NarrowPhase(benchmark::State& state) {  // detectContacts on a fresh candidate list
  std::string why;
  auto sim = relaxedAggregate(static_cast<int>(state.range(0)), true, &why);
  if (!sim) return state.SkipWithError(why.c_str());
  setThreads(static_cast<int>(state.range(1)));
  timeDetection(state, *sim);
}
BENCHMARK(BM_NarrowPhase)->ArgsProduct({{100, 200}, {1, 2}})->Unit(benchmark::kMillisecond);

// The reference fusion's touching 2 × 100-cell spheroids (bench/specs/fusion_reference.toml) at
// Δt 0.5 s, from the spheroid cache named by $ACTIVEFOAM_REFERENCE_CACHE (a foam-run of that spec
// with --spheroid-cache DIR fills it, ~15 min): ~129 000 contact pairs, whose data outgrow the
// CPU's caches. The aggregates above (≤ 41 600 pairs) did not show a 2× regression of the
// contact product that this scene did (docs/benchmarks.md). Skipped without the cache.
std::unique_ptr<Simulation> referenceFusion(std::string* why) {
  const char* dir = std::getenv("ACTIVEFOAM_REFERENCE_CACHE");
  if (!dir || !*dir) {
    *why =
        "set ACTIVEFOAM_REFERENCE_CACHE to the spheroid cache of bench/specs/fusion_reference.toml";
    return nullptr;
  }
  SceneSpec s;
  s.scene = SceneKind::Fusion;
  s.seed = 1;
  s.scene_params.n_cells = 100;
  s.scene_params.prep_max_s = 600;  // as in bench/specs/fusion_reference.toml
  s.numerics.triangles_per_cell = 320;
  s = resolve(s);
  if (const auto error = setField(s, "numerics.dt_s", SpecValue(0.5))) {
    *why = error->str();
    return nullptr;
  }
  const SpheroidCache cache(dir);
  for (int which : {0, 1})
    if (!cache.load(spheroidPrepSpec(s, s.scene_params.n_cells, spheroidSeed(s.seed, which)))) {
      *why = std::string("the reference spheroids are not in ") + dir +
             " (foam-run bench/specs/fusion_reference.toml --spheroid-cache DIR prepares them)";
      return nullptr;
    }
  return std::make_unique<Simulation>(s, buildFusionCells(s, &cache));
}

void BM_CouplingProductReference(benchmark::State& state) {  // Γ v; argument: threads
  std::string why;
  auto sim = referenceFusion(&why);
  if (!sim) return state.SkipWithError(why.c_str());
  setThreads(static_cast<int>(state.range(0)));
  timeCouplingProduct(state, *sim);
}
BENCHMARK(BM_CouplingProductReference)->Arg(1)->Arg(2)->Unit(benchmark::kMillisecond)->MinTime(1.0);

void BM_NarrowPhaseReference(benchmark::State& state) {  // one detection; argument: threads
  std::string why;
  auto sim = referenceFusion(&why);
  if (!sim) return state.SkipWithError(why.c_str());
  setThreads(static_cast<int>(state.range(0)));
  timeDetection(state, *sim);
}
BENCHMARK(BM_NarrowPhaseReference)->Arg(1)->Arg(2)->Unit(benchmark::kMillisecond);

// One step's incomplete-Cholesky factor of Γ (prepareFriction first), as VelocitySolver::solve
// builds it.
bool factorFriction(const Simulation& sim, IncompleteCholesky& ic) {
  return ic.factor(
      sim.cells().numVertices(), [&](const BlockSink& s) { sim.forEachFrictionBlock(s); },
      sim.cells().cell_vertex_begin);
}

// One step's solve from a cold start; with incomplete Cholesky the factorisation is included.
void coldSolve(benchmark::State& state, PreconditionerKind pre) {
  std::string why;
  auto sim = relaxedAggregate(static_cast<int>(state.range(0)), true, &why);
  if (!sim) return state.SkipWithError(why.c_str());
  setThreads(static_cast<int>(state.range(1)));
  Eigen::Matrix3Xd f;
  sim->computeForces(f);
  sim->prepareFriction();
  const SceneSpec& spec = sim->spec();
  LinearSolver solver(pre, spec.numerics.cg_tol, static_cast<int>(spec.numerics.cg_max_iter));
  const Eigen::Index m = 3 * static_cast<Eigen::Index>(sim->cells().numVertices());
  const Eigen::VectorXd b = Eigen::Map<const Eigen::VectorXd>(f.data(), m);
  Eigen::VectorXd v;
  IncompleteCholesky ic;
  const bool factored = pre == PreconditionerKind::IncompleteCholesky;
  int iters = 0;
  for (auto _ : state) {
    v = Eigen::VectorXd::Zero(m);
    if (factored && !factorFriction(*sim, ic)) return state.SkipWithError("factor failed");
    iters = solver
                .solve([&](const double* in, double* out) { sim->applyFriction(in, out); },
                       sim->frictionMatrix(), b, v, factored ? &ic : nullptr)
                .iterations;
    benchmark::DoNotOptimize(v.data());
  }
  state.counters["cg_iters"] = iters;
}

void BM_ConjugateGradient(benchmark::State& state) {  // Jacobi
  coldSolve(state, PreconditionerKind::Jacobi);
}
BENCHMARK(BM_ConjugateGradient)->ArgsProduct({{100, 200}, {1, 2}})->Unit(benchmark::kMillisecond);

// The incomplete-Cholesky preconditioner on the relaxed aggregate's Γ (cells + contact
// couplings): its factorisation (a step pays it once, ros2 too) and one application (once per CG
// iteration), and the CG solve it gives from a cold start against BM_ConjugateGradient's Jacobi.
// Arguments: cells; threads (the cells of one colour run in parallel), 1 if absent.
std::unique_ptr<Simulation> preparedAggregate(benchmark::State& state) {
  std::string why;
  auto sim = relaxedAggregate(static_cast<int>(state.range(0)), true, &why);
  if (!sim) {
    state.SkipWithError(why.c_str());
    return nullptr;
  }
  setThreads(static_cast<int>(state.range(1)));
  sim->prepareFriction();
  return sim;
}

void BM_IncompleteCholeskyFactor(benchmark::State& state) {
  auto sim = preparedAggregate(state);
  if (!sim) return;
  IncompleteCholesky ic;
  for (auto _ : state) {
    if (!factorFriction(*sim, ic)) state.SkipWithError("factor failed");
  }
  state.counters["blocks"] = static_cast<double>(ic.numStoredBlocks());
  state.counters["shift"] = ic.shift();
  state.counters["colours"] = ic.numColours();
}
BENCHMARK(BM_IncompleteCholeskyFactor)
    ->ArgsProduct({{100, 200}, {1, 2}})
    ->Unit(benchmark::kMillisecond);

// The factor's input alone: Γ's blocks as the step emits them (cells' assembled blocks and the
// contact couplings), counted and discarded — the share of BM_IncompleteCholeskyFactor that is
// not the factorisation (and runs on one thread: a callback in emission order).
void BM_FrictionBlocks(benchmark::State& state) {
  auto sim = preparedAggregate(state);
  if (!sim) return;
  long count = 0;
  for (auto _ : state) {
    count = 0;
    sim->forEachFrictionBlock([&](int, int, const Eigen::Matrix3d& m) {
      benchmark::DoNotOptimize(m.data());
      ++count;
    });
  }
  state.counters["blocks"] = static_cast<double>(count);
}
BENCHMARK(BM_FrictionBlocks)->Args({100, 1})->Args({200, 1})->Unit(benchmark::kMillisecond);

void BM_IncompleteCholeskyApply(benchmark::State& state) {
  auto sim = preparedAggregate(state);
  if (!sim) return;
  IncompleteCholesky ic;
  if (!factorFriction(*sim, ic)) return state.SkipWithError("factor failed");
  const Eigen::Index m = 3 * static_cast<Eigen::Index>(sim->cells().numVertices());
  Eigen::VectorXd r(m), z(m);
  for (Eigen::Index i = 0; i < m; ++i) r[i] = std::sin(0.37 * static_cast<double>(i));
  for (auto _ : state) {
    ic.apply(r.data(), z.data());
    benchmark::DoNotOptimize(z.data());
  }
}
BENCHMARK(BM_IncompleteCholeskyApply)
    ->ArgsProduct({{100, 200}, {1, 2}})
    ->Unit(benchmark::kMicrosecond);

void BM_ConjugateGradientIncompleteCholesky(benchmark::State& state) {  // factor + solve, cold
  coldSolve(state, PreconditionerKind::IncompleteCholesky);
}
BENCHMARK(BM_ConjugateGradientIncompleteCholesky)
    ->ArgsProduct({{100, 200}, {1, 2}})
    ->Unit(benchmark::kMillisecond);

// The broad phase along a recorded trajectory of the 100-cell aggregate above (motile cells,
// contact-implicit, remeshing as the scene needs): from scratch every step (skin < 0) against the
// Verlet lists of CandidateCache with the given skin. Arguments: skin in nm (−1: from scratch),
// Δt in ms. The lists start empty each iteration, so their first build is counted.
struct Trajectory {
  std::vector<CellSet> states;
  double margin = 0;
};

const Trajectory& recordedTrajectory(int dt_ms) {
  static std::map<int, Trajectory> cache;
  auto [it, fresh] = cache.try_emplace(dt_ms);
  if (!fresh) return it->second;
  SceneSpec spec = benchSpec(320);
  spec.scene = SceneKind::Doublet;
  spec.numerics.integrator = IntegratorKind::ContactImplicit;
  spec.numerics.dt_s = dt_ms / 1000.0;
  Simulation sim(spec, packedAggregate(100, 320));
  const int warm = static_cast<int>(std::lround(30.0 / spec.numerics.dt_s));
  for (int k = 0; k < warm + 60; ++k) {
    if (!sim.step().ok()) break;
    if (k >= warm) it->second.states.push_back(sim.cells());
  }
  it->second.margin = contactRangeH0(spec.cells);
  return it->second;
}

void BM_BroadPhaseReplay(benchmark::State& state) {
  const double skin = state.range(0) / 1000.0;
  const Trajectory& tr = recordedTrajectory(static_cast<int>(state.range(1)));
  if (tr.states.size() < 60) {
    state.SkipWithError("the aggregate failed while recording");
    return;
  }
  double candidates = 0, seconds = 0;
  CandidateCache::Stats st;
  for (auto _ : state) {
    const auto t0 = std::chrono::steady_clock::now();
    CandidateCache cache(std::max(skin, 0.0));
    for (const CellSet& c : tr.states) {
      const auto found = skin < 0 ? findContactCandidates(c.x, c.tri, c.tri_cell, tr.margin)
                                  : cache.find(c, tr.margin);
      candidates += static_cast<double>(found.size());
      benchmark::DoNotOptimize(found.data());
    }
    st = cache.stats();
    seconds += std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  }
  const double steps = static_cast<double>(state.iterations()) * tr.states.size();
  state.counters["ms_per_step"] = 1e3 * seconds / steps;
  state.counters["candidates"] = candidates / steps;
  if (skin >= 0) {
    const double n = static_cast<double>(tr.states.size());
    state.counters["cells_rebuilt_per_step"] = st.cells_rebuilt / n;
    state.counters["pairs_swept_share"] =
        static_cast<double>(st.cell_pairs_built) / (st.cell_pairs_built + st.cell_pairs_reused);
  }
}
BENCHMARK(BM_BroadPhaseReplay)
    ->ArgsProduct({{-1, 0, 50, 100, 200, 400, 800}, {100, 500}})
    ->Unit(benchmark::kMillisecond)
    ->MinTime(1.0);

}  // namespace

BENCHMARK_MAIN();
