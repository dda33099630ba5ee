// Step cost of the single-cell engine and its split by phase, for 1 cell and for 200 separate
// cells (no contacts) at 320 triangles per cell. Run: build/release/bench/bench_step
// Cells start as 1.3 ellipsoids so the solver works on a relaxing, not a resting, state.
#include <benchmark/benchmark.h>

#include "activefoam/simulation.h"

using namespace activefoam;

namespace {

SceneSpec benchSpec(int triangles) {
  SceneSpec s;
  s.scene = SceneKind::Cell;
  s.numerics.triangles_per_cell = triangles;
  s.cells.tau_k_s = 2 * tauShell(s.cells);
  s.numerics.remesh_every_s = 5 * tauShell(s.cells);
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
  sim.assembleFriction();  // the pattern is built once; steps only overwrite values
  for (auto _ : state) benchmark::DoNotOptimize(sim.assembleFriction().nonZeros());
}
BENCHMARK(BM_FrictionAssembly)->Arg(1)->Arg(200)->Unit(benchmark::kMicrosecond);

void BM_Remesh(benchmark::State& state) {
  Simulation sim(benchSpec(320), separateCells(static_cast<int>(state.range(0)), 320));
  for (auto _ : state) benchmark::DoNotOptimize(sim.remeshAll().remesh_ops);
}
BENCHMARK(BM_Remesh)->Arg(1)->Arg(200)->Unit(benchmark::kMicrosecond);

}  // namespace

BENCHMARK_MAIN();
