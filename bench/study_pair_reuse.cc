// How much of the narrow phase could be reused between steps: on the 2 × N
// fusion, after each step, how far the six vertices of every active contact pair have moved
// relative to each other (their displacement minus the pair's mean displacement: what changes
// the pair's gap, overlap and normal) since the pair's geometry was last computed, and so which
// fraction of the pairs a reuse with a given skin would not recompute. A pair is recomputed when
// it is new (not active at the previous step, or a triangle of it remeshed: pairs are keyed by
// their six vertex ids) or has moved beyond the skin since its last computation; otherwise it
// would be reused. The contact range h0 is the scale: the force of a pair changes by k·δ per
// unit area when its gap changes by δ.
//
//   OMP_NUM_THREADS=1 build/release/bench/study_pair_reuse CACHE [steps] [n_cells] [prep_max_s]
//       [config] [warm_steps]
// config as study_fusion_cost's (default contact-implicit-consistent:0.5:block-jacobi:1e-2);
// warm_steps are run first and not counted (default 0: from the touching spheroids).
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <unordered_map>
#include <vector>

#include "activefoam/simulation.h"
#include "activefoam/spheroid.h"
#include "scheme_config.h"

using namespace activefoam;

namespace {

struct Key {
  std::array<int, 6> v;
  bool operator==(const Key& o) const { return v == o.v; }
};
struct KeyHash {
  std::size_t operator()(const Key& k) const {
    std::uint64_t h = 1469598103934665603ull;
    for (int x : k.v) h = (h ^ static_cast<std::uint64_t>(x)) * 1099511628211ull;
    return h;
  }
};

Key keyOf(const CellSet& cells, const ContactPair& p) {
  Key k;
  std::array<int, 3> a{cells.tri[p.ta][0], cells.tri[p.ta][1], cells.tri[p.ta][2]};
  std::array<int, 3> b{cells.tri[p.tb][0], cells.tri[p.tb][1], cells.tri[p.tb][2]};
  std::sort(a.begin(), a.end());
  std::sort(b.begin(), b.end());
  for (int i = 0; i < 3; ++i) k.v[i] = a[i], k.v[3 + i] = b[i];
  return k;
}

using Corners = std::array<Vec3, 6>;

// Largest displacement of the six corners relative to their mean displacement.
double relativeMove(const Corners& then, const Corners& now) {
  Vec3 mean = Vec3::Zero();
  for (int i = 0; i < 6; ++i) mean += now[i] - then[i];
  mean /= 6;
  double m = 0;
  for (int i = 0; i < 6; ++i) m = std::max(m, (now[i] - then[i] - mean).norm());
  return m;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 2) {
    std::fprintf(stderr,
                 "usage: study_pair_reuse CACHE_DIR [steps] [n_cells] [prep_max_s] [config] "
                 "[warm_steps]\n");
    return 2;
  }
  const SpheroidCache cache(argv[1]);
  const int steps = argc > 2 ? std::atoi(argv[2]) : 200;
  const int n = argc > 3 ? std::atoi(argv[3]) : 20;
  const double prep = argc > 4 ? std::atof(argv[4]) : 600;
  const std::string config =
      argc > 5 ? argv[5] : "contact-implicit-consistent:0.5:block-jacobi:1e-2";
  const int warm = argc > 6 ? std::atoi(argv[6]) : 0;
  SceneSpec s;
  bench::SchemeConfig scheme;
  if (const std::string error = bench::fusionSpec(config, n, prep, s, scheme); !error.empty()) {
    std::fprintf(stderr, "%s: %s\n", config.c_str(), error.c_str());
    return 2;
  }
  s = resolve(s);
  const CellSet cells0 = buildFusionCells(
      s, &cache, {[](const std::string& l) { std::fprintf(stderr, "%s\n", l.c_str()); }});
  Simulation sim(s, cells0, scheme.scheme(s));
  for (int k = 0; k < warm; ++k)
    if (!sim.step().ok()) {
      std::fprintf(stderr, "warm-up step %d failed\n", k);
      return 1;
    }
  const std::vector<double> skins = {0.001, 0.002, 0.005, 0.01, 0.02};
  std::vector<std::unordered_map<Key, Corners, KeyHash>> ref(skins.size());
  std::vector<double> reused(skins.size(), 0);
  double pairs_total = 0, new_total = 0;
  std::vector<double> moves;  // per pair and step: relative move since the previous step
  std::unordered_map<Key, Corners, KeyHash> last;
  const double h0 = contactRangeH0(s.cells);
  for (int step = 0; step < steps; ++step) {
    if (!sim.step().ok()) {
      std::fprintf(stderr, "step %d failed\n", step);
      break;
    }
    const CellSet& c = sim.cells();
    const ContactList& con = sim.contacts();
    std::unordered_map<Key, Corners, KeyHash> now;
    now.reserve(con.pairs.size());
    for (const ContactPair& p : con.pairs) {
      Corners x;
      for (int i = 0; i < 3; ++i) {
        x[i] = c.x.col(c.tri[p.ta][i]);
        x[3 + i] = c.x.col(c.tri[p.tb][i]);
      }
      // Corners in the key's (sorted) order, so that a pair's corners compare across steps.
      Key k = keyOf(c, p);
      Corners xs;
      for (int i = 0; i < 6; ++i) {
        const int v = k.v[i];
        const Tri& t = i < 3 ? c.tri[p.ta] : c.tri[p.tb];
        const int j = t[0] == v ? 0 : (t[1] == v ? 1 : 2);
        xs[i] = x[(i < 3 ? 0 : 3) + j];
      }
      now.emplace(k, xs);
    }
    pairs_total += static_cast<double>(now.size());
    for (const auto& [k, x] : now) {
      const auto it = last.find(k);
      if (it == last.end())
        new_total += 1;
      else
        moves.push_back(relativeMove(it->second, x));
    }
    for (std::size_t i = 0; i < skins.size(); ++i) {
      std::unordered_map<Key, Corners, KeyHash> next;
      next.reserve(now.size());
      for (const auto& [k, x] : now) {
        const auto it = ref[i].find(k);
        if (it != ref[i].end() && last.count(k) && relativeMove(it->second, x) < skins[i]) {
          reused[i] += 1;
          next.emplace(k, it->second);
        } else {
          next.emplace(k, x);
        }
      }
      ref[i] = std::move(next);
    }
    last = std::move(now);
  }
  std::sort(moves.begin(), moves.end());
  auto q = [&](double f) {
    return moves.empty() ? 0.0 : moves[static_cast<std::size_t>(f * (moves.size() - 1))];
  };
  std::printf(
      "# %s, 2 × %d cells, %d steps after %d warm-up steps (t = %.0f s at the end), "
      "h0 = %g µm\n",
      config.c_str(), n, steps, warm, sim.time(), h0);
  std::printf(
      "active pairs per step: %.0f; new each step (not active before, or remeshed): "
      "%.1f %%\n",
      steps ? pairs_total / steps : 0.0, pairs_total ? 100 * new_total / pairs_total : 0.0);
  std::printf(
      "relative move of a pair's corners in one step (µm): median %.2e, 90 %% %.2e, "
      "99 %% %.2e (median %.3f h0)\n",
      q(0.5), q(0.9), q(0.99), q(0.5) / h0);
  std::printf("| skin (µm) | skin / h0 | pairs a reuse would not recompute |\n|---|---|---|\n");
  for (std::size_t i = 0; i < skins.size(); ++i)
    std::printf("| %g | %.3f | %.1f %% |\n", skins[i], skins[i] / h0,
                pairs_total ? 100 * reused[i] / pairs_total : 0.0);
  return 0;
}
