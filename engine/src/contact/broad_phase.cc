// Broad phase of the triangle–triangle contact (docs/model.md §3.2): candidate pairs of facing
// triangles of different cells whose margin-inflated bounding boxes overlap.
//
// findContactCandidates (O(T + candidates) for packed cells with a bounded number of neighbours):
//   1. inflated triangle boxes and raw normals (shared with the brute-force oracle, so both use
//      bit-identical tests);
//   2. cell boxes (union of their triangles' inflated boxes) and the cell pairs whose boxes
//      overlap (sweep and prune along x): cell pairs that cannot touch are skipped;
//   3. per overlapping cell pair, only the triangles of either cell whose boxes meet the
//      intersection of the two cell boxes, swept and pruned along the intersection's longest
//      axis. Each triangle pair belongs to exactly one cell pair, so it is tested once and never
//      against its own cell. Cell pairs run in parallel (OpenMP); each one's candidates are
//      sorted and joined in cell-pair order, so the result is identical for any thread count.
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <iterator>
#include <numeric>
#include <stdexcept>
#include <tuple>

#include <Eigen/Geometry>

#include "activefoam/contact_geometry.h"
#include "activefoam/contacts.h"
#include "activefoam/threads.h"

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

TriData triangleData(const Eigen::Matrix3Xd& x, const std::vector<Tri>& tri,
                     const std::vector<int>& tri_cell, double margin) {
  if (tri_cell.size() != tri.size())
    throw std::invalid_argument("findContactCandidates: tri_cell.size() != tri.size()");
  TriData d;
  d.box.resize(tri.size());
  d.normal.resize(tri.size());
  const Vec3 m = Vec3::Constant(margin);
  const auto T = static_cast<std::int64_t>(tri.size());
#pragma omp parallel for schedule(static) if (T > grain().min_items)
  for (std::int64_t t = 0; t < T; ++t) {
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

// `in` (first entries in [0, n_first)) sorted by (first, second) into `out`: counted by the
// first entry, then each short run by the second (std::sort of the Verlet lists cost ~3 % of a
// step of the 2 × 100 fusion, whose cells are re-swept often).
void sortLocalPairs(const std::vector<std::pair<int, int>>& in, int n_first,
                    std::vector<int>& count, std::vector<std::pair<int, int>>& out) {
  count.assign(static_cast<std::size_t>(n_first) + 1, 0);
  for (const auto& q : in) ++count[q.first + 1];
  for (int i = 0; i < n_first; ++i) count[i + 1] += count[i];
  out.resize(in.size());
  for (const auto& q : in) out[count[q.first]++] = q;
  for (std::size_t b = 0, e; b < out.size(); b = e) {
    for (e = b + 1; e < out.size() && out[e].first == out[b].first;) ++e;
    for (std::size_t i = b + 1; i < e; ++i)  // insertion sort: runs of a few pairs
      for (std::size_t j = i; j > b && out[j].second < out[j - 1].second; --j)
        std::swap(out[j], out[j - 1]);
  }
}

inline Box intersection(const Box& p, const Box& q) {
  return {p.lo.cwiseMax(q.lo), p.hi.cwiseMin(q.hi)};
}

// Pairs of cells whose boxes overlap (sweep and prune along x), each once as (lower index,
// higher index), sorted: the order of the candidates.
std::vector<std::pair<int, int>> overlappingCellPairs(const std::vector<Box>& cell_box) {
  const int C = static_cast<int>(cell_box.size());
  std::vector<std::pair<int, int>> cell_pairs;
  std::vector<int> order(C);
  std::iota(order.begin(), order.end(), 0);
  std::sort(order.begin(), order.end(),
            [&](int p, int q) { return cell_box[p].lo.x() < cell_box[q].lo.x(); });
  for (int i = 0; i < C; ++i) {
    const Box& bi = cell_box[order[i]];
    for (int j = i + 1; j < C && cell_box[order[j]].lo.x() <= bi.hi.x(); ++j)
      if (overlaps(bi, cell_box[order[j]]))
        cell_pairs.emplace_back(std::min(order[i], order[j]), std::max(order[i], order[j]));
  }
  std::sort(cell_pairs.begin(), cell_pairs.end());
  return cell_pairs;
}

struct Interval {
  double lo, hi;
  int tri;
  bool operator<(const Interval& o) const { return lo < o.lo; }
};

// The triangles of two cells whose boxes meet I, swept and pruned along I's longest axis:
// test(s, t) is called exactly once for every pair (s of the first cell, t of the second) whose
// intervals along that axis overlap.
template <class Test>
void sweepCellPair(const std::vector<Box>& box, const Box& I, const int* tris1, int n1,
                   const int* tris2, int n2, std::vector<Interval>& A, std::vector<Interval>& B,
                   Test&& test) {
  int axis;
  (I.hi - I.lo).maxCoeff(&axis);
  auto gather = [&](const int* tris, int n, std::vector<Interval>& out) {
    out.clear();
    for (int p = 0; p < n; ++p) {
      const int t = tris[p];
      if (overlaps(box[t], I)) out.push_back({box[t].lo[axis], box[t].hi[axis], t});
    }
    std::sort(out.begin(), out.end());
  };
  gather(tris1, n1, A);
  if (A.empty()) return;
  gather(tris2, n2, B);
  // Two-list sweep: every pair whose intervals overlap is visited exactly once, from the
  // member with the smaller lower end.
  size_t i = 0, j = 0;
  while (i < A.size() && j < B.size()) {
    if (A[i].lo <= B[j].lo) {
      for (size_t k = j; k < B.size() && B[k].lo <= A[i].hi; ++k) test(A[i].tri, B[k].tri);
      ++i;
    } else {
      for (size_t k = i; k < A.size() && A[k].lo <= B[j].hi; ++k) test(A[k].tri, B[j].tri);
      ++j;
    }
  }
}

}  // namespace

std::vector<std::pair<int, int>> findContactCandidatesBruteForce(const Eigen::Matrix3Xd& x,
                                                                 const std::vector<Tri>& tri,
                                                                 const std::vector<int>& tri_cell,
                                                                 double margin) {
  const TriData d = triangleData(x, tri, tri_cell, margin);
  const int T = static_cast<int>(tri.size());
  std::vector<std::pair<int, int>> out;
  for (int s = 0; s < T; ++s)
    for (int t = s + 1; t < T; ++t)
      if (isCandidate(d, tri_cell, s, t)) out.emplace_back(s, t);
  auto key = [&](const std::pair<int, int>& p) {
    const int c = tri_cell[p.first], e = tri_cell[p.second];
    return std::tuple(std::min(c, e), std::max(c, e), p.first, p.second);
  };
  std::stable_sort(out.begin(), out.end(),
                   [&](const auto& p, const auto& q) { return key(p) < key(q); });
  return out;
}

std::vector<std::pair<int, int>> findContactCandidates(const Eigen::Matrix3Xd& x,
                                                       const std::vector<Tri>& tri,
                                                       const std::vector<int>& tri_cell,
                                                       double margin) {
  const int T = static_cast<int>(tri.size());
  if (T < 2) return {};
  const TriData d = triangleData(x, tri, tri_cell, margin);

  // --- cells: dense indices, triangles grouped by cell, boxes ---------------------------------
  std::vector<int> cell_of(T);
  int C = 0;
  {
    const auto [mn, mx] = std::minmax_element(tri_cell.begin(), tri_cell.end());
    if (*mn >= 0 && *mx <= 4 * T) {  // the usual case: small non-negative ids, O(T)
      std::vector<int> dense(static_cast<size_t>(*mx) + 1, -1);
      for (int t = 0; t < T; ++t) dense[tri_cell[t]] = 0;
      for (int& v : dense)
        if (v == 0) v = C++;
      for (int t = 0; t < T; ++t) cell_of[t] = dense[tri_cell[t]];
    } else {
      std::vector<int> ids(tri_cell.begin(), tri_cell.end());
      std::sort(ids.begin(), ids.end());
      ids.erase(std::unique(ids.begin(), ids.end()), ids.end());
      C = static_cast<int>(ids.size());
      for (int t = 0; t < T; ++t)
        cell_of[t] =
            static_cast<int>(std::lower_bound(ids.begin(), ids.end(), tri_cell[t]) - ids.begin());
    }
  }
  if (C < 2) return {};
  std::vector<int> cell_start(C + 1, 0), cell_tris(T);
  for (int t = 0; t < T; ++t) ++cell_start[cell_of[t] + 1];
  for (int c = 0; c < C; ++c) cell_start[c + 1] += cell_start[c];
  {
    std::vector<int> fill(cell_start.begin(), cell_start.end() - 1);
    for (int t = 0; t < T; ++t) cell_tris[fill[cell_of[t]]++] = t;
  }
  std::vector<Box> cell_box(C, Box{Vec3::Constant(INFINITY), Vec3::Constant(-INFINITY)});
  for (int t = 0; t < T; ++t) {
    Box& b = cell_box[cell_of[t]];
    b.lo = b.lo.cwiseMin(d.box[t].lo);
    b.hi = b.hi.cwiseMax(d.box[t].hi);
  }

  const auto cell_pairs = overlappingCellPairs(cell_box);

  // Each cell pair's candidates sorted, then concatenated in cell-pair order: the result does not
  // depend on the thread count and schedule.
  const int n_cell_pairs = static_cast<int>(cell_pairs.size());
  std::vector<std::vector<std::uint64_t>> found(n_cell_pairs);
#pragma omp parallel if (T > grain().min_items)
  {
    std::vector<Interval> A, B;
#pragma omp for schedule(dynamic, 16)
    for (int cp = 0; cp < n_cell_pairs; ++cp) {
      const auto [c1, c2] = cell_pairs[cp];
      std::vector<std::uint64_t>& keys = found[cp];
      sweepCellPair(d.box, intersection(cell_box[c1], cell_box[c2]), &cell_tris[cell_start[c1]],
                    cell_start[c1 + 1] - cell_start[c1], &cell_tris[cell_start[c2]],
                    cell_start[c2 + 1] - cell_start[c2], A, B, [&](int s, int t) {
                      if (overlaps(d.box[s], d.box[t]) && d.normal[s].dot(d.normal[t]) < 0)
                        keys.push_back(packPair(s, t));
                    });
      std::sort(keys.begin(), keys.end());
    }
  }
  std::vector<std::pair<int, int>> out;
  for (const auto& keys : found)
    for (const std::uint64_t k : keys)
      out.emplace_back(static_cast<int>(k >> 32), static_cast<int>(k & 0xffffffffu));
  return out;
}

void CandidateCache::clear() {
  ref_.clear();
  lists_.clear();
  margin_ = -1;
}

std::vector<std::pair<int, int>> CandidateCache::find(const CellSet& cells, double margin) {
  const int C = cells.numCells(), T = cells.numTriangles();
  if (C < 2 || T < 2) return {};
  if (margin != margin_ || static_cast<int>(ref_.size()) != C) {
    clear();
    ref_.resize(C);
    margin_ = margin;
  }
  const bool topology_changed = cells.topology_version != topology_version_;
  topology_version_ = cells.topology_version;

  // --- cells that moved more than skin/2 from their reference, or whose mesh changed ----------
  std::vector<char> dirty(C, 0);
  bool any_dirty = false;
#pragma omp parallel for schedule(static) reduction(|| : any_dirty) if (T > grain().min_items)
  for (int c = 0; c < C; ++c) {
    CellRef& r = ref_[c];
    const int vb = cells.cell_vertex_begin[c], nv = cells.cell_vertex_begin[c + 1] - vb;
    const int tb = cells.cell_tri_begin[c], nt = cells.cell_tri_begin[c + 1] - tb;
    bool moved = !r.valid || r.x.cols() != nv || static_cast<int>(r.tri.size()) != nt;
    for (int i = 0; !moved && topology_changed && i < nt; ++i)
      for (int k = 0; k < 3; ++k)
        if (cells.tri[tb + i][k] - vb != r.tri[i][k]) moved = true;
    // Written so that a NaN position counts as moved.
    if (!moved) moved = !((cells.x.middleCols(vb, nv) - r.x).cwiseAbs().maxCoeff() <= 0.5 * skin_);
    if (moved) {
      r.valid = true;
      r.x = cells.x.middleCols(vb, nv);
      r.tri.resize(nt);
      for (int i = 0; i < nt; ++i)
        for (int k = 0; k < 3; ++k) r.tri[i][k] = cells.tri[tb + i][k] - vb;
      dirty[c] = 1;
      any_dirty = true;
    }
  }
  if (any_dirty) {
    for (int c = 0; c < C; ++c) stats_.cells_rebuilt += dirty[c];
    for (auto it = lists_.begin(); it != lists_.end();)
      it = dirty[it->first >> 32] || dirty[it->first & 0xffffffffu] ? lists_.erase(it)
                                                                    : std::next(it);
  }

  // --- current boxes, cell boxes, the pairs of cells that may touch now -----------------------
  const TriData d = triangleData(cells.x, cells.tri, cells.tri_cell, margin);
  std::vector<Box> cell_box(C, Box{Vec3::Constant(INFINITY), Vec3::Constant(-INFINITY)});
#pragma omp parallel for schedule(static) if (T > grain().min_items)
  for (int c = 0; c < C; ++c)
    for (int t = cells.cell_tri_begin[c]; t < cells.cell_tri_begin[c + 1]; ++t) {
      cell_box[c].lo = cell_box[c].lo.cwiseMin(d.box[t].lo);
      cell_box[c].hi = cell_box[c].hi.cwiseMax(d.box[t].hi);
    }
  const auto cell_pairs = overlappingCellPairs(cell_box);
  const int n_cell_pairs = static_cast<int>(cell_pairs.size());
  std::vector<std::vector<std::pair<int, int>>*> list(n_cell_pairs);
  std::vector<char> build(n_cell_pairs, 0);
  bool any_build = false;
  for (int cp = 0; cp < n_cell_pairs; ++cp) {
    const auto [c1, c2] = cell_pairs[cp];
    const auto [it, inserted] =
        lists_.try_emplace((static_cast<std::uint64_t>(c1) << 32) | static_cast<std::uint32_t>(c2));
    list[cp] = &it->second;  // element references survive rehashing
    build[cp] = inserted;
    any_build = any_build || inserted;
  }

  // New lists are swept with every box inflated by the skin as well.
  std::vector<Box> big;
  std::vector<int> identity;
  if (any_build) {
    big = d.box;
    for (Box& b : big) {
      b.lo.array() -= skin_;
      b.hi.array() += skin_;
    }
    identity.resize(T);
    std::iota(identity.begin(), identity.end(), 0);
  }

  std::int64_t built = 0;
  if (any_build) {
#pragma omp parallel reduction(+ : built) if (T > grain().min_items)
    {
      std::vector<Interval> A, B;
      std::vector<std::pair<int, int>> swept;
      std::vector<int> at;
#pragma omp for schedule(dynamic, 16)
      for (int cp = 0; cp < n_cell_pairs; ++cp) {
        if (!build[cp]) continue;
        ++built;
        const auto [c1, c2] = cell_pairs[cp];
        const int b1 = cells.cell_tri_begin[c1], n1 = cells.cell_tri_begin[c1 + 1] - b1;
        const int b2 = cells.cell_tri_begin[c2], n2 = cells.cell_tri_begin[c2 + 1] - b2;
        std::vector<std::pair<int, int>>& pairs = *list[cp];
        Box I = intersection(cell_box[c1], cell_box[c2]);
        I.lo.array() -= skin_;
        I.hi.array() += skin_;
        swept.clear();
        sweepCellPair(big, I, &identity[b1], n1, &identity[b2], n2, A, B, [&](int s, int t) {
          if (overlaps(big[s], big[t])) swept.emplace_back(s - b1, t - b2);
        });
        // Sorted once here, so that the filter below keeps the candidates' order.
        sortLocalPairs(swept, n1, at, pairs);
      }
    }
  }
  stats_.cell_pairs_built += built;
  stats_.cell_pairs_reused += n_cell_pairs - built;

  // The stored lists filtered in cell-pair order (c1 < c2, and cells' triangles are numbered in
  // cell order: s < t), each in (s, t) order: findContactCandidates' order. One range of cell
  // pairs per thread, cut at equal counts of stored pairs; the ranges are joined in order.
  std::vector<std::int64_t> stored(static_cast<std::size_t>(n_cell_pairs) + 1, 0);
  for (int cp = 0; cp < n_cell_pairs; ++cp)
    stored[cp + 1] = stored[cp] + static_cast<std::int64_t>(list[cp]->size());
  const int R = stored[n_cell_pairs] > grain().min_items ? threads() : 1;
  std::vector<int> cut(static_cast<std::size_t>(R) + 1, n_cell_pairs);
  for (int r = 0; r < R; ++r)
    cut[r] = static_cast<int>(
        std::lower_bound(stored.begin(), stored.end() - 1, stored[n_cell_pairs] * r / R) -
        stored.begin());
  std::vector<std::pair<int, int>> out;
  std::vector<std::vector<std::pair<int, int>>> rest(static_cast<std::size_t>(R));
  auto filter = [&](int r, std::vector<std::pair<int, int>>& found) {
    for (int cp = cut[r]; cp < cut[r + 1]; ++cp) {
      const int b1 = cells.cell_tri_begin[cell_pairs[cp].first];
      const int b2 = cells.cell_tri_begin[cell_pairs[cp].second];
      for (const auto& [ls, lt] : *list[cp]) {
        const int s = b1 + ls, t = b2 + lt;
        if (overlaps(d.box[s], d.box[t]) && d.normal[s].dot(d.normal[t]) < 0)
          found.emplace_back(s, t);
      }
    }
  };
  if (R == 1) {
    filter(0, out);
    return out;
  }
#pragma omp parallel for schedule(static, 1) num_threads(R)
  for (int r = 0; r < R; ++r) filter(r, r == 0 ? out : rest[r]);
  std::size_t total = out.size();
  for (int r = 1; r < R; ++r) total += rest[r].size();
  out.reserve(total);
  for (int r = 1; r < R; ++r) out.insert(out.end(), rest[r].begin(), rest[r].end());
  return out;
}

}  // namespace activefoam
