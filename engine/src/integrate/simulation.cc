#include "activefoam/simulation.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <sstream>
#include <stdexcept>

#include "activefoam/remesh.h"

namespace activefoam {
namespace {

using Clock = std::chrono::steady_clock;
double since(Clock::time_point t0) {
  return std::chrono::duration<double>(Clock::now() - t0).count();
}

}  // namespace

Simulation::Simulation(const SceneSpec& spec) : Simulation(spec, buildScene(spec)) {}

Simulation::Simulation(const SceneSpec& spec, CellSet cells)
    : spec_(spec),
      cells_(std::move(cells)),
      solver_(spec.numerics.preconditioner, spec.numerics.cg_tol,
              static_cast<int>(spec.numerics.cg_max_iter)) {
  init();
}

void Simulation::init() {
  const CellParams& p = spec_.cells;
  // The explicit list of terms (DESIGN.md §2). Terms whose parameters make them vanish are not
  // built (no per-step cost): motility without p_a, contact friction without ξ unless it also
  // carries the contact-implicit stiffness Δt K_c.
  terms_.push_back(std::make_unique<SurfaceTension>(p));
  auto pressure = std::make_unique<CytoplasmPressure>(p);
  pressure_ = pressure.get();
  terms_.push_back(std::move(pressure));
  terms_.push_back(std::make_unique<MediumDrag>(p));
  terms_.push_back(std::make_unique<CortexViscosity>(p));
  with_contacts_ = cells_.numCells() > 1;
  if (with_contacts_) {
    law_.k = p.k_contact;
    law_.h0 = contactRangeH0(p);
    terms_.push_back(std::make_unique<ContactAdhesion>());
    const bool implicit = spec_.numerics.integrator == IntegratorKind::ContactImplicit;
    const bool frictionless =
        p.xi_normal.value_or(p.xi) == 0 && p.xi_tangential.value_or(p.xi) == 0;
    if (implicit || !frictionless)
      terms_.push_back(std::make_unique<ContactFriction>(p, implicit ? spec_.numerics.dt_s : 0.0));
    if (p.p_a > 0) terms_.push_back(std::make_unique<ActiveMigration>(p, spec_.seed));
  }

  const double every = spec_.numerics.remesh_every_s.value_or(5 * tauShell(p));
  remesh_interval_steps_ =
      every > 0 ? std::max<std::int64_t>(1, std::llround(every / spec_.numerics.dt_s)) : 0;
  updateTopology(cells_, topo_);
  computeGeometry(cells_, geo_);
  detect();
}

void Simulation::detect() {
  if (with_contacts_)
    detectContacts(cells_, geo_, law_, spec_.numerics.contact_quadrature, contacts_, &candidates_);
}

void Simulation::setPositions(const Eigen::Matrix3Xd& x) {
  cells_.x = x;
  computeGeometry(cells_, geo_);
  detect();
}

double Simulation::computeForces(Eigen::Matrix3Xd& f) {
  f.setZero(3, cells_.numVertices());
  double energy = 0;
  const StepContext ctx = context();
  for (const auto& term : terms_) energy += term->addForces(ctx, f);
  return energy;
}

void Simulation::prepareFriction() {
  if (pattern_version_ != cells_.topology_version) {
    // Only the cells' own couplings (mesh edges): contact couplings are applied as a product,
    // so contacts coming and going never force a rebuild.
    std::vector<std::pair<int, int>> couplings;
    couplings.reserve(topo_.edges.size());
    for (const Edge& e : topo_.edges) couplings.emplace_back(e.i, e.j);
    gamma_.setPattern(cells_.numVertices(), std::move(couplings));
    pattern_version_ = cells_.topology_version;
  } else {
    gamma_.setZero();
  }
  const StepContext ctx = context();
  product_terms_.clear();
  for (const auto& term : terms_) {
    if (term->hasCouplingProduct()) {
      term->addFrictionDiagonal(ctx, gamma_);
      product_terms_.push_back(term.get());
    } else {
      term->addFriction(ctx, gamma_);
    }
  }
}

void Simulation::applyFriction(const double* v, double* y) const {
  gamma_.multiply(v, y);
  for (const ForceTerm* t : product_terms_) t->addCouplingProduct(v, y);
}

SpMat Simulation::assembleFriction() {
  std::vector<std::pair<int, int>> couplings;
  for (const Edge& e : topo_.edges) couplings.emplace_back(e.i, e.j);
  for (const ContactPair& p : contacts_.pairs)
    for (int i : cells_.tri[p.ta])
      for (int k : cells_.tri[p.tb]) couplings.emplace_back(i, k);
  BlockMatrix full;
  full.setPattern(cells_.numVertices(), std::move(couplings));
  const StepContext ctx = context();
  for (const auto& term : terms_) term->addFriction(ctx, full);
  return full.matrix();
}

bool Simulation::contactVelocitiesReverse(const Eigen::VectorXd& v) const {
  const double floor = 0.1 * law_.h0 / spec_.numerics.dt_s;  // µm/s
  double dot = 0, norms = 0;
  int moving = 0;
  for (int i = 0; i < cells_.numVertices(); ++i) {
    if (contacts_.vertex_contact_area[i] <= 0) continue;
    const Vec3 now = v.segment<3>(3 * i), before = cells_.v.col(i);
    if (now.norm() < floor || before.norm() < floor) continue;
    ++moving;
    dot += now.dot(before);
    norms += now.norm() * before.norm();
  }
  return moving > 0 && dot < -0.5 * norms;
}

StepReport Simulation::step() {
  StepReport rep;
  const double dt = spec_.numerics.dt_s;
  rep.contacts = static_cast<int>(contacts_.pairs.size());
  auto t0 = Clock::now();
  computeForces(f_);
  times_.forces += since(t0);

  t0 = Clock::now();
  prepareFriction();
  times_.matrix += since(t0);

  t0 = Clock::now();
  const Eigen::Index n = 3 * static_cast<Eigen::Index>(cells_.numVertices());
  Eigen::Map<const Eigen::VectorXd> b(f_.data(), n);
  Eigen::VectorXd v = Eigen::Map<const Eigen::VectorXd>(cells_.v.data(), n);
  rep.cg = solver_.solve([this](const double* in, double* out) { applyFriction(in, out); }, gamma_,
                         b, v);
  times_.solve += since(t0);

  std::ostringstream why;
  if (!v.allFinite() || !b.allFinite()) {
    rep.failure = FailureKind::NonFinite;
    why << "non-finite " << (b.allFinite() ? "velocity" : "force") << " at t=" << t_ << " s";
    rep.reason = why.str();
    return rep;
  }
  if (!rep.cg.converged) {
    rep.failure = FailureKind::CgNotConverged;
    why << "CG did not reach the tolerance " << spec_.numerics.cg_tol << " in " << rep.cg.iterations
        << " iterations (relative residual " << rep.cg.residual << ") at t=" << t_ << " s";
    rep.reason = why.str();
    return rep;
  }

  if (with_contacts_) {
    oscillating_steps_ = contactVelocitiesReverse(v) ? oscillating_steps_ + 1 : 0;
    if (oscillating_steps_ >= spec_.numerics.max_oscillating_steps) {
      rep.failure = FailureKind::ContactOscillation;
      why << "contact velocities reversed in " << oscillating_steps_
          << " consecutive steps at t=" << t_
          << " s: the contact springs are too stiff for dt = " << dt << " s with the "
          << toString(spec_.numerics.integrator)
          << " integrator (use contact-implicit or a smaller dt)";
      rep.reason = why.str();
      return rep;
    }
  }
  cells_.v = Eigen::Map<const Eigen::Matrix3Xd>(v.data(), 3, cells_.numVertices());
  cells_.x += dt * cells_.v;
  {
    const StepContext ctx = context();  // geometry of the start of the step
    for (const auto& term : terms_) term->endStep(ctx, cells_);
  }
  ++steps_;
  t_ = static_cast<double>(steps_) * dt;  // not a running sum: sample times stay exact

  t0 = Clock::now();
  std::swap(geo_prev_, geo_);
  computeGeometry(cells_, geo_);
  times_.geometry += since(t0);

  // Failure checks: a triangle whose normal turned by more than 90° in one step has inverted.
  for (int t = 0; t < cells_.numTriangles(); ++t) {
    if (geo_.tri_area[t] <= 0 || geo_.tri_normal[t].dot(geo_prev_.tri_normal[t]) < 0) {
      rep.failure = FailureKind::InvertedTriangle;
      why << "triangle " << t << " of cell " << cells_.tri_cell[t] << " inverted at t=" << t_
          << " s (time step too large for the forces?)";
      rep.reason = why.str();
      return rep;
    }
  }
  for (int c = 0; c < cells_.numCells(); ++c) {
    const double eps = (geo_.cell_volume[c] - cells_.target_volume[c]) / cells_.target_volume[c];
    if (!(std::abs(eps) <= spec_.numerics.max_volume_error)) {
      rep.failure = FailureKind::VolumeDrift;
      why << "cell " << c << " volume error " << eps << " exceeds numerics.max_volume_error "
          << spec_.numerics.max_volume_error << " at t=" << t_ << " s";
      rep.reason = why.str();
      return rep;
    }
  }

  // Remeshing before contact detection: a remesh re-detects the contacts of the new meshes, and
  // detecting before it as well cost a second full detection on every remesh step (50–85 ms of
  // ~500 ms per step on the 2 × 100 fusion, where some cell remeshes almost every step).
  const std::uint64_t topology_before = cells_.topology_version;
  if (remesh_interval_steps_ > 0) {
    StepReport r;
    if (steps_ % remesh_interval_steps_ == 0) {
      r = remeshAll();
    } else {
      // Between the periodic remeshes, a cell whose triangle has shrunk below half of A_m is
      // remeshed at once: where contacts zip up (a compacting aggregate) triangles at the rim
      // are squeezed from A_m to zero area in a few seconds, less than τ_r, and then invert.
      std::vector<char> which(cells_.numCells(), 0);
      bool any = false;
      for (int t = 0; t < cells_.numTriangles(); ++t) {
        const int c = cells_.tri_cell[t];
        if (!which[c] && geo_.tri_area[t] < 0.5 * minTriangleArea(c)) which[c] = any = true;
      }
      if (any) r = remeshCells(which);
    }
    rep.remesh_ops = r.remesh_ops;
    rep.remesh_volume_jump = r.remesh_volume_jump;
  }
  if (cells_.topology_version == topology_before) {
    t0 = Clock::now();
    detect();
    times_.contacts += since(t0);
  }

  if (with_contacts_) {
    if (std::string why_not = interpenetration(); !why_not.empty()) {
      rep.failure = FailureKind::Interpenetration;
      rep.reason = why_not;
      return rep;
    }
  }
  return rep;
}

std::string Simulation::interpenetration() {
  // Per pair of cells, the area-weighted mean gap of their contact pairs. Single triangle
  // pairs are no measure: where two surfaces meet at a rim at ~70° a pair overlaps by a sliver
  // of 1e-4 µm² whose mean gap along the pair normal reads −0.5 … −1.6 µm while the cells do
  // not overlap (measured on a 2 × 8-cell fusion; it stopped runs at t = 990 s).
  penetration_.clear();
  for (const ContactPair& p : contacts_.pairs) {
    int a = cells_.tri_cell[p.ta], b = cells_.tri_cell[p.tb];
    if (a > b) std::swap(a, b);
    penetration_.push_back({(static_cast<std::uint64_t>(a) << 32) | static_cast<std::uint32_t>(b),
                            p.c.mean_gap * p.c.area, p.c.area});
  }
  std::sort(penetration_.begin(), penetration_.end(),
            [](const auto& x, const auto& y) { return x.key < y.key; });
  const double limit = spec_.numerics.max_penetration_um;
  for (std::size_t i = 0; i < penetration_.size();) {
    double gs = 0, area = 0;
    std::size_t j = i;
    for (; j < penetration_.size() && penetration_[j].key == penetration_[i].key; ++j) {
      gs += penetration_[j].gap_area;
      area += penetration_[j].area;
    }
    if (area > 0 && -gs / area > limit) {
      std::ostringstream why;
      why << "cells " << (penetration_[i].key >> 32) << " and "
          << (penetration_[i].key & 0xffffffffULL) << " interpenetrate by " << -gs / area
          << " µm on average over their contact > numerics.max_penetration_um = " << limit
          << " µm at t=" << t_ << " s";
      return why.str();
    }
    i = j;
  }
  return {};
}

double Simulation::minTriangleArea(int c) const {
  const double r = cells_.radius[c];
  return spec_.numerics.remesh_min_area_factor * 4 * M_PI * r * r /
         static_cast<double>(spec_.numerics.triangles_per_cell);
}

StepReport Simulation::remeshAll() {
  return remeshCells(std::vector<char>(cells_.numCells(), 1));
}

StepReport Simulation::remeshCells(const std::vector<char>& which) {
  StepReport rep;
  const auto t0 = Clock::now();
  const int tris = static_cast<int>(spec_.numerics.triangles_per_cell);
  std::vector<TriMesh> meshes(cells_.numCells());
  int ops = 0;
  for (int c = 0; c < cells_.numCells(); ++c) {
    meshes[c] = cells_.cellMesh(c);
    if (!which[c]) continue;
    const double r = cells_.radius[c];
    const double a_ref = 4 * M_PI * r * r / tris;
    RemeshParams rp;
    rp.min_area = spec_.numerics.remesh_min_area_factor * a_ref;
    rp.max_area = spec_.numerics.remesh_max_area_factor * a_ref;
    rp.smooth_min_angle_deg = 15;
    const RemeshStats s = remesh(meshes[c], rp);
    ops += s.operations();
    if (s.volume_before > 0)
      rep.remesh_volume_jump = std::max(
          rep.remesh_volume_jump, std::abs(s.volume_after - s.volume_before) / s.volume_before);
  }
  if (ops > 0) {
    cells_.setCellMeshes(meshes);
    updateTopology(cells_, topo_);
    computeGeometry(cells_, geo_);
    detect();
  }
  rep.remesh_ops = ops;
  remesh_ops_ += ops;
  times_.remesh += std::chrono::duration<double>(Clock::now() - t0).count();
  return rep;
}

}  // namespace activefoam
