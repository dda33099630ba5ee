#include "activefoam/friction_operator.h"

namespace activefoam {

void FrictionOperator::reset(int num_vertices, std::uint64_t topology_version) {
  if (version_ != topology_version || diagonal_.numBlocks() != num_vertices) {
    // Diagonal blocks only: every coupling is a product, so neither remeshing nor contacts
    // coming and going change more than the number of blocks.
    diagonal_.setPattern(num_vertices, {});
    version_ = topology_version;
  } else {
    diagonal_.setZero();
  }
  for (Slot& s : slots_) s.active = false;
}

void FrictionOperator::apply(const double* v, double* y) const {
  diagonal_.multiply(v, y);
  for (const Slot& s : slots_)
    if (s.active) s.coupling->addProduct(v, y);
}

void FrictionOperator::forEachBlock(const BlockSink& sink) const {
  diagonal_.forEachLowerBlock(sink);
  for (const Slot& s : slots_)
    if (s.active) s.coupling->forEachBlock(sink);
}

SpMat FrictionOperator::assembled() const {
  std::vector<Eigen::Triplet<double>> entries;
  forEachBlock([&](int i, int j, const Eigen::Matrix3d& m) {
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 3; ++c) {
        entries.emplace_back(3 * i + r, 3 * j + c, m(r, c));
        if (i != j) entries.emplace_back(3 * j + c, 3 * i + r, m(r, c));
      }
  });
  const Eigen::Index n = 3 * static_cast<Eigen::Index>(numBlocks());
  SpMat a(n, n);
  a.setFromTriplets(entries.begin(), entries.end());
  return a;
}

}  // namespace activefoam
