// The scenes the tests of the time step share (schedule, guards, adaptive step, ros2).
#pragma once

#include "activefoam/simulation.h"
#include "test_support.h"

namespace activefoam::testing {

// A motile doublet (random polarity streams, contacts, remeshing every 10 s), 80 triangles;
// remeshing splits triangles above 1.5 A_Δ (the stretched pair below has some).
inline SceneSpec motileDoublet(double dt) {
  SceneSpec s = cellSpec(1.0, 80);
  s.scene = SceneKind::Doublet;
  s.cells.p_a = 0.0372;
  s.seed = 7;
  s.numerics.dt_s = dt;
  s.numerics.remesh_every_s = 10;
  s.numerics.remesh_min_area_factor = 0.7;
  s.numerics.remesh_max_area_factor = 1.5;
  return s;
}

// Two cells stretched along x (ellipsoids with semi-axes (2.2, 1, 1/2.2) r), 0.04 µm apart (inside
// the adhesion range): their first remesh has work to do (the stretched triangles are split,
// collapsed and flipped), so a try that remeshes changes the topology.
inline CellSet stretchedPair(const SceneSpec& s) {
  const double r = s.cells.radius_mean_um, q = 2.2;
  const int tris = static_cast<int>(s.numerics.triangles_per_cell);
  CellSet c;
  c.addCell(ellipsoidCell(r, q, tris, Vec3(-(q * r + 0.02), 0, 0)), r);
  c.addCell(ellipsoidCell(r, q, tris, Vec3(q * r + 0.02, 0, 0)), r);
  return c;
}

}  // namespace activefoam::testing
