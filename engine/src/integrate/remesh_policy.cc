#include "activefoam/remesh_policy.h"

#include <cmath>

namespace activefoam {

RemeshPolicy::RemeshPolicy(const SceneSpec& spec, const TimeStepper& stepper)
    : min_area_factor_(spec.numerics.remesh_min_area_factor),
      triangles_(static_cast<double>(spec.numerics.triangles_per_cell)) {
  const double every = remeshEveryS(spec);
  if (every > 0) interval_ticks_ = stepper.periodTicks(every);
}

double RemeshPolicy::minTriangleArea(const CellSet& cells, int c) const {
  const double r = cells.radius[c];
  return min_area_factor_ * 4 * M_PI * r * r / triangles_;
}

std::vector<char> RemeshPolicy::due(std::int64_t ticks, const CellSet& cells, const Geometry& geo,
                                    bool& all) const {
  all = false;
  if (interval_ticks_ == 0) return {};
  if (ticks % interval_ticks_ == 0) {
    all = true;
    return std::vector<char>(cells.numCells(), 1);
  }
  std::vector<char> which(cells.numCells(), 0);
  bool any = false;
  for (int t = 0; t < cells.numTriangles(); ++t) {
    const int c = cells.tri_cell[t];
    if (!which[c] && geo.tri_area[t] < 0.5 * minTriangleArea(cells, c)) which[c] = any = true;
  }
  if (!any) which.clear();
  return which;
}

RemeshParams cellRemeshParams(const NumericsParams& n, double r) {
  const int tris = static_cast<int>(n.triangles_per_cell);
  const double a_ref = 4 * M_PI * r * r / tris;
  RemeshParams rp;
  rp.min_area = n.remesh_min_area_factor * a_ref;
  rp.max_area = n.remesh_max_area_factor * a_ref;
  rp.smooth_min_angle_deg = 15;
  rp.on_surface = n.remesh_on_surface;
  rp.rescue = n.remesh_repair != RemeshRepair::None;
  rp.rebuild_triangles = n.remesh_repair == RemeshRepair::RescueRebuild ? tris : 0;
  rp.keep_out_um = n.remesh_keep_out_um;
  return rp;
}

}  // namespace activefoam
