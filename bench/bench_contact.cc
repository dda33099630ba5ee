// Contact geometry kernels: narrow phase per facing pair (per quadrature) and the broad phase
// over a packed scene of icosphere cells (320 triangles each) in contact.
#include <cmath>
#include <map>
#include <random>

#include <benchmark/benchmark.h>
#include <Eigen/Geometry>

#include "activefoam/contact_geometry.h"
#include "activefoam/mesh.h"

namespace {

using activefoam::ContactLaw;
using activefoam::ContactLawKind;
using activefoam::ContactQuadrature;
using activefoam::Tri;
using activefoam::Vec3;
using Tri3 = std::array<Vec3, 3>;

// Facing pairs as they occur in a contact: near-parallel, gaps around the range h0.
std::vector<std::pair<Tri3, Tri3>> facingPairs(int n) {
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> u(-1, 1), ug(-0.03, 0.08), ut(-0.1, 0.1);
  std::normal_distribution<double> n01;
  auto flat = [&](bool ccw) {
    Tri3 t{Vec3(u(rng), u(rng), 0), Vec3(u(rng), u(rng), 0), Vec3(u(rng), u(rng), 0)};
    if (((t[1] - t[0]).cross(t[2] - t[0]).z() > 0) != ccw) std::swap(t[1], t[2]);
    return t;
  };
  std::vector<std::pair<Tri3, Tri3>> out;
  while (static_cast<int>(out.size()) < n) {
    Tri3 a = flat(true), b = flat(false);
    const Eigen::Matrix3d tilt =
        Eigen::AngleAxisd(ut(rng), Vec3(u(rng), u(rng), 0).normalized()).toRotationMatrix();
    const double gap = ug(rng);
    for (Vec3& p : b) p = tilt * p + Vec3(0, 0, gap);
    const Eigen::Matrix3d R =
        Eigen::Quaterniond(n01(rng), n01(rng), n01(rng), n01(rng)).normalized().toRotationMatrix();
    for (Vec3& p : a) p = R * p;
    for (Vec3& p : b) p = R * p;
    if (computeTriangleContact(a, b, ContactLaw{}, ContactQuadrature::Exact).active)
      out.emplace_back(a, b);
  }
  return out;
}

template <ContactQuadrature Q>
void BM_NarrowPhase(benchmark::State& state) {
  const auto pairs = facingPairs(4096);
  const ContactLaw law;
  size_t i = 0;
  for (auto _ : state) {
    const auto& [a, b] = pairs[i++ & 4095];
    benchmark::DoNotOptimize(computeTriangleContact(a, b, law, Q));
  }
  state.SetItemsProcessed(state.iterations());
}
BENCHMARK(BM_NarrowPhase<ContactQuadrature::Exact>);
BENCHMARK(BM_NarrowPhase<ContactQuadrature::Dunavant7>);

// The contact law's bounds on the same pairs (Exact): 0 the law, 1 within prisms (six more
// clips), 2 the overlapping part only within prisms (the polygon split at g = 0 first). The
// pairs are near-parallel, as in a junction: the prisms seldom cut them, so this is the clips'
// own cost.
void BM_NarrowPhaseLaw(benchmark::State& state) {
  const auto pairs = facingPairs(4096);
  ContactLaw law;
  law.kind = state.range(0) == 0   ? ContactLawKind::Supplement
             : state.range(0) == 1 ? ContactLawKind::Prisms
                                   : ContactLawKind::PrismsOverlap;
  size_t i = 0;
  for (auto _ : state) {
    const auto& [a, b] = pairs[i++ & 4095];
    benchmark::DoNotOptimize(computeTriangleContact(a, b, law, ContactQuadrature::Exact));
  }
  state.SetItemsProcessed(state.iterations());
}
BENCHMARK(BM_NarrowPhaseLaw)->Arg(0)->Arg(1)->Arg(2);
BENCHMARK(BM_NarrowPhase<ContactQuadrature::Centroid>);

// The engine's icosphere as plain vectors.
void icosphere(int levels, std::vector<Vec3>& x, std::vector<Tri>& tri) {
  const activefoam::TriMesh m = activefoam::icosphere(levels);
  x.clear();
  for (int i = 0; i < m.numVertices(); ++i) x.push_back(m.x.col(i));
  tri = m.tri;
}

// n_cells spheres of radius r = 8.88 µm (320 triangles) on the FCC sites nearest the origin,
// nearest-neighbour distance 1.9 r: neighbours overlap by 0.1 r, so every cell has flat-ish
// contact patches with its ~12 neighbours (a packed aggregate as seen by the broad phase).
struct PackedScene {
  Eigen::Matrix3Xd x;
  std::vector<Tri> tri;
  std::vector<int> tri_cell;
};

PackedScene packedScene(int n_cells) {
  const double r = 8.88, d = 1.95 * r, a = d * std::sqrt(2.0);  // FCC cube edge
  std::vector<Vec3> sites;
  for (int i = -6; i <= 6; ++i)
    for (int j = -6; j <= 6; ++j)
      for (int k = -6; k <= 6; ++k)
        for (const Vec3& o :
             {Vec3(0, 0, 0), Vec3(0.5, 0.5, 0), Vec3(0.5, 0, 0.5), Vec3(0, 0.5, 0.5)})
          sites.push_back(a * (Vec3(i, j, k) + o));
  std::sort(sites.begin(), sites.end(),
            [](const Vec3& p, const Vec3& q) { return p.squaredNorm() < q.squaredNorm(); });
  std::vector<Vec3> ux;
  std::vector<Tri> utri;
  icosphere(2, ux, utri);
  PackedScene s;
  const int nv = static_cast<int>(ux.size());
  s.x.resize(3, n_cells * nv);
  for (int c = 0; c < n_cells; ++c) {
    for (int v = 0; v < nv; ++v) s.x.col(c * nv + v) = sites[c] + r * ux[v];
    for (const Tri& f : utri) {
      s.tri.push_back({f[0] + c * nv, f[1] + c * nv, f[2] + c * nv});
      s.tri_cell.push_back(c);
    }
  }
  return s;
}

void BM_BroadPhasePacked(benchmark::State& state) {
  const PackedScene s = packedScene(static_cast<int>(state.range(0)));
  const double margin = 0.06;  // h0
  size_t pairs = 0;
  for (auto _ : state) {
    auto p = activefoam::findContactCandidates(s.x, s.tri, s.tri_cell, margin);
    pairs = p.size();
    benchmark::DoNotOptimize(p.data());
  }
  state.counters["triangles"] = static_cast<double>(s.tri.size());
  state.counters["pairs"] = static_cast<double>(pairs);
}
BENCHMARK(BM_BroadPhasePacked)->Arg(100)->Arg(200)->Unit(benchmark::kMillisecond);

// Narrow phase over every candidate of the packed scene (what one step costs).
void BM_NarrowPhaseAllCandidates(benchmark::State& state) {
  const PackedScene s = packedScene(static_cast<int>(state.range(0)));
  const auto pairs = activefoam::findContactCandidates(s.x, s.tri, s.tri_cell, 0.06);
  auto corners = [&](int t) {
    return Tri3{s.x.col(s.tri[t][0]), s.x.col(s.tri[t][1]), s.x.col(s.tri[t][2])};
  };
  size_t active = 0;
  for (auto _ : state) {
    active = 0;
    for (const auto& [p, q] : pairs)
      active +=
          computeTriangleContact(corners(p), corners(q), ContactLaw{}, ContactQuadrature::Exact)
              .active;
  }
  state.counters["pairs"] = static_cast<double>(pairs.size());
  state.counters["active"] = static_cast<double>(active);
}
BENCHMARK(BM_NarrowPhaseAllCandidates)->Arg(100)->Unit(benchmark::kMillisecond);

// The O(T²) oracle on a small scene, for scale.
void BM_BroadPhaseBruteForce(benchmark::State& state) {
  const PackedScene s = packedScene(static_cast<int>(state.range(0)));
  for (auto _ : state)
    benchmark::DoNotOptimize(
        activefoam::findContactCandidatesBruteForce(s.x, s.tri, s.tri_cell, 0.06).data());
}
BENCHMARK(BM_BroadPhaseBruteForce)->Arg(13)->Unit(benchmark::kMillisecond);

}  // namespace

BENCHMARK_MAIN();
