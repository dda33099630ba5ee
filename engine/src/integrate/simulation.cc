#include "activefoam/simulation.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <sstream>
#include <stdexcept>

#include "activefoam/remesh.h"
#include "activefoam/threads.h"

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
      stepper_(spec.numerics.dt_s, dtMinS(spec.numerics), spec.numerics.adaptive),
      integrator_(spec.numerics),
      remesh_(spec, stepper_) {
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
    law_.stiffness_moments = integrator_.twoStage();
    terms_.push_back(std::make_unique<ContactAdhesion>());
    const bool implicit = integrator_.contactStiffnessDt(1.0) > 0;
    const bool frictionless =
        p.xi_normal.value_or(p.xi) == 0 && p.xi_tangential.value_or(p.xi) == 0;
    if (implicit || !frictionless) terms_.push_back(std::make_unique<ContactFriction>(p));
    if (p.p_a > 0) terms_.push_back(std::make_unique<ActiveMigration>(p, spec_.seed));
  }
  guards_ = standardGuards(with_contacts_);
  if (integrator_.twoStage() && spec_.numerics.max_step_error_um > 0)
    guards_.push_back(stepErrorGuard());
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
  return integrator_.computeForces(context(), terms_, f);
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

std::string Simulation::interpenetration() {
  if (!with_contacts_) return {};
  return activefoam::interpenetration(cells_, contacts_, spec_.numerics.max_penetration_um, time(),
                                      penetration_);
}

std::optional<StepFailure> Simulation::runGuards(StepGuard::Phase phase, const GuardView& view) {
  for (const auto& g : guards_)
    if (g->phase() == phase)
      if (auto failure = g->check(view)) return failure;
  return std::nullopt;
}

void Simulation::resetGuardCounts() {
  for (const auto& g : guards_) g->setCount(0);
}

void Simulation::saveRollback() {
  saved_.cells = cells_;  // copy-assignment: reuses the buffers of the last step
  saved_.remesh_ops = remesh_ops_;
}

void Simulation::rollback() {
  const std::uint64_t tried_version = cells_.topology_version;
  cells_ = saved_.cells;
  remesh_ops_ = saved_.remesh_ops;
  if (cells_.topology_version != tried_version) {
    // The try remeshed: a version number that nothing has seen, so that the edge list, Γ's
    // pattern and the broad phase's lists are rebuilt rather than taken for the tried meshes'.
    cells_.topology_version = tried_version + 1;
    updateTopology(cells_, topo_);
  }
  // Geometry and contacts are functions of the cells alone (the broad phase's lists give the
  // same sorted candidates whatever they hold), so recomputing them restores them exactly.
  computeGeometry(cells_, geo_);
  detect();
}

StepReport Simulation::step() {
  if (stepper_.adaptive()) saveRollback();
  int rejected = 0;
  FailureKind first_kind = FailureKind::None;
  std::string first_reason;
  for (;;) {
    StepReport rep = tryStep();
    rep.rejected = rejected;
    rep.rejected_kind = first_kind;
    rep.rejected_reason = first_reason;
    if (rep.ok()) {
      const int level = stepper_.level();
      stepper_.accept();
      if (stepper_.level() != level) resetGuardCounts();
      return rep;
    }
    if (!stepper_.canHalve()) {
      if (stepper_.adaptive()) {
        std::ostringstream why;
        why << rep.reason << "; still failing at dt = " << rep.dt
            << " s, the floor numerics.dt_min_s, after " << rejected << " halvings";
        rep.reason = why.str();
      }
      return rep;
    }
    if (rejected == 0) {
      first_kind = rep.failure;
      first_reason = std::move(rep.reason);
    }
    rollback();
    stepper_.halve();
    resetGuardCounts();  // consecutive-step counts at another Δt say nothing about this one
    ++rejected;
    ++steps_rejected_;
  }
}

StepReport Simulation::tryStep() {
  StepReport rep;
  const double dt = stepper_.dt();
  rep.dt = dt;
  rep.contacts = static_cast<int>(contacts_.pairs.size());
  const StepContext ctx = context();  // geometry and contacts of the start of the step

  auto t0 = Clock::now();
  integrator_.computeForces(ctx, terms_, f_);
  times_.forces += since(t0);
  t0 = Clock::now();
  integrator_.prepareFriction(ctx, terms_);
  times_.matrix += since(t0);
  t0 = Clock::now();
  v_ = Eigen::Map<const Eigen::VectorXd>(cells_.v.data(), cells_.v.size());  // warm start
  rep.cg = integrator_.solve(f_, v_);
  times_.solve += since(t0);

  GuardView view{spec_, cells_, geo_};
  view.contacts = with_contacts_ ? &contacts_ : nullptr;
  view.law = &law_;
  view.t = ctx.t;
  view.dt = dt;
  view.v = &v_;
  view.force = &f_;
  view.cg = &rep.cg;
  auto failed = [&rep](StepFailure&& f) {
    rep.failure = f.kind;
    rep.reason = std::move(f.reason);
    return rep;
  };
  // geo_prev_ keeps the start of the step's geometry for the end-of-step updates and the Moved
  // guards; ros2 evaluates its second stage in geo_ and contacts_ (the Solved guards see those).
  const bool two_stage = integrator_.twoStage();
  if (two_stage) {
    std::swap(geo_prev_, geo_);
    if (auto f = secondStage(dt, rep.cg)) return failed(std::move(*f));
    view.step_error_um = step_error_;
  }
  if (auto f = runGuards(StepGuard::Phase::Solved, view)) return failed(std::move(*f));
  if (!two_stage) std::swap(geo_prev_, geo_);

  cells_.v = Eigen::Map<const Eigen::Matrix3Xd>(v_.data(), 3, cells_.numVertices());
  if (two_stage) cells_.x = x0_;
  cells_.x += dt * cells_.v;
  // ε of the start of the step (and of the predicted end, still in geo_, for ros2).
  const StepContext start = atGeometry(ctx, geo_prev_, two_stage ? &geo_ : nullptr);
  for (const auto& term : terms_) term->endStep(start, cells_);
  t0 = Clock::now();
  computeGeometry(cells_, geo_);
  times_.geometry += since(t0);
  view.geo_before = &geo_prev_;
  if (auto f = runGuards(StepGuard::Phase::Moved, view)) return failed(std::move(*f));

  // Remeshing before contact detection: a remesh re-detects the contacts of the new meshes, and
  // detecting before it as well cost a second full detection on every remesh step (50–85 ms of
  // ~500 ms per step on the 2 × 100 fusion, where some cell remeshes almost every step).
  const std::uint64_t topology_before = cells_.topology_version;
  bool all = false;
  const std::vector<char> which =
      remesh_.due(stepper_.ticks() + stepper_.stepTicks(), cells_, geo_, all);
  if (!which.empty()) {
    const StepReport r = remeshCells(which);
    rep.remesh_ops = r.remesh_ops;
    rep.remesh_volume_jump = r.remesh_volume_jump;
  }
  if (cells_.topology_version == topology_before) {
    t0 = Clock::now();
    detect();
    times_.contacts += since(t0);
  }
  view.geo_before = nullptr;  // the meshes may have changed
  if (auto f = runGuards(StepGuard::Phase::Detected, view)) return failed(std::move(*f));
  return rep;
}

StepContext Simulation::atGeometry(const StepContext& c, const Geometry& geo,
                                   const Geometry* geo_end) {
  return {c.cells,
          geo,
          c.topo,
          c.dt,
          c.t,
          c.contacts,
          c.contact_stiffness_dt,
          c.consistent_stiffness,
          c.t_end,
          geo_end};
}

std::optional<StepFailure> Simulation::secondStage(double dt, SolveStats& cg) {
  // Stage 1 must be usable before anything is evaluated at x*: NaNs in the broad phase, or a
  // prediction from an unconverged solve, would only produce a later, less clear failure.
  std::ostringstream why;
  if (!v_.allFinite() || !f_.allFinite()) {
    why << "non-finite " << (f_.allFinite() ? "velocity" : "force")
        << " in the first stage at t=" << time() << " s";
    return StepFailure{FailureKind::NonFinite, why.str()};
  }
  if (!cg.converged) {
    why << "CG did not reach the tolerance " << spec_.numerics.cg_tol << " in " << cg.iterations
        << " iterations in the first stage (relative residual " << cg.residual
        << ") at t=" << time() << " s";
    return StepFailure{FailureKind::CgNotConverged, why.str()};
  }
  x0_ = cells_.x;
  k1_ = Eigen::Map<const Eigen::Matrix3Xd>(v_.data(), 3, cells_.numVertices());
  cells_.x = x0_ + dt * k1_;
  auto t0 = Clock::now();
  computeGeometry(cells_, geo_);
  times_.geometry += since(t0);
  t0 = Clock::now();
  detect();
  times_.contacts += since(t0);

  StepContext predicted = context();
  // The pressure at x* with the PI integral predicted as ROS2 predicts every state variable,
  // I* = I₀ + Δt ε₀; I₀ is restored for the end of the step.
  pi0_ = cells_.pi_integral;
  pressure_->endStep(atGeometry(predicted, geo_prev_, nullptr), cells_);
  t0 = Clock::now();
  integrator_.computeForces(predicted, terms_, f2_);
  times_.forces += since(t0);
  cells_.pi_integral = pi0_;
  // Γ* k₁ without the spring stiffness, then Γ* + γΔt K* for the solve.
  t0 = Clock::now();
  const double stiffness = predicted.contact_stiffness_dt;
  predicted.contact_stiffness_dt = 0;
  integrator_.prepareFriction(predicted, terms_);
  g_.resize(k1_.size());
  integrator_.applyFriction(k1_.data(), g_.data());
  predicted.contact_stiffness_dt = stiffness;
  integrator_.prepareFriction(predicted, terms_);
  times_.matrix += since(t0);
  f2_ -= 2 * Eigen::Map<const Eigen::Matrix3Xd>(g_.data(), 3, cells_.numVertices());
  t0 = Clock::now();
  k2_ = -v_;  // k₂ ≈ −k₁ where the forces change little over the step
  const SolveStats s2 = integrator_.solve(f2_, k2_, /*reuse_factor=*/true);
  times_.solve += since(t0);
  cg.iterations += s2.iterations;
  cg.converged = cg.converged && s2.converged;
  cg.residual = std::max(cg.residual, s2.residual);
  // x₁ − (x₀ + Δt k₁) = Δt/2 (k₁ + k₂): the embedded first-order step's distance, the estimate.
  double e2 = 0;
  for (Eigen::Index i = 0; i < v_.size(); i += 3)
    e2 = std::max(e2, (v_.segment<3>(i) + k2_.segment<3>(i)).squaredNorm());
  step_error_ = 0.5 * dt * std::sqrt(e2);
  v_ = 1.5 * v_ + 0.5 * k2_;  // the step's effective velocity: x₁ = x₀ + Δt v
  return std::nullopt;
}

StepReport Simulation::remeshAll() {
  return remeshCells(std::vector<char>(cells_.numCells(), 1));
}

StepReport Simulation::remeshCells(const std::vector<char>& which) {
  StepReport rep;
  const auto t0 = Clock::now();
  const int tris = static_cast<int>(spec_.numerics.triangles_per_cell);
  const int n = cells_.numCells();
  std::vector<TriMesh> meshes(n);
  std::vector<RemeshStats> stats(n);
  for (int c = 0; c < n; ++c) meshes[c] = cells_.cellMesh(c);
    // Each cell's remesh is independent (remesh() keeps no shared state); the totals are taken in
    // cell order afterwards, so the result does not depend on the thread count.
#pragma omp parallel for schedule(dynamic) if (cells_.numTriangles() > grain().min_items)
  for (int c = 0; c < n; ++c) {
    if (!which[c]) continue;
    const double r = cells_.radius[c];
    const double a_ref = 4 * M_PI * r * r / tris;
    RemeshParams rp;
    rp.min_area = spec_.numerics.remesh_min_area_factor * a_ref;
    rp.max_area = spec_.numerics.remesh_max_area_factor * a_ref;
    rp.smooth_min_angle_deg = 15;
    stats[c] = remesh(meshes[c], rp);
  }
  int ops = 0;
  for (int c = 0; c < n; ++c) {
    if (!which[c]) continue;
    const RemeshStats& st = stats[c];
    ops += st.operations();
    if (st.volume_before > 0)
      rep.remesh_volume_jump = std::max(
          rep.remesh_volume_jump, std::abs(st.volume_after - st.volume_before) / st.volume_before);
  }
  if (ops > 0) {
    // The cells not asked to remesh keep their meshes: their edges are shifted, not rebuilt
    // (if the edge list is that of the meshes before this remesh).
    const bool current = topo_.version == cells_.topology_version;
    std::vector<char> same(which.size());
    for (std::size_t c = 0; c < which.size(); ++c) same[c] = !which[c];
    cells_.setCellMeshes(meshes);
    updateTopology(cells_, topo_, current ? &same : nullptr);
    computeGeometry(cells_, geo_);
    detect();
  }
  rep.remesh_ops = ops;
  remesh_ops_ += ops;
  times_.remesh += std::chrono::duration<double>(Clock::now() - t0).count();
  return rep;
}

}  // namespace activefoam
