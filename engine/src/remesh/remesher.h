// The remesher of one cell surface (engine-internal), as remesh() runs it: its passes (split,
// collapse, flip) in remesh.cc, its tangential smoothing and the volume restore of on_surface in
// smoothing.cc, its repairs (the rescue, the keep-out of collapses and the rebuild) in repair.cc.
//
// Each sweep works on a snapshot of the vertex→triangle incidence (rebuilt per sweep, O(T)).
// An operation is applied only if everything it reads is unmodified since the snapshot (tracked
// with per-triangle and per-vertex "touched" flags), so the snapshot stays valid for it.
#pragma once

#include <array>
#include <vector>

#include "activefoam/remesh.h"

namespace activefoam::remesh_internal {

class Remesher {
 public:
  Remesher(TriMesh& mesh, const RemeshParams& p, RemeshStats& st);

  // The passes, and the rescue where they leave a triangle below half of A_m (repair.cc).
  void run();
  void passes();
  void finish(std::vector<int>* old_to_new);
  // on_surface: restores the volume the remesh changed (smoothing.cc).
  void restoreVolume();

 private:
  // ---- snapshot structures ----
  void computeAreas();
  template <class Pred>
  bool anyArea(Pred pred) const {
    for (double a : area_)
      if (pred(a)) return true;
    return false;
  }
  void buildIncidence();
  int valence(int i) const { return incStart_[i + 1] - incStart_[i]; }
  int opposite(int i, int j) const;
  bool touchedTri(int t, int nsnap) const { return t < 0 || t >= nsnap || triTouched_[t]; }
  void removeDeadTriangles();

  // ---- split ----
  int splitSweep();

  // ---- collapse ----
  int collapseSweep();
  bool ringsUntouched(int a, int b) const;
  bool tryCollapse(int t, int u, int a, int b, int c, int d);
  // RemeshParams::keep_out: refuses (true, counted) a merged vertex deeper inside a touching cell
  // than keep_out_um and than both vertices it merges (repair.cc).
  bool keptOut(const Vec3& merged, int a, int b);

  // ---- flip ----
  int flipSweep();
  double sinOppositeAngleSum(int i, int j, int k, int l) const;
  bool flipAllowed(int i, int j, int k, int l, double& dv);
  Vec3 volumeGradient(int q, int t, int u) const;
  bool compensateFlipVolume(int t, int u, std::array<int, 4> q, double dv);

  // ---- tangential smoothing (smoothing.cc) ----
  double minAngleCos(const Tri& f) const;
  bool badTriangle(int t) const;
  double ringWorstCos(int q) const;
  int smoothSweep();
  double volume() const;
  Vec3 closestOnRing(int q, const Vec3& p) const;

  TriMesh& mesh_;
  const RemeshParams& p_;
  RemeshStats& st_;
  std::vector<Tri> tri_;
  std::vector<Vec3> x_, v_;
  std::vector<int> rep_;
  std::vector<char> dead_;
  int alive_ = 0;
  bool relaxed_ = false;  // the rescue's passes
  double vol_ = 0;
  double v0_ = 0;  // on_surface: the volume to restore
  std::vector<double> area_;
  std::vector<int> incStart_, inc_, fill_, cand_, stamp_;
  int stampId_ = 0;
  std::vector<char> triTouched_, vertTouched_;
};

// RemeshParams::rebuild_triangles: after the Remesher, rebuilds (rebuildRadially) a mesh still left
// with a triangle below half of A_m, where that leaves its smallest triangle larger and engulfs no
// touching cell's vertex (RemeshParams::keep_out_points); maps old_to_new, if given, to the new
// vertices (repair.cc).
void rebuildIfLeftSmall(TriMesh& mesh, const RemeshParams& params, std::vector<int>* old_to_new,
                        RemeshStats& st);

}  // namespace activefoam::remesh_internal
