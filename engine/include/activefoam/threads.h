// Thread count of the engine's parallel kernels, and the helpers that keep their results
// bit-identical for any thread count (a promise of the spec, ARCHITECTURE.md: a run is a pure
// function of its spec).
//
// The rule every parallel kernel follows: a thread only writes slots that belong to the items it
// was given (a cell's vertices, a row of Γ, a contact pair's result), and every floating-point
// sum over items is taken in an order fixed by the data, never by the threads: per-item results
// are gathered serially or per owner in item order, and reductions are partial sums over chunks
// of Grain::reduce_chunk entries whose boundaries depend only on the length, added in chunk order.
#pragma once

#include <algorithm>
#include <cstdint>
#include <vector>

namespace activefoam {

// Sets the number of threads the engine's kernels use on the calling thread (OpenMP's
// nthreads-var is per thread: each foamd worker sets its own before it runs a job). n < 1 → 1.
void setThreads(int n);
// The number of threads a kernel started now on the calling thread would use.
int threads();

// How finely kernels split their work.
struct Grain {
  // Chunk length of deterministic reductions (CG dot products and norms). 4096 doubles (32 KiB)
  // cost far more than scheduling them, and the 2 × 100-cell scene (~10⁵ entries) still splits
  // into ~25 chunks. It is part of the arithmetic: another chunk length gives other bits.
  std::int64_t reduce_chunk = 4096;
  // Below this many items (vertices, triangles, pairs, vector entries) a kernel stays on the
  // calling thread. A team costs a few µs when the cores are free, but a whole scheduler slice
  // (ms) when another process holds one of them and a barrier waits for the descheduled thread:
  // a 2 × 8-cell fusion (5 000 triangles) on 2 threads of a loaded 2-core machine ran many
  // times slower than on one. 16 384 keeps scenes of ~50 cells and less on one thread.
  std::int64_t min_items = 16384;
};
Grain grain();
// For tests: a small grain makes a scene of a few cells take every parallel path with many
// chunks. Not for runs (reduce_chunk changes the bits); process-wide, not per thread.
void setGrain(const Grain& g);

// Σ_{k=0}^{n−1} f(k) as partial sums over chunks [j·C, (j+1)·C) (each summed in index order)
// added in chunk order: the same bits for any thread count, threaded or not. f(begin, end) sums
// one chunk.
template <class ChunkSum>
double deterministicSum(std::int64_t n, std::int64_t chunk, bool threaded,
                        const ChunkSum& chunk_sum) {
  if (n <= 0) return 0;
  const std::int64_t chunks = (n + chunk - 1) / chunk;
  if (chunks == 1) return chunk_sum(std::int64_t{0}, n);
  constexpr int kStack = 256;
  double stack[kStack];
  std::vector<double> heap;
  double* part = stack;
  if (chunks > kStack) {
    heap.resize(static_cast<std::size_t>(chunks));
    part = heap.data();
  }
#pragma omp parallel for schedule(static) if (threaded)
  for (std::int64_t j = 0; j < chunks; ++j)
    part[j] = chunk_sum(j * chunk, std::min(n, (j + 1) * chunk));
  double s = 0;
  for (std::int64_t j = 0; j < chunks; ++j) s += part[j];
  return s;
}

}  // namespace activefoam
