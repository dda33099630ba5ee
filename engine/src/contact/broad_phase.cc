// Broad phase of the triangle–triangle contact (DESIGN.md §4.6): candidate pairs of facing
// triangles of different cells whose margin-inflated bounding boxes overlap.
//
// findContactCandidates:
//   1. inflated triangle boxes and raw normals (shared with the brute-force oracle, so both use
//      bit-identical tests);
//   2. cell boxes (union of their triangles' inflated boxes) and the overlapping cell pairs
//      (sweep and prune along x);
//   3. a triangle is kept only if its box overlaps the box of a cell that touches its own cell;
//   4. kept triangles go into a uniform grid (hashed, counting-sorted), cell size ≈ the mean
//      inflated triangle box size; a pair is tested only in the grid cell holding the minimum
//      corner of the intersection of the two boxes, so each pair is found exactly once.
//      Triangles spanning many grid cells are tested against all kept triangles instead.
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <numeric>

#include <Eigen/Geometry>

#include "activefoam/contact_geometry.h"

namespace activefoam {
namespace {

struct Box {
  Vec3 lo, hi;
};

inline bool overlaps(const Box& p, const Box& q) {
  return p.lo.x() <= q.hi.x() && q.lo.x() <= p.hi.x() && p.lo.y() <= q.hi.y() &&
         q.lo.y() <= p.hi.y() && p.lo.z() <= q.hi.z() && q.lo.z() <= p.hi.z();
}

struct TriData {
  std::vector<Box> box;      // inflated by margin on every side
  std::vector<Vec3> normal;  // unnormalised (b−a)×(c−a); facing iff dot < 0
};

TriData triangleData(const Eigen::Matrix3Xd& x, const std::vector<Tri>& tri, double margin) {
  TriData d;
  d.box.resize(tri.size());
  d.normal.resize(tri.size());
  const Vec3 m = Vec3::Constant(margin);
  for (size_t t = 0; t < tri.size(); ++t) {
    const Vec3 p0 = x.col(tri[t][0]), p1 = x.col(tri[t][1]), p2 = x.col(tri[t][2]);
    d.box[t].lo = p0.cwiseMin(p1).cwiseMin(p2) - m;
    d.box[t].hi = p0.cwiseMax(p1).cwiseMax(p2) + m;
    d.normal[t] = (p1 - p0).cross(p2 - p0);
  }
  return d;
}

inline bool isCandidate(const TriData& d, const std::vector<int>& tri_cell, int s, int t) {
  return tri_cell[s] != tri_cell[t] && overlaps(d.box[s], d.box[t]) &&
         d.normal[s].dot(d.normal[t]) < 0;
}

inline std::uint64_t packPair(int s, int t) {
  if (s > t) std::swap(s, t);
  return (static_cast<std::uint64_t>(s) << 32) | static_cast<std::uint32_t>(t);
}

std::vector<std::pair<int, int>> unpackSorted(std::vector<std::uint64_t>& keys) {
  std::sort(keys.begin(), keys.end());
  keys.erase(std::unique(keys.begin(), keys.end()), keys.end());
  std::vector<std::pair<int, int>> out;
  out.reserve(keys.size());
  for (std::uint64_t k : keys)
    out.emplace_back(static_cast<int>(k >> 32), static_cast<int>(k & 0xffffffffu));
  return out;
}

}  // namespace

std::vector<std::pair<int, int>> findContactCandidatesBruteForce(const Eigen::Matrix3Xd& x,
                                                                 const std::vector<Tri>& tri,
                                                                 const std::vector<int>& tri_cell,
                                                                 double margin) {
  const TriData d = triangleData(x, tri, margin);
  const int T = static_cast<int>(tri.size());
  std::vector<std::pair<int, int>> out;
  for (int s = 0; s < T; ++s)
    for (int t = s + 1; t < T; ++t)
      if (isCandidate(d, tri_cell, s, t)) out.emplace_back(s, t);
  return out;
}

std::vector<std::pair<int, int>> findContactCandidates(const Eigen::Matrix3Xd& x,
                                                       const std::vector<Tri>& tri,
                                                       const std::vector<int>& tri_cell,
                                                       double margin) {
  const int T = static_cast<int>(tri.size());
  if (T < 2) return {};
  const TriData d = triangleData(x, tri, margin);

  // --- cells: dense ids, boxes, overlapping pairs ---------------------------------------------
  std::vector<int> ids(tri_cell.begin(), tri_cell.end());
  std::sort(ids.begin(), ids.end());
  ids.erase(std::unique(ids.begin(), ids.end()), ids.end());
  const int C = static_cast<int>(ids.size());
  if (C < 2) return {};
  std::vector<int> cell_of(T);
  for (int t = 0; t < T; ++t)
    cell_of[t] =
        static_cast<int>(std::lower_bound(ids.begin(), ids.end(), tri_cell[t]) - ids.begin());

  std::vector<Box> cell_box(C, Box{Vec3::Constant(INFINITY), Vec3::Constant(-INFINITY)});
  for (int t = 0; t < T; ++t) {
    Box& b = cell_box[cell_of[t]];
    b.lo = b.lo.cwiseMin(d.box[t].lo);
    b.hi = b.hi.cwiseMax(d.box[t].hi);
  }
  std::vector<std::vector<int>> neighbours(C);
  {
    std::vector<int> order(C);
    std::iota(order.begin(), order.end(), 0);
    std::sort(order.begin(), order.end(),
              [&](int p, int q) { return cell_box[p].lo.x() < cell_box[q].lo.x(); });
    for (int i = 0; i < C; ++i) {
      const Box& bi = cell_box[order[i]];
      for (int j = i + 1; j < C && cell_box[order[j]].lo.x() <= bi.hi.x(); ++j) {
        if (overlaps(bi, cell_box[order[j]])) {
          neighbours[order[i]].push_back(order[j]);
          neighbours[order[j]].push_back(order[i]);
        }
      }
    }
  }

  // --- triangles that can touch another cell at all -------------------------------------------
  std::vector<int> kept;
  kept.reserve(T);
  Box scene{Vec3::Constant(INFINITY), Vec3::Constant(-INFINITY)};
  double extent_sum = 0;
  for (int t = 0; t < T; ++t) {
    bool touches = false;
    for (int c : neighbours[cell_of[t]]) {
      if (overlaps(d.box[t], cell_box[c])) {
        touches = true;
        break;
      }
    }
    if (!touches) continue;
    kept.push_back(t);
    scene.lo = scene.lo.cwiseMin(d.box[t].lo);
    scene.hi = scene.hi.cwiseMax(d.box[t].hi);
    extent_sum += (d.box[t].hi - d.box[t].lo).maxCoeff();
  }
  if (kept.size() < 2) return {};

  // --- uniform grid ---------------------------------------------------------------------------
  const double scene_extent = (scene.hi - scene.lo).maxCoeff();
  if (!std::isfinite(scene_extent))
    return findContactCandidatesBruteForce(x, tri, tri_cell, margin);
  // At most 2^20 grid cells per axis (keys pack into 63 bits); never a zero cell size.
  double h = 3.0 * extent_sum / static_cast<double>(kept.size());
  h = std::max({h, scene_extent / double(1 << 20), 1e-300});
  const double inv_h = 1.0 / h;
  auto cellIndex = [&](double v, int axis) {
    const double c = std::floor((v - scene.lo[axis]) * inv_h);
    return static_cast<std::int64_t>(std::clamp(c, 0.0, double((1 << 21) - 1)));
  };
  auto key = [](std::int64_t i, std::int64_t j, std::int64_t k) {
    return static_cast<std::uint64_t>((i << 42) | (j << 21) | k);
  };

  // A triangle spanning more than kMaxSpan grid cells along an axis goes to the "large" list.
  constexpr std::int64_t kMaxSpan = 4;
  struct Entry {
    std::uint64_t key;
    int tri;
  };
  std::vector<Entry> entries;
  entries.reserve(kept.size() * 4);
  std::vector<int> large;
  std::vector<char> is_large(T, 0);
  for (int t : kept) {
    const Box& b = d.box[t];
    std::int64_t lo[3], hi[3];
    bool big = false;
    for (int a = 0; a < 3; ++a) {
      lo[a] = cellIndex(b.lo[a], a);
      hi[a] = cellIndex(b.hi[a], a);
      big = big || hi[a] - lo[a] + 1 > kMaxSpan;
    }
    if (big) {
      large.push_back(t);
      is_large[t] = 1;
      continue;
    }
    for (std::int64_t i = lo[0]; i <= hi[0]; ++i)
      for (std::int64_t j = lo[1]; j <= hi[1]; ++j)
        for (std::int64_t k = lo[2]; k <= hi[2]; ++k) entries.push_back({key(i, j, k), t});
  }

  // Counting sort of the entries into hash buckets.
  const size_t E = entries.size();
  size_t nbuckets = 1;
  while (nbuckets < 2 * E) nbuckets <<= 1;
  auto bucketOf = [&](std::uint64_t k) {
    k ^= k >> 33;
    k *= 0xff51afd7ed558ccdULL;
    k ^= k >> 33;
    return static_cast<size_t>(k & (nbuckets - 1));
  };
  std::vector<std::uint32_t> start(nbuckets + 1, 0);
  for (const Entry& e : entries) ++start[bucketOf(e.key) + 1];
  for (size_t i = 0; i < nbuckets; ++i) start[i + 1] += start[i];
  std::vector<Entry> sorted(E);
  {
    std::vector<std::uint32_t> fill(start.begin(), start.end() - 1);
    for (const Entry& e : entries) sorted[fill[bucketOf(e.key)]++] = e;
  }

  std::vector<std::uint64_t> found;
  found.reserve(kept.size() * 2);
  for (size_t bkt = 0; bkt < nbuckets; ++bkt) {
    for (std::uint32_t p = start[bkt]; p < start[bkt + 1]; ++p) {
      const Entry& ep = sorted[p];
      for (std::uint32_t q = p + 1; q < start[bkt + 1]; ++q) {
        const Entry& eq = sorted[q];
        if (ep.key != eq.key) continue;  // hash collision of two grid cells
        const int s = ep.tri, t = eq.tri;
        if (!isCandidate(d, tri_cell, s, t)) continue;
        // Report only in the grid cell of the intersection's minimum corner.
        const Box& bs = d.box[s];
        const Box& bt = d.box[t];
        const std::uint64_t owner = key(cellIndex(std::max(bs.lo.x(), bt.lo.x()), 0),
                                        cellIndex(std::max(bs.lo.y(), bt.lo.y()), 1),
                                        cellIndex(std::max(bs.lo.z(), bt.lo.z()), 2));
        if (owner == ep.key) found.push_back(packPair(s, t));
      }
    }
  }

  // Large triangles against every kept triangle (large–large pairs once).
  for (int s : large) {
    for (int t : kept) {
      if (t == s || (is_large[t] && t < s)) continue;
      if (isCandidate(d, tri_cell, s, t)) found.push_back(packPair(s, t));
    }
  }

  return unpackSorted(found);
}

}  // namespace activefoam
