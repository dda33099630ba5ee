#include "activefoam/integrator.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <sstream>

#include "activefoam/contacts.h"

namespace activefoam {

// ---- TimeStepper ---------------------------------------------------------------------------

TimeStepper::TimeStepper(double dt_s, double dt_min_s, bool adaptive)
    : dt_(dt_s), adaptive_(adaptive) {
  // The deepest halving whose step is still ≥ dt_min (a tolerance of one part in 10⁹ so that
  // dt_min = Δt/64 written in decimal still allows the sixth halving). Non-adaptive runs never
  // halve, and their ticks are whole steps.
  if (adaptive_)
    while (max_level_ < 30 && std::ldexp(dt_, -(max_level_ + 1)) >= dt_min_s * (1 - 1e-9))
      ++max_level_;
  tick_s_ = std::ldexp(dt_, -max_level_);
  setLevel(0);
}

double TimeStepper::minDt() const {
  return std::ldexp(dt_, -max_level_);
}

std::int64_t TimeStepper::baseSteps(double seconds) const {
  return std::llround(seconds / dt_);
}

std::int64_t TimeStepper::ticksFor(double seconds) const {
  return baseSteps(seconds) * ticksPerBaseStep();
}

std::int64_t TimeStepper::periodTicks(double seconds) const {
  return std::max<std::int64_t>(1, baseSteps(seconds)) * ticksPerBaseStep();
}

void TimeStepper::setLevel(int level) {
  level_ = level;
  level_dt_ = std::ldexp(dt_, -level_);  // exact: a power of two
}

void TimeStepper::halve() {
  if (since_growth_ < std::max(4 * wait_, kRecent))  // grew too early
    wait_ = std::min(2 * wait_, kMaxWait);
  setLevel(level_ + 1);
  good_ = 0;
  calm_ = 0;
}

void TimeStepper::accept() {
  ticks_ += stepTicks();
  ++steps_;
  since_growth_ = std::min(since_growth_ + 1, kSaturated);
  if (++calm_ >= 2 * std::max(4 * wait_, kRecent)) {
    wait_ = std::max(wait_ / 2, kGrowAfter);
    calm_ = 0;
  }
  if (level_ > 0 && ++good_ >= wait_ && ticks_ % (2 * stepTicks()) == 0) {
    setLevel(level_ - 1);
    good_ = 0;
    since_growth_ = 0;
  }
}

void TimeStepper::setState(const State& s) {
  ticks_ = s.ticks;
  steps_ = s.steps;
  setLevel(std::clamp<int>(s.level, 0, max_level_));
  good_ = s.good;
  wait_ = std::clamp<int>(s.wait, kGrowAfter, kMaxWait);
  since_growth_ = std::clamp<int>(s.since_growth, 0, kSaturated);
  calm_ = std::max<int>(s.calm, 0);
}

// ---- guards --------------------------------------------------------------------------------

namespace {

std::string at(double t) {
  std::ostringstream os;
  os << " at t=" << t << " s";
  return os.str();
}

class NonFiniteGuard : public StepGuard {
 public:
  std::string_view name() const override { return "non-finite"; }
  Phase phase() const override { return Phase::Solved; }
  std::optional<StepFailure> check(const GuardView& g) override {
    const bool f_ok = g.force->allFinite();
    if (f_ok && g.v->allFinite()) return std::nullopt;
    return StepFailure{FailureKind::NonFinite,
                       std::string("non-finite ") + (f_ok ? "velocity" : "force") + at(g.t)};
  }
};

class CgGuard : public StepGuard {
 public:
  std::string_view name() const override { return "cg-not-converged"; }
  Phase phase() const override { return Phase::Solved; }
  std::optional<StepFailure> check(const GuardView& g) override {
    if (g.cg->converged) return std::nullopt;
    std::ostringstream why;
    why << "CG did not reach the tolerance " << g.spec.numerics.cg_tol << " in " << g.cg->iterations
        << " iterations (relative residual " << g.cg->residual << ")" << at(g.t);
    return StepFailure{FailureKind::CgNotConverged, why.str()};
  }
};

// The period-2 signature of an explicit contact scheme past its stability limit: contacting
// vertices that move by a noticeable fraction of h0 per step mostly reverse their velocity from
// one step to the next, for numerics.max_oscillating_steps steps in a row.
class OscillationGuard : public StepGuard {
 public:
  std::string_view name() const override { return "contact-oscillation"; }
  Phase phase() const override { return Phase::Solved; }
  std::int64_t count() const override { return steps_; }
  void setCount(std::int64_t n) override { steps_ = n; }
  std::optional<StepFailure> check(const GuardView& g) override {
    const ContactList& contacts = *g.contacts;
    const Eigen::VectorXd& v = *g.v;
    const double floor = 0.1 * g.law->h0 / g.dt;  // µm/s
    double dot = 0, norms = 0;
    int moving = 0;
    for (int i = 0; i < g.cells.numVertices(); ++i) {
      if (contacts.vertex_contact_area[i] <= 0) continue;
      const Vec3 now = v.segment<3>(3 * i), before = g.cells.v.col(i);
      if (now.norm() < floor || before.norm() < floor) continue;
      ++moving;
      dot += now.dot(before);
      norms += now.norm() * before.norm();
    }
    steps_ = moving > 0 && dot < -0.5 * norms ? steps_ + 1 : 0;
    if (steps_ < g.spec.numerics.max_oscillating_steps) return std::nullopt;
    std::ostringstream why;
    why << "contact velocities reversed in " << steps_ << " consecutive steps" << at(g.t)
        << ": the contact springs are too stiff for dt = " << g.dt << " s with the "
        << toString(g.spec.numerics.integrator)
        << " integrator (use contact-implicit or a smaller dt)";
    return StepFailure{FailureKind::ContactOscillation, why.str()};
  }

 private:
  std::int64_t steps_ = 0;
};

// A triangle whose normal turned by more than 90° in one step has inverted.
class InvertedTriangleGuard : public StepGuard {
 public:
  std::string_view name() const override { return "inverted-triangle"; }
  Phase phase() const override { return Phase::Moved; }
  std::optional<StepFailure> check(const GuardView& g) override {
    for (int t = 0; t < g.cells.numTriangles(); ++t) {
      if (g.geo.tri_area[t] > 0 && g.geo.tri_normal[t].dot(g.geo_before->tri_normal[t]) >= 0)
        continue;
      std::ostringstream why;
      why << "triangle " << t << " of cell " << g.cells.tri_cell[t] << " inverted" << at(g.t + g.dt)
          << " (time step too large for the forces?)";
      return StepFailure{FailureKind::InvertedTriangle, why.str()};
    }
    return std::nullopt;
  }
};

class VolumeGuard : public StepGuard {
 public:
  std::string_view name() const override { return "volume-drift"; }
  Phase phase() const override { return Phase::Moved; }
  std::optional<StepFailure> check(const GuardView& g) override {
    const double limit = g.spec.numerics.max_volume_error;
    for (int c = 0; c < g.cells.numCells(); ++c) {
      const double v0 = g.cells.target_volume[c];
      const double eps = (g.geo.cell_volume[c] - v0) / v0;
      if (std::abs(eps) <= limit) continue;
      std::ostringstream why;
      why << "cell " << c << " volume error " << eps << " exceeds numerics.max_volume_error "
          << limit << at(g.t + g.dt);
      return StepFailure{FailureKind::VolumeDrift, why.str()};
    }
    return std::nullopt;
  }
};

// Per pair of cells, the area-weighted mean gap of their contact pairs. Single triangle pairs
// are no measure: where two surfaces meet at a rim at ~70° a pair overlaps by a sliver of
// 1e-4 µm² whose mean gap along the pair normal reads −0.5 … −1.6 µm while the cells do not
// overlap (measured on a 2 × 8-cell fusion; it stopped runs at t = 990 s).
class InterpenetrationGuard : public StepGuard {
 public:
  std::string_view name() const override { return "interpenetration"; }
  Phase phase() const override { return Phase::Detected; }
  std::optional<StepFailure> check(const GuardView& g) override {
    std::string why = interpenetration(g.cells, *g.contacts, g.spec.numerics.max_penetration_um,
                                       g.t + g.dt, scratch_);
    if (why.empty()) return std::nullopt;
    return StepFailure{FailureKind::Interpenetration, std::move(why)};
  }

 private:
  std::vector<PairGap> scratch_;
};

}  // namespace

std::string interpenetration(const CellSet& cells, const ContactList& contacts, double limit,
                             double t, std::vector<PairGap>& scratch) {
  scratch.clear();
  for (const ContactPair& p : contacts.pairs) {
    int a = cells.tri_cell[p.ta], b = cells.tri_cell[p.tb];
    if (a > b) std::swap(a, b);
    scratch.push_back({(static_cast<std::uint64_t>(a) << 32) | static_cast<std::uint32_t>(b),
                       p.c.mean_gap * p.c.area, p.c.area});
  }
  // detectContacts lists the pairs grouped by pair of cells already (the broad phase's order):
  // the sort is then skipped.
  const auto by_key = [](const auto& x, const auto& y) { return x.key < y.key; };
  if (!std::is_sorted(scratch.begin(), scratch.end(), by_key))
    std::sort(scratch.begin(), scratch.end(), by_key);
  for (std::size_t i = 0; i < scratch.size();) {
    double gs = 0, area = 0;
    std::size_t j = i;
    for (; j < scratch.size() && scratch[j].key == scratch[i].key; ++j) {
      gs += scratch[j].gap_area;
      area += scratch[j].area;
    }
    if (area > 0 && -gs / area > limit) {
      std::ostringstream why;
      why << "cells " << (scratch[i].key >> 32) << " and " << (scratch[i].key & 0xffffffffULL)
          << " interpenetrate by " << -gs / area
          << " µm on average over their contact > numerics.max_penetration_um = " << limit << " µm"
          << at(t);
      return why.str();
    }
    i = j;
  }
  return {};
}

class StepErrorGuard : public StepGuard {
 public:
  std::string_view name() const override { return "step-error"; }
  Phase phase() const override { return Phase::Solved; }
  std::optional<StepFailure> check(const GuardView& g) override {
    const NumericsParams& n = g.spec.numerics;
    if (!(n.max_step_error_um > 0) || !(g.step_error_um > n.max_step_error_um)) return std::nullopt;
    if (0.5 * g.dt < dtMinS(n)) return std::nullopt;  // at the floor
    std::ostringstream why;
    why << "error estimate " << g.step_error_um << " µm of a " << g.dt
        << " s step exceeds numerics.max_step_error_um = " << n.max_step_error_um << at(g.t);
    return StepFailure{FailureKind::StepError, why.str()};
  }
};

std::unique_ptr<StepGuard> stepErrorGuard() {
  return std::make_unique<StepErrorGuard>();
}

std::vector<std::unique_ptr<StepGuard>> standardGuards(bool with_contacts) {
  std::vector<std::unique_ptr<StepGuard>> g;
  g.push_back(std::make_unique<NonFiniteGuard>());
  g.push_back(std::make_unique<CgGuard>());
  if (with_contacts) g.push_back(std::make_unique<OscillationGuard>());
  g.push_back(std::make_unique<InvertedTriangleGuard>());
  g.push_back(std::make_unique<VolumeGuard>());
  if (with_contacts) g.push_back(std::make_unique<InterpenetrationGuard>());
  return g;
}

// ---- RemeshPolicy ---------------------------------------------------------------------------

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

// ---- Integrator ------------------------------------------------------------------------------

Integrator::Integrator(const NumericsParams& n)
    : kind_(n.integrator),
      solver_(n.preconditioner, n.cg_tol, static_cast<int>(n.cg_max_iter)),
      preconditioner_(n.preconditioner) {}

double Integrator::computeForces(const StepContext& ctx, const Terms& terms,
                                 Eigen::Matrix3Xd& f) const {
  f.setZero(3, ctx.cells.numVertices());
  double energy = 0;
  for (const auto& term : terms) energy += term->addForces(ctx, f);
  return energy;
}

void Integrator::prepareFriction(const StepContext& ctx, const Terms& terms) {
  if (pattern_version_ != ctx.cells.topology_version) {
    // Diagonal blocks only: every coupling (mesh edges, contacts) is applied as a product, so
    // neither remeshing nor contacts coming and going change more than the number of blocks.
    gamma_.setPattern(ctx.cells.numVertices(), {});
    pattern_version_ = ctx.cells.topology_version;
  } else {
    gamma_.setZero();
  }
  if (preconditioner_ == PreconditionerKind::IncompleteCholesky)
    cell_vertex_begin_ = ctx.cells.cell_vertex_begin;  // the factor's groups (solve())
  product_terms_.clear();
  for (const auto& term : terms) {
    if (term->hasCouplingProduct()) {
      term->addFrictionDiagonal(ctx, gamma_);
      product_terms_.push_back(term.get());
    } else {
      term->addFriction(ctx, gamma_);
    }
  }
}

void Integrator::applyFriction(const double* v, double* y) const {
  gamma_.multiply(v, y);
  for (const ForceTerm* t : product_terms_) t->addCouplingProduct(v, y);
}

void Integrator::forEachFrictionBlock(const BlockSink& sink) const {
  gamma_.forEachLowerBlock(sink);
  for (const ForceTerm* t : product_terms_) t->forEachCouplingBlock(sink);
}

SolveStats Integrator::solve(const Eigen::Matrix3Xd& f, Eigen::VectorXd& v, bool reuse_factor) {
  Eigen::Map<const Eigen::VectorXd> b(f.data(), f.size());
  const IncompleteCholesky* factor = nullptr;
  if (preconditioner_ == PreconditionerKind::IncompleteCholesky) {
    if (!reuse_factor || factor_.numBlocks() != gamma_.numBlocks()) {
      // The cells are the factor's groups: its triangular solves run the cells of one colour
      // (no two of them in contact) in parallel.
      const bool ok = factor_.factor(
          gamma_.numBlocks(), [this](const BlockSink& sink) { forEachFrictionBlock(sink); },
          cell_vertex_begin_);
      if (!ok) {
        // Γ is SPD whenever the step is sane; a factor that breaks down at every shift means
        // non-finite entries, which the CG guard reports.
        SolveStats s;
        s.residual = std::numeric_limits<double>::quiet_NaN();
        return s;
      }
    }
    factor = &factor_;
  }
  return solver_.solve([this](const double* in, double* out) { applyFriction(in, out); }, gamma_, b,
                       v, factor);
}

}  // namespace activefoam
