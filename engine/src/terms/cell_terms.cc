#include <algorithm>
#include <cmath>
#include <vector>

#include "activefoam/contacts.h"
#include "activefoam/terms.h"
#include "activefoam/threads.h"

namespace activefoam {

double SurfaceTension::addForces(const StepContext& ctx, Eigen::Matrix3Xd& f) const {
  const CellSet& cells = ctx.cells;
  const auto& x = cells.x;
  const std::vector<double>* frac = ctx.contacts ? &ctx.contacts->tri_contact_fraction : nullptr;
  const int nc = cells.numCells();
  std::vector<double> cell_energy(nc);
  // A cell's triangles touch only its own vertices: threads own whole cells, each summed in
  // triangle order; energies are added in cell order.
#pragma omp parallel for schedule(static) if (cells.numTriangles() > grain().min_items)
  for (int c = 0; c < nc; ++c) {
    double e = 0;
    for (int t = cells.cell_tri_begin[c]; t < cells.cell_tri_begin[c + 1]; ++t) {
      const Tri& tr = cells.tri[t];
      const Vec3& n = ctx.geo.tri_normal[t];
      const double g = frac ? gamma_ - w_ * (*frac)[t] : gamma_;
      e += g * ctx.geo.tri_area[t];
      for (int k = 0; k < 3; ++k) {
        const int i = tr[k], j = tr[(k + 1) % 3], l = tr[(k + 2) % 3];
        f.col(i) += 0.5 * g * (x.col(l) - x.col(j)).cross(n);
      }
    }
    cell_energy[c] = e;
  }
  double energy = 0;
  for (double e : cell_energy) energy += e;
  return energy;
}

double CytoplasmPressure::pressure(const CellSet& cells, const Geometry& geo, int c) const {
  const double vstar = cells.target_volume[c];
  const double eps = (geo.cell_volume[c] - vstar) / vstar;
  return 2 * gamma_ / cells.radius[c] - k_ * eps - k_ / tau_k_ * cells.pi_integral[c];
}

double CytoplasmPressure::addForces(const StepContext& ctx, Eigen::Matrix3Xd& f) const {
  const CellSet& cells = ctx.cells;
  // Threads own whole cells (a cell's triangles touch only its vertices).
#pragma omp parallel for schedule(static) if (cells.numTriangles() > grain().min_items)
  for (int c = 0; c < cells.numCells(); ++c) {
    const double p = pressure(cells, ctx.geo, c);
    for (int t = cells.cell_tri_begin[c]; t < cells.cell_tri_begin[c + 1]; ++t) {
      const Vec3 ft = p * ctx.geo.tri_area[t] / 3.0 * ctx.geo.tri_normal[t];
      for (int k = 0; k < 3; ++k) f.col(cells.tri[t][k]) += ft;
    }
  }
  double energy = 0;
  for (int c = 0; c < cells.numCells(); ++c) {
    const double v = ctx.geo.cell_volume[c], vstar = cells.target_volume[c];
    energy += -(2 * gamma_ / cells.radius[c] - k_ / tau_k_ * cells.pi_integral[c]) * v +
              k_ * (v - vstar) * (v - vstar) / (2 * vstar);
  }
  return energy;
}

void CytoplasmPressure::endStep(const StepContext& ctx, CellSet& cells) const {
  // Explicit (forward) integration of ε over the step, with ε at the start of the step; the
  // trapezoid with the predicted end for ros2 (forward Euler there would make it first order).
  for (int c = 0; c < cells.numCells(); ++c) {
    const double vstar = cells.target_volume[c];
    const double eps = (ctx.geo.cell_volume[c] - vstar) / vstar;
    if (ctx.geo_end)
      cells.pi_integral[c] += 0.5 * (eps + (ctx.geo_end->cell_volume[c] - vstar) / vstar) * ctx.dt;
    else
      cells.pi_integral[c] += eps * ctx.dt;
  }
}

void MediumDrag::addFriction(const StepContext& ctx, BlockMatrix& gamma) const {
#pragma omp parallel for schedule(static) if (ctx.cells.numVertices() > grain().min_items)
  for (int i = 0; i < ctx.cells.numVertices(); ++i) {
    const double r = ctx.cells.radius[ctx.cells.vertex_cell[i]];
    gamma.addDiagonal(i, (1.5 * eta_m_ / r * ctx.geo.vertex_area[i]) * Eigen::Matrix3d::Identity());
  }
}

void CortexViscosity::addFriction(const StepContext& ctx, BlockMatrix& gamma) const {
  const double g = eta_ / std::sqrt(3.0);
  const CellSet& cells = ctx.cells;
  const auto& edges = ctx.topo.edges;
  const int nc = cells.numCells();
  // Edges are sorted by their first vertex and a cell's vertices are contiguous, so each cell's
  // edges are one contiguous range that couples only its own vertices: threads own whole cells
  // and add their edges in list order.
  auto firstEdge = [&](int c) {
    const int v = cells.cell_vertex_begin[c];
    return static_cast<int>(
        std::lower_bound(edges.begin(), edges.end(), v,
                         [](const Edge& e, int vertex) { return e.i < vertex; }) -
        edges.begin());
  };
#pragma omp parallel for schedule(static) if (static_cast <int>(edges.size()) > grain().min_items)
  for (int c = 0; c < nc; ++c)
    for (int k = firstEdge(c), end = c + 1 < nc ? firstEdge(c + 1) : static_cast<int>(edges.size());
         k < end; ++k) {
      const Edge& e = edges[k];
      const Vec3 n = (ctx.cells.x.col(e.j) - ctx.cells.x.col(e.i)).normalized();
      Vec3 b = ctx.geo.tri_normal[e.ta] + ctx.geo.tri_normal[e.tb];
      b -= b.dot(n) * n;  // exactly orthogonal to the edge (both normals are, up to roundoff)
      const double bn = b.norm();
      // A fully folded edge has no defined bisector: fall back to isotropic coupling, still SPD.
      if (bn < 1e-12) {
        gamma.addCoupling(e.i, e.j, g * Eigen::Matrix3d::Identity());
        continue;
      }
      b /= bn;
      // (n̂, t̂ = b̂ × n̂, b̂) is orthonormal: n̂n̂ᵀ + t̂t̂ᵀ + ε b̂b̂ᵀ = I − (1 − ε) b̂b̂ᵀ.
      const Eigen::Matrix3d m =
          g * (Eigen::Matrix3d::Identity() - (1 - eps_n_) * b * b.transpose());
      gamma.addCoupling(e.i, e.j, m);
    }
}

}  // namespace activefoam
