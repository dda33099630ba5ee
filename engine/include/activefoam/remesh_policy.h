// When cells are remeshed during a run.
#pragma once

#include <cstdint>
#include <vector>

#include "activefoam/cellset.h"
#include "activefoam/geometry.h"
#include "activefoam/remesh.h"
#include "activefoam/spec.h"
#include "activefoam/time_stepper.h"

namespace activefoam {

// When to remesh (numerics.remesh_every_s): every cell at multiples of τ_r, and in between any
// cell with a triangle below half of A_m (contacts zipping up squeeze rim triangles from A_m to
// zero area in a few seconds, less than τ_r, and then they invert).
class RemeshPolicy {
 public:
  RemeshPolicy(const SceneSpec& spec, const TimeStepper& stepper);
  // Cells to remesh at the end of a step that ended at `ticks`; empty when none is due.
  // `all` is set when it is the periodic remesh of every cell.
  std::vector<char> due(std::int64_t ticks, const CellSet& cells, const Geometry& geo,
                        bool& all) const;
  double minTriangleArea(const CellSet& cells, int c) const;  // A_m of cell c

 private:
  std::int64_t interval_ticks_ = 0;  // 0: never
  double min_area_factor_;
  double triangles_;
};

// How a cell of radius r is remeshed in a run (the numerics' areas relative to 4πr²/triangles,
// smoothing at 15°, on the surface, rescue, rebuild, the keep-out's depth); keep_out itself,
// which needs the neighbours, is the caller's.
RemeshParams cellRemeshParams(const NumericsParams& numerics, double radius_um);

}  // namespace activefoam
