// Remeshing cost per cell (docs/model.md §6.3: 200 cells every τ_r).
#include <cmath>
#include <random>

#include <benchmark/benchmark.h>

#include "activefoam/remesh.h"

using namespace activefoam;

namespace {

constexpr double kRadius = 8.88;

RemeshParams params() {
  const double a = 4.0 * M_PI * kRadius * kRadius / 320.0;
  RemeshParams p;
  p.min_area = a / 3.0;
  p.max_area = 3.0 * a;
  return p;
}

TriMesh sphere() {
  TriMesh m = icosphere(2);
  m.x *= kRadius;
  return m;
}

// Tangential noise (σ = amp µm), back onto the sphere: non-Delaunay edges, some small triangles.
TriMesh perturbed(double amp) {
  TriMesh m = sphere();
  std::mt19937 rng(7);
  std::normal_distribution<double> n01;
  for (int i = 0; i < m.numVertices(); ++i) {
    const Vec3 n = m.x.col(i).normalized();
    Vec3 d(n01(rng), n01(rng), n01(rng));
    d -= d.dot(n) * n;
    m.x.col(i) = kRadius * (m.x.col(i) + amp * d).normalized();
  }
  return m;
}

// 320-triangle icosphere: no operation needed (the common case).
void BM_RemeshNoOp(benchmark::State& state) {
  TriMesh m = sphere();
  const RemeshParams p = params();
  for (auto _ : state) {
    RemeshStats st = remesh(m, p);
    benchmark::DoNotOptimize(st);
  }
}
BENCHMARK(BM_RemeshNoOp);

// Copy of the mesh alone: the baseline to subtract from BM_RemeshPerturbed.
void BM_CopyMesh(benchmark::State& state) {
  const TriMesh src = perturbed(0.1 * state.range(0));
  for (auto _ : state) {
    TriMesh m = src;
    benchmark::DoNotOptimize(m.x.data());
  }
}
BENCHMARK(BM_CopyMesh)->Arg(5)->Arg(10);

// Perturbed icosphere (σ = 0.5 / 1.0 µm): flips, collapses, splits on a fresh copy each time.
void BM_RemeshPerturbed(benchmark::State& state) {
  const TriMesh src = perturbed(0.1 * state.range(0));
  const RemeshParams p = params();
  RemeshStats last;
  for (auto _ : state) {
    TriMesh m = src;
    last = remesh(m, p);
    benchmark::DoNotOptimize(last);
  }
  state.counters["splits"] = last.splits;
  state.counters["collapses"] = last.collapses;
  state.counters["flips"] = last.flips;
}
BENCHMARK(BM_RemeshPerturbed)->Arg(5)->Arg(10);

}  // namespace

BENCHMARK_MAIN();
