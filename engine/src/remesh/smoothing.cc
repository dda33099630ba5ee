// The remesher's tangential smoothing (RemeshParams::smooth_min_angle_deg), and the volume
// restore of RemeshParams::on_surface.
#include <algorithm>
#include <cmath>
#include <vector>

#include "activefoam/remesh.h"
#include "remesher.h"

namespace activefoam::remesh_internal {

// Slivers and caps that the guards keep (a collapse or flip that would leave a vertex of
// valence 3, a flip across a crease) are fixed by moving their vertices instead: each vertex of
// a bad triangle moves half-way towards the mean of its neighbours, within its tangent plane,
// then along its volume gradient so that the enclosed volume is unchanged (the volume is affine
// in one vertex: exact). The move is kept only if no ring triangle turns by more than 60° and
// the ring's smallest angle grows.
double Remesher::minAngleCos(const Tri& f) const {  // cosine of the triangle's smallest angle
  double worst = -1;
  for (int k = 0; k < 3; ++k) {
    const Vec3 a = x_[f[(k + 1) % 3]] - x_[f[k]], b = x_[f[(k + 2) % 3]] - x_[f[k]];
    const double den = a.norm() * b.norm();
    worst = std::max(worst, den > 0 ? a.dot(b) / den : 1.0);
  }
  return worst;
}
bool Remesher::badTriangle(int t) const {
  const Tri& f = tri_[t];
  const double area = 0.5 * (x_[f[1]] - x_[f[0]]).cross(x_[f[2]] - x_[f[0]]).norm();
  return area < p_.min_area || minAngleCos(f) > std::cos(p_.smooth_min_angle_deg * M_PI / 180);
}
double Remesher::ringWorstCos(int q) const {
  double worst = -1;
  for (int r = incStart_[q]; r < incStart_[q + 1]; ++r)
    worst = std::max(worst, minAngleCos(tri_[inc_[r]]));
  return worst;
}

int Remesher::smoothSweep() {
  const int nt = static_cast<int>(tri_.size());
  cand_.clear();
  for (int t = 0; t < nt; ++t)
    if (badTriangle(t))
      for (int k : tri_[t]) cand_.push_back(k);
  if (cand_.empty()) return 0;
  std::sort(cand_.begin(), cand_.end());
  cand_.erase(std::unique(cand_.begin(), cand_.end()), cand_.end());
  buildIncidence();
  int n = 0;
  std::vector<Vec3> oldNormal;
  for (int q : cand_) {
    Vec3 mean = Vec3::Zero(), normal = Vec3::Zero(), grad = Vec3::Zero();
    int count = 0;
    oldNormal.clear();
    for (int r = incStart_[q]; r < incStart_[q + 1]; ++r) {
      const Tri& f = tri_[inc_[r]];
      int k = 0;
      while (f[k] != q) ++k;
      const Vec3 &xj = x_[f[(k + 1) % 3]], &xk = x_[f[(k + 2) % 3]];
      mean += xj;  // each neighbour once: j runs over the ring exactly once
      ++count;
      const Vec3 nrm = (xj - x_[q]).cross(xk - x_[q]);
      normal += nrm;
      oldNormal.push_back(nrm);
      grad += nrm / 6.0;
    }
    if (count < 3 || normal.norm() <= 0 || grad.squaredNorm() <= 0) continue;
    normal.normalize();
    Vec3 d = mean / count - x_[q];
    d -= normal.dot(d) * normal;
    d *= 0.5;
    if (p_.on_surface) {
      d = closestOnRing(q, x_[q] + d) - x_[q];
    } else {
      const double dv = d.dot(grad);  // volume change of the move (affine in x_q)
      d -= (dv / grad.squaredNorm()) * grad;
    }
    const double before = ringWorstCos(q);
    const Vec3 xold = x_[q];
    x_[q] = xold + d;
    bool ok = ringWorstCos(q) < before - 1e-9;
    for (int r = incStart_[q], m = 0; ok && r < incStart_[q + 1]; ++r, ++m) {
      const Tri& f = tri_[inc_[r]];
      int k = 0;
      while (f[k] != q) ++k;
      const Vec3 nrm = (x_[f[(k + 1) % 3]] - x_[q]).cross(x_[f[(k + 2) % 3]] - x_[q]);
      if (nrm.dot(oldNormal[m]) <= 0.5 * nrm.norm() * oldNormal[m].norm()) ok = false;
    }
    if (!ok) {
      x_[q] = xold;
      continue;
    }
    ++n;
  }
  st_.smooths += n;
  return n;
}

double Remesher::volume() const {
  double v = 0;
  for (const Tri& f : tri_) v += x_[f[0]].dot(x_[f[1]].cross(x_[f[2]]));
  return v / 6.0;
}

// The point of q's ring (its triangles as they are now) closest to p.
Vec3 Remesher::closestOnRing(int q, const Vec3& p) const {
  Vec3 best = x_[q];
  double d2 = (p - best).squaredNorm();
  for (int r = incStart_[q]; r < incStart_[q + 1]; ++r) {
    const Tri& f = tri_[inc_[r]];
    const Vec3 c = closestOnTriangle(p, x_[f[0]], x_[f[1]], x_[f[2]]);
    const double e2 = (p - c).squaredNorm();
    if (e2 < d2) d2 = e2, best = c;
  }
  return best;
}

// on_surface: restores the volume the remesh changed — smoothing's, as collapses and flips
// keep theirs locally (but for a collapse whose placement was ill-conditioned) — by moving
// every vertex the same distance h along its normal (the volume gradient's direction): V(h)
// is a cubic in h whose slope at 0 is Σ|∇_i V|, so Newton converges in two or three steps.
void Remesher::restoreVolume() {
  if (!p_.on_surface || st_.operations() == 0) return;
  std::vector<char> used(x_.size(), 0);
  for (const Tri& f : tri_)
    for (int k : f) used[k] = 1;
  std::vector<Vec3> dir(x_.size(), Vec3::Zero());
  double total = 0;
  for (int it = 0; it < 4; ++it) {
    const double dv = v0_ - volume();
    if (std::abs(dv) <= 1e-13 * std::abs(v0_)) break;
    std::fill(dir.begin(), dir.end(), Vec3::Zero());
    for (const Tri& f : tri_)
      for (int k = 0; k < 3; ++k)
        dir[f[k]] += (x_[f[(k + 1) % 3]] - x_[f[k]]).cross(x_[f[(k + 2) % 3]] - x_[f[k]]) / 6.0;
    double slope = 0;
    for (size_t i = 0; i < x_.size(); ++i)
      if (used[i]) slope += dir[i].norm();
    if (!(slope > 0)) break;
    const double h = dv / slope;
    for (size_t i = 0; i < x_.size(); ++i)
      if (used[i] && dir[i].squaredNorm() > 0) x_[i] += h * dir[i].normalized();
    total += h;
  }
  st_.volume_offset = total;
}

}  // namespace activefoam::remesh_internal
