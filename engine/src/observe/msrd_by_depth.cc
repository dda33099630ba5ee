// observe.msrd_by_depth's classification of the cells and its split of the MSRD (probe.h); the
// pooling over origins is MsrdTracker's.
#include <algorithm>
#include <stdexcept>

#include "activefoam/probe.h"

namespace activefoam {
namespace {

// A cell's label at a sample: whether it is buried (bit 0) and its depth, capped at 2 (above):
// what a pair's two classes are decided by.
int label(bool buried, int depth) {
  return (buried ? 1 : 0) | std::min(depth, 2) << 1;
}

// The nine classes of a pair, burial × layer, one pass over the origin–pairs for both splits.
int classOf(int a, int b) {
  const int burial = (a & 1) + (b & 1);  // Burial: the number of buried cells
  const int layer = std::min(a >> 1, b >> 1);
  return 3 * burial + layer;
}

}  // namespace

std::vector<double> freeFractions(const Geometry& geo, const ContactList& contacts) {
  const std::size_t n = geo.cell_area.size();
  std::vector<double> free(n, 1.0);
  if (contacts.cell_contact_area.size() != n) return free;
  for (std::size_t c = 0; c < n; ++c)
    if (geo.cell_area[c] > 0) free[c] = 1.0 - contacts.cell_contact_area[c] / geo.cell_area[c];
  return free;
}

std::vector<int> contactDepths(const std::vector<double>& free_fraction,
                               const std::vector<std::pair<int, int>>& pairs, double buried_below) {
  const int n = static_cast<int>(free_fraction.size());
  std::vector<std::vector<int>> nbr(n);
  for (const auto& [i, j] : pairs) {
    if (i < 0 || j < 0 || i >= n || j >= n)
      throw std::invalid_argument("contactDepths: contact pair out of range");
    nbr[i].push_back(j);
    nbr[j].push_back(i);
  }
  std::vector<int> depth(n, -1), front;
  for (int c = 0; c < n; ++c)
    if (!(free_fraction[c] < buried_below)) {
      depth[c] = 0;
      front.push_back(c);
    }
  int deepest = front.empty() ? -1 : 0;
  while (!front.empty()) {
    std::vector<int> next;
    for (int c : front)
      for (int o : nbr[c])
        if (depth[o] < 0) {
          depth[o] = depth[c] + 1;
          deepest = depth[o];
          next.push_back(o);
        }
    front.swap(next);
  }
  for (int& d : depth)
    if (d < 0) d = deepest + 1;
  return depth;
}

void MsrdByDepth::addSample(double t_s, std::vector<Vec3> centroids,
                            std::vector<std::pair<int, int>> pairs,
                            const std::vector<double>& free_fraction) {
  if (free_fraction.size() != centroids.size())
    throw std::invalid_argument("MsrdByDepth: free fractions, one per cell");
  const std::vector<int> depth = contactDepths(free_fraction, pairs, buried_below_);
  std::vector<int> labels(depth.size());
  for (std::size_t c = 0; c < depth.size(); ++c)
    labels[c] = label(free_fraction[c] < buried_below_, depth[c]);
  tracker_.addSample(t_s, std::move(centroids), std::move(pairs), std::move(labels));
}

MsrdByDepth::Split MsrdByDepth::pooled(int lag) const {
  const std::vector<MsrdTracker::Pooled> nine = tracker_.pooledByClass(lag, 9, classOf);
  Split s;
  for (int burial = 0; burial < 3; ++burial)
    for (int layer = 0; layer < 3; ++layer) {
      const MsrdTracker::Pooled& p = nine[3 * burial + layer];
      for (MsrdTracker::Pooled* into : {&s.burial[burial], &s.layer[layer]}) {
        into->sum += p.sum;
        into->pairs += p.pairs;
      }
    }
  return s;
}

void MsrdByDepth::restore(const std::string& bytes) {
  MsrdTracker t;
  t.restore(bytes);
  for (int k = 0; k < t.numSamples(); ++k) {
    const std::vector<int>& l = t.labels(k);
    if (l.empty() || std::any_of(l.begin(), l.end(), [](int x) { return x < 0 || x > 5; }))
      throw std::invalid_argument("msrd by depth: a sample without the cells' depths");
  }
  tracker_ = std::move(t);
}

}  // namespace activefoam
