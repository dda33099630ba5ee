#include "activefoam/simulation.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <sstream>
#include <stdexcept>

#include "activefoam/motility.h"
#include "activefoam/remesh.h"
#include "activefoam/threads.h"

namespace activefoam {
namespace {

using Clock = std::chrono::steady_clock;

}  // namespace

Simulation::Simulation(const SceneSpec& spec) : Simulation(spec, buildScene(spec)) {}

Simulation::Simulation(const SceneSpec& spec, CellSet cells)
    : Simulation(spec, std::move(cells), makeTimeScheme(spec.numerics)) {}

Simulation::Simulation(const SceneSpec& spec, CellSet cells, std::unique_ptr<TimeScheme> scheme)
    : spec_(spec),
      cells_(std::move(cells)),
      stepper_(spec.numerics.dt_s, dtMinS(spec.numerics), spec.numerics.adaptive),
      scheme_(std::move(scheme)),
      solver_(spec.numerics),
      remesh_(spec, stepper_) {
  init();
}

void Simulation::init() {
  const CellParams& p = spec_.cells;
  // The explicit list of terms (ARCHITECTURE.md). Terms whose parameters make them vanish are not
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
    law_.stiffness_moments = scheme_->consistentStiffness();
    law_.kind = spec_.numerics.contact_law;
    terms_.push_back(std::make_unique<ContactAdhesion>());
    const bool implicit = scheme_->contactStiffnessDt(1.0) > 0;
    const bool frictionless =
        p.xi_normal.value_or(p.xi) == 0 && p.xi_tangential.value_or(p.xi) == 0;
    if (implicit || !frictionless) terms_.push_back(std::make_unique<ContactFriction>(p));
    if (p.p_a > 0) terms_.push_back(std::make_unique<ActiveMigration>(p, spec_.seed));
  }
  guards_ = standardGuards(with_contacts_);
  scheme_->addGuards(spec_.numerics, guards_);
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
  return solver_.computeForces(context(), terms_, f);
}

SpMat Simulation::assembleFriction() {
  FrictionOperator op;
  op.reset(cells_.numVertices(), cells_.topology_version);
  const StepContext ctx = context();
  for (const auto& term : terms_) term->addFriction(ctx, op);
  return op.assembled();
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
  saved_.remesh_rescues = remesh_rescues_;
  saved_.remesh_rebuilds = remesh_rebuilds_;
  saved_.remesh_kept_out = remesh_kept_out_;
}

void Simulation::rollback() {
  const std::uint64_t tried_version = cells_.topology_version;
  cells_ = saved_.cells;
  remesh_ops_ = saved_.remesh_ops;
  remesh_rescues_ = saved_.remesh_rescues;
  remesh_rebuilds_ = saved_.remesh_rebuilds;
  remesh_kept_out_ = saved_.remesh_kept_out;
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
        // The halvings of the schedule, not only this step's: a step that starts at the floor
        // (earlier steps halved it) fails "after 0 halvings" of its own.
        why << rep.reason << "; still failing at dt = " << rep.dt
            << " s, the floor numerics.dt_min_s (numerics.dt_s halved " << stepper_.level()
            << " times, " << rejected << " of them in this step)";
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

  // geo_prev_ takes the start of the step's geometry (for the end-of-step updates and the Moved
  // guards) once geo_ moves on: within the scheme if it evaluates elsewhere (ros2's x*; the
  // Solved guards then see that state's contacts), else after the Solved guards.
  SchemeState state{cells_, geo_, geo_prev_, terms_, solver_, f_, v_, times_, [this] { detect(); }};
  state.on_start_solve = &start_solve_;
  v_ = Eigen::Map<const Eigen::VectorXd>(cells_.v.data(), cells_.v.size());  // warm start
  SchemeResult solved = scheme_->solve(state, ctx);
  rep.cg = solved.cg;

  GuardView view{spec_, cells_, geo_};
  view.contacts = with_contacts_ ? &contacts_ : nullptr;
  view.law = &law_;
  view.t = ctx.t;
  view.dt = dt;
  view.v = &v_;
  view.force = &f_;
  view.cg = &rep.cg;
  view.step_error_um = solved.step_error_um;
  auto failed = [&rep](StepFailure&& f) {
    rep.failure = f.kind;
    rep.reason = std::move(f.reason);
    return rep;
  };
  if (solved.failure) return failed(std::move(*solved.failure));
  if (auto f = runGuards(StepGuard::Phase::Solved, view)) return failed(std::move(*f));
  state.keepStart();

  cells_.v = Eigen::Map<const Eigen::Matrix3Xd>(v_.data(), 3, cells_.numVertices());
  scheme_->advance(cells_, dt);
  const StepContext start = atGeometry(ctx, geo_prev_, scheme_->predictedEnd(state));
  for (const auto& term : terms_) term->endStep(start, cells_);
  timed(times_.geometry, [&] { computeGeometry(cells_, geo_); });
  view.geo_before = &geo_prev_;
  if (stepper_.adaptive()) view.cells_before = &saved_.cells;
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
  if (cells_.topology_version == topology_before) timed(times_.contacts, [&] { detect(); });
  view.geo_before = nullptr;  // the meshes may have changed (cells_before keeps its own)
  view.remeshed = &which;
  if (auto f = runGuards(StepGuard::Phase::Detected, view)) return failed(std::move(*f));
  return rep;
}

StepReport Simulation::remeshAll() {
  return remeshCells(std::vector<char>(cells_.numCells(), 1));
}

StepReport Simulation::remeshCells(const std::vector<char>& which) {
  StepReport rep;
  const auto t0 = Clock::now();
  const int n = cells_.numCells();
  std::vector<TriMesh> meshes(n);
  std::vector<RemeshStats> stats(n);
  for (int c = 0; c < n; ++c) meshes[c] = cells_.cellMesh(c);
  // numerics.remesh_keep_out_um: the cells each cell touches (its contacts at the step's start),
  // whose surfaces before this remesh its collapses must not enter. Read-only during the loop,
  // so the result does not depend on the thread count.
  std::vector<std::vector<int>> touching;
  if (spec_.numerics.remesh_keep_out_um > 0) {
    touching.resize(n);
    for (const ContactPair& p : contacts_.pairs) {
      const int a = cells_.tri_cell[p.ta], b = cells_.tri_cell[p.tb];
      if (a == b) continue;
      touching[a].push_back(b);
      touching[b].push_back(a);
    }
    for (auto& list : touching) {
      std::sort(list.begin(), list.end());
      list.erase(std::unique(list.begin(), list.end()), list.end());
    }
  }
  // Each cell's remesh is independent (remesh() keeps no shared state); the totals are taken in
  // cell order afterwards, so the result does not depend on the thread count.
#pragma omp parallel for schedule(dynamic) if (cells_.numTriangles() > grain().min_items)
  for (int c = 0; c < n; ++c) {
    if (!which[c]) continue;
    RemeshParams rp = cellRemeshParams(spec_.numerics, cells_.radius[c]);
    if (rp.keep_out_um > 0 && !touching[c].empty()) {
      rp.keep_out = [this, &others = touching[c]](const Vec3& p) {
        double depth = 0;
        for (int o : others)
          if (windingNumber(cells_, o, p) > 0.5)
            depth = std::max(depth, distanceToSurface(cells_, o, p));
        return depth;
      };
      // The touching cells' vertices before this remesh, which a rebuild must not engulf.
      rp.keep_out_points = [this, &others = touching[c]](std::vector<Vec3>& points) {
        for (int o : others)
          for (int v = cells_.cell_vertex_begin[o]; v < cells_.cell_vertex_begin[o + 1]; ++v)
            points.push_back(cells_.x.col(v));
      };
    }
    stats[c] = remesh(meshes[c], rp);
  }
  int ops = 0;
  for (int c = 0; c < n; ++c) {
    if (!which[c]) continue;
    const RemeshStats& st = stats[c];
    ops += st.operations();
    remesh_rescues_ += st.rescues;
    remesh_rebuilds_ += st.rebuilds;
    remesh_kept_out_ += st.kept_out + st.rebuilds_kept_out;
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
