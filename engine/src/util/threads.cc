#include "activefoam/threads.h"

#include <atomic>

#include <omp.h>

namespace activefoam {
namespace {
std::atomic<std::int64_t> g_reduce_chunk{Grain{}.reduce_chunk};
std::atomic<std::int64_t> g_min_items{Grain{}.min_items};
}  // namespace

void setThreads(int n) {
  omp_set_num_threads(n < 1 ? 1 : n);
}

int threads() {
  return omp_get_max_threads();
}

Grain grain() {
  return {g_reduce_chunk.load(std::memory_order_relaxed),
          g_min_items.load(std::memory_order_relaxed)};
}

void setGrain(const Grain& g) {
  g_reduce_chunk.store(g.reduce_chunk < 1 ? 1 : g.reduce_chunk, std::memory_order_relaxed);
  g_min_items.store(g.min_items < 0 ? 0 : g.min_items, std::memory_order_relaxed);
}

}  // namespace activefoam
