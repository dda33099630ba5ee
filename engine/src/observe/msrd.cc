// Neighbours over time (docs/model.md §8.6): the contacting cell pairs, the MSRD and its pooling
// over origins (by pair class too), the unique contacts, and the Kabsch rotation they share.
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <iterator>
#include <limits>
#include <stdexcept>

#include <Eigen/Dense>

#include "../integrate/bytes.h"
#include "activefoam/observables.h"

namespace activefoam {

namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

}  // namespace

std::vector<std::pair<int, int>> contactingCellPairs(const CellSet& cells,
                                                     const ContactList& contacts) {
  std::vector<std::pair<int, int>> out;
  out.reserve(contacts.pairs.size());
  for (const ContactPair& p : contacts.pairs) {
    const int a = cells.tri_cell[p.ta], b = cells.tri_cell[p.tb];
    if (a != b) out.emplace_back(std::min(a, b), std::max(a, b));
  }
  std::sort(out.begin(), out.end());
  out.erase(std::unique(out.begin(), out.end()), out.end());
  return out;
}

void MsrdTracker::addSample(double t_s, std::vector<Vec3> centroids,
                            std::vector<std::pair<int, int>> contact_pairs,
                            std::vector<int> labels) {
  if (!x_.empty() && centroids.size() != x_.front().size())
    throw std::invalid_argument("MsrdTracker: the number of cells changed");
  if (!labels.empty() && labels.size() != centroids.size())
    throw std::invalid_argument("MsrdTracker: labels, one per cell");
  if (!t_.empty() && !(t_s > t_.back()))
    throw std::invalid_argument("MsrdTracker: sample times must increase");
  const int nc = static_cast<int>(centroids.size());
  for (auto& [i, j] : contact_pairs) {
    if (i < 0 || j < 0 || i >= nc || j >= nc || i == j)
      throw std::invalid_argument("MsrdTracker: contact pair out of range");
    if (i > j) std::swap(i, j);
  }
  std::sort(contact_pairs.begin(), contact_pairs.end());
  contact_pairs.erase(std::unique(contact_pairs.begin(), contact_pairs.end()), contact_pairs.end());
  t_.push_back(t_s);
  x_.push_back(std::move(centroids));
  pairs_.push_back(std::move(contact_pairs));
  labels_.push_back(std::move(labels));
}

void MsrdTracker::addSample(double t_s, const CellSet& cells, const Geometry& geo,
                            const ContactList& contacts) {
  addSample(t_s, geo.cell_centroid, contactingCellPairs(cells, contacts));
}

double MsrdTracker::lagTime(int k) const {
  const int n = numSamples();
  return n < 2 ? 0.0 : k * (t_.back() - t_.front()) / (n - 1);
}

std::vector<int> MsrdTracker::origins() const {
  const int n = numSamples();
  const int stride = std::max(1, (n + max_origins_ - 1) / std::max(1, max_origins_));
  std::vector<int> o;
  for (int k = 0; k < n; k += stride) o.push_back(k);
  return o;
}

Eigen::Matrix3d bestRotation(const std::vector<Vec3>& p, const std::vector<Vec3>& q) {
  if (p.size() != q.size() || p.empty())
    throw std::invalid_argument("bestRotation: two equal, non-empty sets of points");
  const int n = static_cast<int>(p.size());
  Vec3 pm = Vec3::Zero(), qm = Vec3::Zero();
  for (int i = 0; i < n; ++i) {
    pm += p[i];
    qm += q[i];
  }
  pm /= n;
  qm /= n;
  Eigen::Matrix3d h = Eigen::Matrix3d::Zero();
  for (int i = 0; i < n; ++i) h += (p[i] - pm) * (q[i] - qm).transpose();
  const Eigen::JacobiSVD<Eigen::Matrix3d> svd(h, Eigen::ComputeFullU | Eigen::ComputeFullV);
  const Eigen::Matrix3d v = svd.matrixV(), u = svd.matrixU();
  const Vec3 s = svd.singularValues();
  if (s[0] == 0) return Eigen::Matrix3d::Identity();
  // Points on one line (two cells): every turn about the line fits as well, and the SVD's other
  // vectors are arbitrary (the 2 × 1 doublet read 180° every other sample). The smallest such
  // rotation carries the line's direction onto its new one.
  if (s[1] <= 1e-9 * s[0])
    return Eigen::Quaterniond::FromTwoVectors(u.col(0), v.col(0)).toRotationMatrix();
  Eigen::Matrix3d d = Eigen::Matrix3d::Identity();
  if ((v * u.transpose()).determinant() < 0) d(2, 2) = -1;
  return v * d * u.transpose();
}

double rotationAngle(const Eigen::Matrix3d& r) {
  return std::acos(std::clamp((r.trace() - 1.0) / 2.0, -1.0, 1.0));
}

MsrdTracker::LagSums MsrdTracker::lagSums(int lag, bool less_rotation, const ClassOf* class_of,
                                          std::vector<Pooled>* by_class) const {
  LagSums s;
  const int n = numSamples();
  if (lag < 0 || lag >= n) return s;
  for (int o : origins()) {
    if (o + lag >= n) break;
    if (pairs_[o].empty()) continue;
    const auto& x0 = x_[o];
    const auto& x1 = x_[o + lag];
    Eigen::Matrix3d rot = Eigen::Matrix3d::Identity();
    if (less_rotation) {
      rot = bestRotation(x0, x1);
      s.angle += rotationAngle(rot);
    }
    const std::vector<int>& label = labels_[o];
    if (by_class && label.empty())
      throw std::invalid_argument("MsrdTracker: sample " + std::to_string(o) + " has no labels");
    for (const auto& [i, j] : pairs_[o]) {
      const Vec3 d0 = x0[i] - x0[j];
      const double d2 = ((x1[i] - x1[j]) - (less_rotation ? Vec3(rot * d0) : d0)).squaredNorm();
      s.sum += d2;
      ++s.pairs;
      if (!by_class) continue;
      const int c = (*class_of)(label[i], label[j]);
      if (c < 0 || c >= static_cast<int>(by_class->size()))
        throw std::invalid_argument("MsrdTracker: pair class out of range");
      (*by_class)[c].sum += d2;
      ++(*by_class)[c].pairs;
    }
    ++s.origins;
  }
  return s;
}

double MsrdTracker::msrd(int lag) const {
  const LagSums s = lagSums(lag, false);
  return s.pairs ? s.sum / s.pairs : kNaN;
}

double MsrdTracker::msrdLessRotation(int lag) const {
  const LagSums s = lagSums(lag, true);
  return s.pairs ? s.sum / s.pairs : kNaN;
}

double MsrdTracker::turnDeg(int lag) const {
  const LagSums s = lagSums(lag, true);
  return s.origins ? s.angle / s.origins * 180.0 / M_PI : kNaN;
}

double MsrdTracker::Pooled::mean() const {
  return pairs ? sum / pairs : kNaN;
}

std::vector<MsrdTracker::Pooled> MsrdTracker::pooledByClass(int lag, int classes,
                                                            const ClassOf& class_of) const {
  std::vector<Pooled> out(static_cast<std::size_t>(std::max(classes, 0)));
  lagSums(lag, false, &class_of, &out);
  return out;
}

std::vector<double> MsrdTracker::msrdCurve() const {
  std::vector<double> c(t_.size());
  for (int k = 0; k < numSamples(); ++k) c[k] = msrd(k);
  return c;
}

MsrdTracker::Mixing MsrdTracker::mixingTime(double r_um) const {
  return mixingOf(r_um, false);
}

MsrdTracker::Mixing MsrdTracker::mixingTimeLessRotation(double r_um) const {
  return mixingOf(r_um, true);
}

MsrdTracker::Mixing MsrdTracker::mixingTime(double r_um, const std::vector<double>& curve) const {
  return mixingOn(r_um,
                  [&](int k) { return k < static_cast<int>(curve.size()) ? curve[k] : kNaN; });
}

MsrdTracker::Mixing MsrdTracker::mixingOf(double r_um, bool less_rotation) const {
  return mixingOn(r_um, [&](int k) { return less_rotation ? msrdLessRotation(k) : msrd(k); });
}

MsrdTracker::Mixing MsrdTracker::mixingOn(double r_um,
                                          const std::function<double(int)>& msrd_at) const {
  Mixing m;
  const int n = numSamples();
  m.time_s = lagTime(std::max(n - 1, 0));
  const double target = r_um * r_um;
  double prev = 0;
  for (int k = 1; k < n; ++k) {
    const double v = msrd_at(k);
    if (!std::isfinite(v)) continue;
    if (v >= target) {
      // Linear between lag k − 1 (MSRD prev < r²) and lag k.
      const double f = v > prev ? (target - prev) / (v - prev) : 1.0;
      m.time_s = lagTime(k - 1) + std::clamp(f, 0.0, 1.0) * (lagTime(k) - lagTime(k - 1));
      m.reached = true;
      return m;
    }
    prev = v;
  }
  return m;
}

void ContactHistory::add(const std::vector<std::pair<int, int>>& cell_pairs) {
  std::vector<std::pair<int, int>> p;
  p.reserve(cell_pairs.size());
  for (const auto& [i, j] : cell_pairs)
    if (i != j) p.emplace_back(std::min(i, j), std::max(i, j));
  std::sort(p.begin(), p.end());
  p.erase(std::unique(p.begin(), p.end()), p.end());
  if (initial_ < 0) initial_ = static_cast<int>(p.size());
  std::vector<std::pair<int, int>> merged;
  merged.reserve(seen_.size() + p.size());
  std::set_union(seen_.begin(), seen_.end(), p.begin(), p.end(), std::back_inserter(merged));
  seen_.swap(merged);
}

void ContactHistory::add(const CellSet& cells, const ContactList& contacts) {
  add(contactingCellPairs(cells, contacts));
}

double ContactHistory::normalized() const {
  return initial_ > 0 ? static_cast<double>(seen_.size()) / initial_ : kNaN;
}

std::string MsrdTracker::save() const {
  bytes::Writer w;
  w.pod<std::int32_t>(max_origins_);
  w.vec(t_);
  w.pod<std::uint64_t>(x_.size());
  for (std::size_t k = 0; k < x_.size(); ++k) {
    w.vec(x_[k]);
    w.vec(pairs_[k]);
  }
  // Labels only where some sample has them: a tracker without keeps the bytes it had before them.
  if (std::any_of(labels_.begin(), labels_.end(), [](const auto& l) { return !l.empty(); }))
    for (const auto& l : labels_) w.vec(l);
  return w.take();
}

void MsrdTracker::restore(const std::string& data) {
  bytes::Reader r(data, "msrd tracker");
  MsrdTracker m(r.pod<std::int32_t>());
  m.t_ = r.vec<double>();
  const auto n = r.pod<std::uint64_t>();
  if (n != m.t_.size()) throw std::invalid_argument("msrd tracker: inconsistent sample count");
  for (std::uint64_t k = 0; k < n; ++k) {
    m.x_.push_back(r.vec<Vec3>());
    m.pairs_.push_back(r.vec<std::pair<int, int>>());
  }
  const bool labelled = !r.done();
  for (std::uint64_t k = 0; k < n; ++k) {
    m.labels_.push_back(labelled ? r.vec<int>() : std::vector<int>());
    if (!m.labels_[k].empty() && m.labels_[k].size() != m.x_[k].size())
      throw std::invalid_argument("msrd tracker: labels of a sample, one per cell");
  }
  if (!r.done()) throw std::invalid_argument("msrd tracker: trailing bytes");
  *this = std::move(m);
}

std::string ContactHistory::save() const {
  bytes::Writer w;
  w.pod<std::int32_t>(initial_);
  w.vec(seen_);
  return w.take();
}

void ContactHistory::restore(const std::string& data) {
  bytes::Reader r(data, "contact history");
  const auto initial = r.pod<std::int32_t>();
  auto seen = r.vec<std::pair<int, int>>();
  if (!r.done()) throw std::invalid_argument("contact history: trailing bytes");
  initial_ = initial;
  seen_ = std::move(seen);
}

}  // namespace activefoam
