#include <algorithm>
#include <cmath>
#include <cstdint>
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

void MediumDrag::addFriction(const StepContext& ctx, FrictionOperator& op) const {
  BlockMatrix& gamma = op.diagonal();
#pragma omp parallel for schedule(static) if (ctx.cells.numVertices() > grain().min_items)
  for (int i = 0; i < ctx.cells.numVertices(); ++i) {
    const double r = ctx.cells.radius[ctx.cells.vertex_cell[i]];
    gamma.addDiagonal(i, (1.5 * eta_m_ / r * ctx.geo.vertex_area[i]) * Eigen::Matrix3d::Identity());
  }
}

namespace {

// b̂ of edge e, the mean of its two triangles' normals made orthogonal to the edge; zero for a
// fully folded edge, which has none (the cortex's coupling is then isotropic, still SPD; the
// tension's stiffness adds nothing there).
Vec3 bisector(const StepContext& ctx, const Edge& e) {
  const Vec3 n = (ctx.cells.x.col(e.j) - ctx.cells.x.col(e.i)).normalized();
  Vec3 b = ctx.geo.tri_normal[e.ta] + ctx.geo.tri_normal[e.tb];
  b -= b.dot(n) * n;  // exactly orthogonal to the edge (both normals are, up to roundoff)
  const double bn = b.norm();
  if (bn < 1e-12) return Vec3::Zero();
  return b / bn;
}

// f(k) for every edge k, cell by cell (cell c's edges are cell_edges[c] .. [c + 1]), each
// cell's in list order: threads own whole cells, and a cell's edges touch only its vertices, so
// every sum f makes into a vertex has the same order whatever the thread count.
template <class F>
void forEachEdgeByCell(const std::vector<std::size_t>& cell_edges, F&& f) {
  if (cell_edges.empty()) return;
  const int nc = static_cast<int>(cell_edges.size()) - 1;
  const int ne = static_cast<int>(cell_edges.back());
#pragma omp parallel for schedule(static) if (ne > grain().min_items)
  for (int c = 0; c < nc; ++c)
    for (std::size_t k = cell_edges[c]; k < cell_edges[c + 1]; ++k) f(k);
}

// An edge coupling's product y −= C v, edge by edge in forEachEdgeByCell's order: f(e, v_i, v_j,
// y_i, y_j) for each edge e = ij.
template <class Edge, class F>
void forEachEdgeProduct(const std::vector<std::size_t>& cell_edges, const std::vector<Edge>& edges,
                        const double* v, double* y, F&& f) {
  forEachEdgeByCell(cell_edges, [&](std::size_t k) {
    const Edge& e = edges[k];
    const std::int64_t i = 3 * static_cast<std::int64_t>(e.i);
    const std::int64_t j = 3 * static_cast<std::int64_t>(e.j);
    f(e, v + i, v + j, y + i, y + j);
  });
}

// The mesh edges' couplings of one step: −G_ij across each edge ij.
class EdgeCoupling : public Coupling {
 public:
  struct EdgeOp {
    int i, j;
    double b[3];
  };
  // G of an edge: (n̂, t̂ = b̂ × n̂, b̂) is orthonormal, so n̂n̂ᵀ + t̂t̂ᵀ + ε b̂b̂ᵀ = I − (1 − ε) b̂b̂ᵀ.
  Eigen::Matrix3d edgeMatrix(const double* b) const {
    const Vec3 bv(b[0], b[1], b[2]);
    return g * (Eigen::Matrix3d::Identity() - (1 - eps_n) * bv * bv.transpose());
  }
  // −G v_j into y_i and −G v_i into y_j, with G v = g (v − (1 − ε) b̂ (b̂·v)): edgeMatrix applied
  // without forming it.
  void addProduct(const double* v, double* y) const override {
    const double c = 1 - eps_n;
    forEachEdgeProduct(
        cell_edges, edges, v, y,
        [&](const EdgeOp& e, const double* vi, const double* vj, double* yi, double* yj) {
          const double bi = c * (e.b[0] * vi[0] + e.b[1] * vi[1] + e.b[2] * vi[2]);
          const double bj = c * (e.b[0] * vj[0] + e.b[1] * vj[1] + e.b[2] * vj[2]);
          for (int d = 0; d < 3; ++d) {
            yi[d] -= g * (vj[d] - bj * e.b[d]);
            yj[d] -= g * (vi[d] - bi * e.b[d]);
          }
        });
  }
  void forEachBlock(const BlockSink& sink) const override {
    for (const EdgeOp& e : edges) sink(e.i, e.j, -edgeMatrix(e.b));
  }
  double g = 0, eps_n = 0;
  std::vector<EdgeOp> edges;
  std::vector<std::size_t> cell_edges;  // cell c's edges: edges[cell_edges[c] .. [c + 1])
};

// The surface tension's out-of-plane stiffness of one step: −k b̂b̂ᵀ across each edge.
class NormalEdgeCoupling : public Coupling {
 public:
  struct EdgeOp {
    int i, j;
    double k;  // nN·s/µm: the step's factor times the edge's stiffness
    double b[3];
  };
  void addProduct(const double* v, double* y) const override {
    forEachEdgeProduct(
        cell_edges, edges, v, y,
        [](const EdgeOp& e, const double* vi, const double* vj, double* yi, double* yj) {
          const double bi = e.k * (e.b[0] * vi[0] + e.b[1] * vi[1] + e.b[2] * vi[2]);
          const double bj = e.k * (e.b[0] * vj[0] + e.b[1] * vj[1] + e.b[2] * vj[2]);
          for (int d = 0; d < 3; ++d) {
            yi[d] -= bj * e.b[d];
            yj[d] -= bi * e.b[d];
          }
        });
  }
  static Eigen::Matrix3d edgeMatrix(const EdgeOp& e) {
    const Vec3 bv(e.b[0], e.b[1], e.b[2]);
    return e.k * bv * bv.transpose();
  }
  void forEachBlock(const BlockSink& sink) const override {
    for (const EdgeOp& e : edges) sink(e.i, e.j, -edgeMatrix(e));
  }
  std::vector<EdgeOp> edges;
  std::vector<std::size_t> cell_edges;
};

// ½ cot of the angle of triangle t opposite its edge ij.
double halfCotOpposite(const CellSet& cells, int t, int i, int j) {
  const Tri& tr = cells.tri[t];
  int o = tr[0];
  for (int q = 1; q < 3; ++q)
    if (o == i || o == j) o = tr[q];
  const Vec3 u = cells.x.col(i) - cells.x.col(o), w = cells.x.col(j) - cells.x.col(o);
  const double s = u.cross(w).norm();
  return s > 0 ? 0.5 * u.dot(w) / s : 0.0;
}

}  // namespace

void SurfaceTension::addFriction(const StepContext& ctx, FrictionOperator& op) const {
  if (ctx.tension_stiffness_dt <= 0) return;
  const auto& edges = ctx.topo.edges;
  const std::vector<double>* frac = ctx.contacts ? &ctx.contacts->tri_contact_fraction : nullptr;
  auto& coupling = op.coupling<NormalEdgeCoupling>(this);
  coupling.cell_edges = ctx.topo.cell_edge_begin;
  coupling.edges.resize(edges.size());
  BlockMatrix& gamma = op.diagonal();
  forEachEdgeByCell(coupling.cell_edges, [&](std::size_t n) {
    const Edge& e = edges[n];
    double k = 0;
    for (int t : {e.ta, e.tb})
      k += (frac ? gamma_ - w_ * (*frac)[t] : gamma_) * halfCotOpposite(ctx.cells, t, e.i, e.j);
    // An obtuse pair of angles makes the cotangent weight negative: dropped, so that Γ stays
    // positive definite (the stiffness is then a little less than the tension's).
    k = std::max(0.0, ctx.tension_stiffness_dt * k);
    const Vec3 b = bisector(ctx, e);
    NormalEdgeCoupling::EdgeOp& out = coupling.edges[n];
    out = {e.i, e.j, k, {b.x(), b.y(), b.z()}};
    const Eigen::Matrix3d m = NormalEdgeCoupling::edgeMatrix(out);
    gamma.addDiagonal(e.i, m);
    gamma.addDiagonal(e.j, m);
  });
}

void CortexViscosity::addFriction(const StepContext& ctx, FrictionOperator& op) const {
  const auto& edges = ctx.topo.edges;
  auto& coupling = op.coupling<EdgeCoupling>(this);
  coupling.g = g_;
  coupling.eps_n = eps_n_;
  // A cell's edges are one range that couples only its own vertices (updateTopology).
  coupling.cell_edges = ctx.topo.cell_edge_begin;
  coupling.edges.resize(edges.size());
  BlockMatrix& gamma = op.diagonal();
  forEachEdgeByCell(coupling.cell_edges, [&](std::size_t k) {
    const Edge& e = edges[k];
    const Vec3 b = bisector(ctx, e);
    EdgeCoupling::EdgeOp& out = coupling.edges[k];
    out = {e.i, e.j, {b.x(), b.y(), b.z()}};
    const Eigen::Matrix3d m = coupling.edgeMatrix(out.b);
    gamma.addDiagonal(e.i, m);
    gamma.addDiagonal(e.j, m);
  });
}

}  // namespace activefoam
