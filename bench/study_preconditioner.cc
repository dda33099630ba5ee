// Experiment: which preconditioner pays on the relaxed reduced fusion
// (2 × n cells)? Loads the spheroids from a cache (the fusion study's), runs `warm` steps, then
// for the next 120 steps assembles the full Γ + Δt K_c and solves it (ε_CG of the spec, warm start
// from the previous step's solution) with: Jacobi; a scalar IC(0) on Γ's pattern (the same
// factor as the engine's block IncompleteCholesky) built fresh at every step; the same factor
// kept while the mesh keeps its vertex count (stale: the pattern and values of an older step);
// and Jacobi plus a coarse correction on the cells' translations (additive two-level).
// Eigen's IncompleteCholesky (AMD ordering) is timed once for its setup.
//
//   OMP_NUM_THREADS=1 build/release/bench/study_preconditioner CACHE [n] [dt] [warm] [integrator]
// Results: docs/benchmarks.md, "8. CG iterations".
// The consistent stiffness (integrator `contact-implicit-consistent`): with
// AGG="θ:cap:cross;…" it compares, over 30 steps, block-Jacobi, block symmetric Gauss–Seidel and
// block-Jacobi on aggregates of strongly coupled vertices (coupling ≥ θ, at most `cap` vertices,
// `cross` = 1: partners in other cells only); CG_TOL overrides the spec's ε_CG. Results:
// docs/science/motion-convergence.md, "ε_CG at the consistent step".
// AGG_SETUP="θ:cap": the setup such aggregates would cost built from the engine's own blocks
// (sim.forEachFrictionBlock), over 10 steps: docs/benchmarks.md, "8. CG iterations".
#include <Eigen/Cholesky>
#include <Eigen/IterativeLinearSolvers>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <functional>
#include <map>
#include <string>
#include <vector>

#include "activefoam/simulation.h"
#include "activefoam/spheroid.h"

using namespace activefoam;
using Clock = std::chrono::steady_clock;
static double secs(Clock::time_point a) {
  return std::chrono::duration<double>(Clock::now() - a).count();
}

using Prec = std::function<void(const Eigen::VectorXd&, Eigen::VectorXd&)>;

struct Res {
  int it;
  double ms;
};
static Res pcg(const SpMat& a, const Eigen::VectorXd& b, Eigen::VectorXd& x, const Prec& m,
               double tol) {
  auto t0 = Clock::now();
  Eigen::VectorXd r = b - a * x, z(b.size()), p, q;
  const double bn = b.squaredNorm(), th = tol * tol * bn;
  int it = 0;
  if (r.squaredNorm() >= th) {
    m(r, z);
    p = z;
    double rz = r.dot(z);
    while (it < 5000) {
      q = a * p;
      const double al = rz / p.dot(q);
      x += al * p;
      r -= al * q;
      ++it;
      if (r.squaredNorm() < th) break;
      m(r, z);
      const double rzn = r.dot(z);
      p = z + (rzn / rz) * p;
      rz = rzn;
    }
  }
  return {it, 1e3 * secs(t0)};
}

// IC(0) on the scalar pattern of A (lower part), natural order, with a diagonal shift on breakdown.
struct IC0 {
  std::vector<int> rp, ci;  // CSR of L (cols ≤ row, diag last)
  std::vector<double> v;
  int n = 0;
  double shift = 0;
  void build(const SpMat& a) {
    n = static_cast<int>(a.rows());
    rp.assign(n + 1, 0);
    ci.clear();
    for (int i = 0; i < n; ++i) {
      for (SpMat::InnerIterator it(a, i); it; ++it)
        if (it.col() <= i) ci.push_back(static_cast<int>(it.col()));
      rp[i + 1] = static_cast<int>(ci.size());
    }
    std::vector<double> av(ci.size());
    for (int i = 0; i < n; ++i) {
      int k = rp[i];
      for (SpMat::InnerIterator it(a, i); it; ++it)
        if (it.col() <= i) av[k++] = it.value();
    }
    for (shift = 0;; shift = shift == 0 ? 1e-3 : 2 * shift) {
      v = av;
      bool ok = true;
      for (int i = 0; i < n && ok; ++i) {
        for (int kk = rp[i]; kk < rp[i + 1]; ++kk) {
          const int k = ci[kk];
          double s = v[kk];
          // dot of row i (cols < k) and row k (cols < k)
          int p = rp[i], q = rp[k];
          const int pe = kk, qe = rp[k + 1] - 1;
          while (p < pe && q < qe) {
            if (ci[p] == ci[q])
              s -= v[p++] * v[q++];
            else if (ci[p] < ci[q])
              ++p;
            else
              ++q;
          }
          if (k == i) {
            s *= 1.0;
            const double d = s + shift * av[kk];
            if (!(d > 0)) {
              ok = false;
              break;
            }
            v[kk] = std::sqrt(d);
          } else {
            v[kk] = s / v[rp[k + 1] - 1];
          }
        }
      }
      if (ok) break;
    }
  }
  void apply(const Eigen::VectorXd& r, Eigen::VectorXd& z) const {
    z = r;
    for (int i = 0; i < n; ++i) {
      double s = z[i];
      for (int kk = rp[i]; kk < rp[i + 1] - 1; ++kk) s -= v[kk] * z[ci[kk]];
      z[i] = s / v[rp[i + 1] - 1];
    }
    for (int i = n - 1; i >= 0; --i) {
      z[i] /= v[rp[i + 1] - 1];
      const double zi = z[i];
      for (int kk = rp[i]; kk < rp[i + 1] - 1; ++kk) z[ci[kk]] -= v[kk] * zi;
    }
  }
};

// Block-Jacobi on aggregates of vertices: each vertex joins, in index order, the aggregate of
// its strongest not-yet-aggregated neighbours (block coupling ‖A_ij‖_F ≥ θ √(‖A_ii‖ ‖A_jj‖)),
// up to `cap` vertices; each aggregate's dense block inverted (LDLT). Aggregates that pair an
// interface vertex with its partners across the contact invert the stiff relative mode exactly.
// The presets' 3×3 block-Jacobi of an assembled Γ: each vertex's diagonal block, inverted.
static std::vector<Eigen::Matrix3d> blockJacobi(const SpMat& a) {
  const int nb = static_cast<int>(a.rows() / 3);
  std::vector<Eigen::Matrix3d> bj(nb);
  for (int i = 0; i < nb; ++i) {
    Eigen::Matrix3d d;
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 3; ++c) d(r, c) = a.coeff(3 * i + r, 3 * i + c);
    bj[i] = d.inverse();
  }
  return bj;
}

static Prec applyBlocks(const std::vector<Eigen::Matrix3d>& bj) {
  return [&bj](const Eigen::VectorXd& r, Eigen::VectorXd& z) {
    z.resize(r.size());
    for (std::size_t i = 0; i < bj.size(); ++i) z.segment<3>(3 * i) = bj[i] * r.segment<3>(3 * i);
  };
}

// Greedy aggregation: each vertex not yet taken, in order, takes its strongest partners not yet
// taken (nbr: each vertex's partners, strongest first) while their coupling is ≥ theta, up to
// cap vertices. Returns each vertex's aggregate; members of aggregate g are
// members[agg_begin[g] .. agg_begin[g + 1]).
static std::vector<int> greedyAggregates(
    const std::vector<std::vector<std::pair<int, double>>>& nbr, int cap, double theta,
    std::vector<int>& agg_begin, std::vector<int>& members) {
  const int nb = static_cast<int>(nbr.size());
  std::vector<int> of(nb, -1);
  agg_begin.assign(1, 0);
  members.clear();
  for (int i = 0; i < nb; ++i) {
    if (of[i] >= 0) continue;
    const int id = static_cast<int>(agg_begin.size()) - 1;
    of[i] = id;
    members.push_back(i);
    int size = 1;
    for (const auto& [j, w] : nbr[i]) {
      if (size >= cap || w < theta) break;
      if (of[j] >= 0) continue;
      of[j] = id;
      members.push_back(j);
      ++size;
    }
    agg_begin.push_back(static_cast<int>(members.size()));
  }
  return of;
}

struct AggregateJacobi {
  std::vector<int> agg_begin, members;  // members of aggregate a: [agg_begin[a], agg_begin[a+1])
  std::vector<Eigen::LDLT<Eigen::MatrixXd>> inv;
  int cross = 0;  // aggregates spanning two cells
  void build(const SpMat& a, double theta, int cap, const std::vector<int>& vcell,
             bool cross_only) {
    const int nb = static_cast<int>(a.rows() / 3);
    std::vector<std::vector<std::pair<int, double>>> nbr(nb);
    std::vector<double> dn(nb, 0);
    {
      std::vector<std::map<int, Eigen::Matrix3d>> rows(nb);
      for (int i = 0; i < a.rows(); ++i)
        for (SpMat::InnerIterator it(a, i); it; ++it) {
          auto& m = rows[i / 3]
                        .try_emplace(static_cast<int>(it.col() / 3), Eigen::Matrix3d::Zero())
                        .first->second;
          m(i % 3, it.col() % 3) = it.value();
        }
      for (int i = 0; i < nb; ++i) dn[i] = rows[i].at(i).norm();
      for (int i = 0; i < nb; ++i)
        for (const auto& [j, m] : rows[i])
          if (j != i && (!cross_only || vcell[i] != vcell[j])) {
            const double w = m.norm() / std::sqrt(dn[i] * dn[j]);
            if (w >= theta) nbr[i].emplace_back(j, w);
          }
      for (auto& v : nbr)
        std::sort(v.begin(), v.end(), [](auto& x, auto& y) { return x.second > y.second; });
    }
    greedyAggregates(nbr, cap, 0.0, agg_begin, members);  // nbr holds the pairs ≥ θ only
    cross = 0;
    for (std::size_t g = 0; g + 1 < agg_begin.size(); ++g) {
      bool spans = false;
      for (int q = agg_begin[g] + 1; q < agg_begin[g + 1]; ++q)
        spans = spans || vcell[members[q]] != vcell[members[agg_begin[g]]];
      cross += spans;
    }
    inv.clear();
    const int na = static_cast<int>(agg_begin.size()) - 1;
    inv.reserve(na);
    std::vector<int> local(nb, -1);
    for (int g = 0; g < na; ++g) {
      const int b0 = agg_begin[g], sz = agg_begin[g + 1] - b0;
      for (int k = 0; k < sz; ++k) local[members[b0 + k]] = k;
      Eigen::MatrixXd d = Eigen::MatrixXd::Zero(3 * sz, 3 * sz);
      for (int k = 0; k < sz; ++k) {
        const int v = members[b0 + k];
        for (int r = 0; r < 3; ++r)
          for (SpMat::InnerIterator it(a, 3 * v + r); it; ++it) {
            const int l = local[it.col() / 3];
            if (l >= 0) d(3 * k + r, 3 * l + it.col() % 3) = it.value();
          }
      }
      inv.emplace_back(d);
      for (int k = 0; k < sz; ++k) local[members[b0 + k]] = -1;
    }
  }
  void apply(const Eigen::VectorXd& r, Eigen::VectorXd& z) const {
    z.resize(r.size());
    const int na = static_cast<int>(agg_begin.size()) - 1;
    for (int g = 0; g < na; ++g) {
      const int b0 = agg_begin[g], sz = agg_begin[g + 1] - b0;
      Eigen::VectorXd rg(3 * sz);
      for (int k = 0; k < sz; ++k) rg.segment<3>(3 * k) = r.segment<3>(3 * members[b0 + k]);
      const Eigen::VectorXd zg = inv[g].solve(rg);
      for (int k = 0; k < sz; ++k) z.segment<3>(3 * members[b0 + k]) = zg.segment<3>(3 * k);
    }
  }
};

int main(int argc, char** argv) {
  if (argc < 2) {
    std::fprintf(stderr, "usage: study_preconditioner CACHE [n] [dt] [warm] [integrator]\n");
    return 2;
  }
  const SpheroidCache cache(argv[1]);
  const int n = argc > 2 ? std::atoi(argv[2]) : 30;
  const double dt = argc > 3 ? std::atof(argv[3]) : 0.5;
  const int warm = argc > 4 ? std::atoi(argv[4]) : 200;
  const std::string integ = argc > 5 ? argv[5] : "contact-implicit";
  SceneSpec base;
  base.scene = SceneKind::Fusion;
  base.seed = 1;
  base.scene_params.n_cells = n;
  base.scene_params.prep_max_s = 600;
  base.numerics.triangles_per_cell = 320;
  base.numerics.dt_s = dt;
  base.numerics.integrator = integ == "ros2" ? IntegratorKind::Ros2
                             : integ == "contact-implicit-consistent"
                                 ? IntegratorKind::ContactImplicitConsistent
                                 : IntegratorKind::ContactImplicit;
  base = resolve(base);
  const CellSet cells = buildFusionCells(
      base, &cache, {[](const std::string& l) { std::fprintf(stderr, "%s\n", l.c_str()); }});
  Simulation sim(base, cells);
  auto t0 = Clock::now();
  for (int k = 0; k < warm; ++k)
    if (!sim.step().ok()) return 1;
  std::fprintf(stderr, "warm %d steps %.1f s, t=%g\n", warm, secs(t0), sim.time());

  auto system = [&](SpMat& a, Eigen::VectorXd& b) {
    Eigen::Matrix3Xd f;
    sim.computeForces(f);
    b = Eigen::Map<const Eigen::VectorXd>(f.data(), f.size());
    a = sim.assembleFriction();
  };
  SpMat a0;
  Eigen::VectorXd b0;
  system(a0, b0);
  const Eigen::Index m = a0.rows();
  std::printf("unknowns %ld nnz %ld pairs %zu\n", long(m), long(a0.nonZeros()),
              sim.contacts().pairs.size());
  const double tol =
      std::getenv("CG_TOL") ? std::atof(std::getenv("CG_TOL")) : base.numerics.cg_tol;
  // Fresh IC(0)
  auto t1 = Clock::now();
  IC0 ic;
  ic.build(a0);
  const double ic_setup = 1e3 * secs(t1);
  std::printf("IC0 setup %.1f ms shift %g nnzL %zu\n", ic_setup, ic.shift, ic.v.size());
  // Eigen IC
  t1 = Clock::now();
  Eigen::IncompleteCholesky<double, Eigen::Lower, Eigen::AMDOrdering<int>> eic;
  Eigen::SparseMatrix<double> a0c = a0;
  eic.compute(a0c);
  std::printf("Eigen IC setup %.1f ms\n", 1e3 * secs(t1));

  // coarse: per-cell translation
  const CellSet& cs = sim.cells();
  const int nc = cs.numCells();
  const std::vector<int>& vcell = cs.vertex_cell;
  auto coarse = [&](const SpMat& a) {
    Eigen::MatrixXd ac = Eigen::MatrixXd::Zero(3 * nc, 3 * nc);
    for (int i = 0; i < a.rows(); ++i)
      for (SpMat::InnerIterator it(a, i); it; ++it)
        ac(3 * vcell[i / 3] + i % 3, 3 * vcell[it.col() / 3] + it.col() % 3) += it.value();
    return Eigen::LDLT<Eigen::MatrixXd>(ac);
  };
  auto addCoarse = [&](const Eigen::LDLT<Eigen::MatrixXd>& l, const Eigen::VectorXd& r,
                       Eigen::VectorXd& z) {
    Eigen::VectorXd rc = Eigen::VectorXd::Zero(3 * nc);
    for (Eigen::Index i = 0; i < r.size(); ++i) rc[3 * vcell[i / 3] + i % 3] += r[i];
    const Eigen::VectorXd zc = l.solve(rc);
    for (Eigen::Index i = 0; i < r.size(); ++i) z[i] += zc[3 * vcell[i / 3] + i % 3];
  };

  if (const char* spec = std::getenv("AGG_SETUP")) {
    // AGG_SETUP="θ:cap": what aggregate block-Jacobi's setup would cost inside a step, built the
    // way the engine could build it — from the friction operator's blocks (the assembled
    // diagonal and the couplings the product applies, sim.forEachFrictionBlock), not from an
    // assembled matrix: one pass summing each vertex pair's coupling strength (Frobenius norms,
    // a heuristic: the norm of the sum is not needed to choose partners), the greedy
    // aggregation, a second pass summing the blocks inside aggregates, and an LDLT factor per
    // aggregate (AggregateJacobi's, which then preconditions CG). Then its CG iterations on the
    // assembled Γ against block-Jacobi's. 10 steps.
    double theta = 0.1;
    int cap = 8;
    std::sscanf(spec, "%lf:%d", &theta, &cap);
    double t_emit = 0, t_pass1 = 0, t_greedy = 0, t_pass2 = 0, it_bj = 0, it_agg = 0;
    long blocks = 0;
    double mean_size = 0;
    Eigen::VectorXd xprev;
    const int steps = 10;
    for (int k = 0; k < steps; ++k) {
      if (!sim.step().ok()) return 1;
      sim.prepareFriction();
      const int nb = static_cast<int>(sim.cells().numVertices());
      // The block stream alone.
      auto c0 = Clock::now();
      long nblk = 0;
      sim.forEachFrictionBlock([&](int, int, const Eigen::Matrix3d&) { ++nblk; });
      t_emit += 1e3 * secs(c0);
      blocks += nblk;
      // Pass 1: diagonal norms and summed off-diagonal strengths per row (small linear lists).
      c0 = Clock::now();
      std::vector<double> dn(nb, 0);
      std::vector<std::vector<std::pair<int, double>>> nbr(nb);
      sim.forEachFrictionBlock([&](int i, int j, const Eigen::Matrix3d& m) {
        if (i == j) {
          dn[i] += m.norm();
          return;
        }
        const double w = m.norm();
        for (int side = 0; side < 2; ++side) {
          const int r = side ? j : i, c = side ? i : j;
          auto& row = nbr[r];
          auto hit = std::find_if(row.begin(), row.end(), [&](auto& e) { return e.first == c; });
          if (hit == row.end())
            row.emplace_back(c, w);
          else
            hit->second += w;
        }
      });
      t_pass1 += 1e3 * secs(c0);
      // Greedy aggregation, strongest partners first.
      c0 = Clock::now();
      std::vector<int> of, agg_begin, members;
      for (int i = 0; i < nb; ++i) {
        auto& row = nbr[i];
        for (auto& e : row) e.second /= std::sqrt(dn[i] * dn[e.first]);
        std::sort(row.begin(), row.end(), [](auto& x, auto& y) { return x.second > y.second; });
      }
      of = greedyAggregates(nbr, cap, theta, agg_begin, members);
      t_greedy += 1e3 * secs(c0);
      // Pass 2: the blocks inside each aggregate, then its factor.
      c0 = Clock::now();
      const int na = static_cast<int>(agg_begin.size()) - 1;
      std::vector<int> local(nb);
      for (int g = 0; g < na; ++g)
        for (int q = agg_begin[g]; q < agg_begin[g + 1]; ++q) local[members[q]] = q - agg_begin[g];
      std::vector<Eigen::MatrixXd> dense(na);
      for (int g = 0; g < na; ++g) {
        const int sz = agg_begin[g + 1] - agg_begin[g];
        dense[g] = Eigen::MatrixXd::Zero(3 * sz, 3 * sz);
      }
      sim.forEachFrictionBlock([&](int i, int j, const Eigen::Matrix3d& m) {
        if (of[i] != of[j]) return;
        Eigen::MatrixXd& d = dense[of[i]];
        d.block<3, 3>(3 * local[i], 3 * local[j]) += m;
        if (i != j) d.block<3, 3>(3 * local[j], 3 * local[i]) += m.transpose();
      });
      AggregateJacobi ag;  // its apply; the factors are timed here
      ag.agg_begin = agg_begin;
      ag.members = members;
      ag.inv.reserve(na);
      for (int g = 0; g < na; ++g) ag.inv.emplace_back(dense[g]);
      t_pass2 += 1e3 * secs(c0);
      mean_size += double(nb) / na;
      // Iterations on the assembled Γ: block-Jacobi (3×3) against these aggregates.
      SpMat a;
      Eigen::VectorXd b;
      system(a, b);
      if (xprev.size() != a.rows()) xprev = Eigen::VectorXd::Zero(a.rows());
      const std::vector<Eigen::Matrix3d> bj = blockJacobi(a);
      Eigen::VectorXd x = xprev;
      const Res r0 = pcg(a, b, x, applyBlocks(bj), tol);
      const Eigen::VectorXd xs = x;
      x = xprev;
      const Res r1 = pcg(
          a, b, x, [&](const Eigen::VectorXd& r, Eigen::VectorXd& z) { ag.apply(r, z); }, tol);
      it_bj += r0.it;
      it_agg += r1.it;
      xprev = xs;
    }
    std::printf(
        "aggregate setup (θ %g, cap %d), mean over %d steps: %.0f blocks; emitting them %.2f ms; "
        "pass 1 (strengths) %.2f ms; greedy %.2f ms; pass 2 + factors %.2f ms; mean aggregate "
        "%.2f vertices; CG iterations block-Jacobi %.1f, aggregates %.1f\n",
        theta, cap, steps, double(blocks) / steps, t_emit / steps, t_pass1 / steps,
        t_greedy / steps, t_pass2 / steps, mean_size / steps, it_bj / steps, it_agg / steps);
    return 0;
  }

  if (const char* spec = std::getenv("AGG")) {
    // AGG="θ:cap:cross_only;…": block-Jacobi (3×3) against aggregate block-Jacobi, 30 steps.
    struct Cfg {
      double theta;
      int cap;
      bool cross;
    };
    std::vector<Cfg> cfgs;
    for (std::string rest = spec; !rest.empty();) {
      const auto semi = rest.find(';');
      const std::string one = rest.substr(0, semi);
      rest = semi == std::string::npos ? "" : rest.substr(semi + 1);
      Cfg c{};
      int cr = 0;
      if (std::sscanf(one.c_str(), "%lf:%d:%d", &c.theta, &c.cap, &cr) == 3) {
        c.cross = cr != 0;
        cfgs.push_back(c);
      }
    }
    std::vector<long> its(cfgs.size() + 1, 0);
    std::vector<double> ms(cfgs.size() + 1, 0), setup(cfgs.size() + 1, 0), sizes(cfgs.size(), 0);
    int steps = 0;
    long sgs_it = 0;
    double sgs_ms = 0;
    Eigen::VectorXd xprev;
    for (int k = 1; k <= 30; ++k) {
      if (!sim.step().ok()) return 1;
      SpMat a;
      Eigen::VectorXd b;
      system(a, b);
      if (xprev.size() != a.rows()) xprev = Eigen::VectorXd::Zero(a.rows());
      const int nb = static_cast<int>(a.rows() / 3);
      // 3×3 block-Jacobi (the presets')
      t1 = Clock::now();
      const std::vector<Eigen::Matrix3d> bj = blockJacobi(a);
      setup[0] += 1e3 * secs(t1);
      Eigen::VectorXd x = xprev;
      const Res r0 = pcg(a, b, x, applyBlocks(bj), tol);
      const Eigen::VectorXd xs = x;
      its[0] += r0.it;
      ms[0] += r0.ms;
      std::printf("step %d pairs %zu: block-jacobi %d", k, sim.contacts().pairs.size(), r0.it);
      {
        // Block symmetric Gauss–Seidel: M = (D + L) D⁻¹ (D + L)ᵀ, natural order, no factor.
        x = xprev;
        const Res rs = pcg(
            a, b, x,
            [&](const Eigen::VectorXd& r, Eigen::VectorXd& z) {
              z.resize(r.size());
              Eigen::VectorXd y(r.size());
              for (int i = 0; i < nb; ++i) {  // (D + L) y = r
                Eigen::Vector3d s = r.segment<3>(3 * i);
                for (int rr = 0; rr < 3; ++rr)
                  for (SpMat::InnerIterator it(a, 3 * i + rr); it; ++it)
                    if (it.col() < 3 * i) s[rr] -= it.value() * y[it.col()];
                y.segment<3>(3 * i) = bj[i] * s;
              }
              for (int i = nb - 1; i >= 0; --i) {  // (D + U) z = D y
                Eigen::Vector3d s = Eigen::Vector3d::Zero();
                for (int rr = 0; rr < 3; ++rr)
                  for (SpMat::InnerIterator it(a, 3 * i + rr); it; ++it)
                    if (it.col() >= 3 * i + 3) s[rr] += it.value() * z[it.col()];
                z.segment<3>(3 * i) = y.segment<3>(3 * i) - bj[i] * s;
              }
            },
            tol);
        sgs_it += rs.it;
        sgs_ms += rs.ms;
        std::printf(" | block-SGS %d", rs.it);
      }
      for (std::size_t c = 0; c < cfgs.size(); ++c) {
        AggregateJacobi ag;
        t1 = Clock::now();
        ag.build(a, cfgs[c].theta, cfgs[c].cap, vcell, cfgs[c].cross);
        setup[c + 1] += 1e3 * secs(t1);
        x = xprev;
        const Res rc = pcg(
            a, b, x, [&](const Eigen::VectorXd& r, Eigen::VectorXd& z) { ag.apply(r, z); }, tol);
        its[c + 1] += rc.it;
        ms[c + 1] += rc.ms;
        sizes[c] += double(nb) / (ag.agg_begin.size() - 1);
        std::printf(" | agg(%g,%d,%d) %d (%d cross of %zu)", cfgs[c].theta, cfgs[c].cap,
                    int(cfgs[c].cross), rc.it, ag.cross, ag.agg_begin.size() - 1);
      }
      std::printf("\n");
      std::fflush(stdout);
      xprev = xs;
      ++steps;
    }
    std::printf(
        "mean over %d steps: block-jacobi %.1f it (%.1f ms solve); block-SGS %.1f it (%.1f ms)",
        steps, double(its[0]) / steps, ms[0] / steps, double(sgs_it) / steps, sgs_ms / steps);
    for (std::size_t c = 0; c < cfgs.size(); ++c)
      std::printf("; agg(θ %g, cap %d, cross %d) %.1f it (%.1f ms solve, mean size %.2f)",
                  cfgs[c].theta, cfgs[c].cap, int(cfgs[c].cross), double(its[c + 1]) / steps,
                  ms[c + 1] / steps, sizes[c] / steps);
    std::printf("\n");
    return 0;
  }
  std::printf("| step | pairs | jacobi | IC0 fresh | IC0 stale (age) | jacobi + coarse |\n");
  Eigen::VectorXd xprev;
  int built_at = 0;
  long sj = 0, sf = 0, ss = 0, sc = 0, steps = 0;
  double tj = 0, tf = 0, ts = 0, tsetup = 0;
  int refreshes = 0;
  for (int k = 1; k <= 120; ++k) {
    if (!sim.step().ok()) return 1;
    SpMat a;
    Eigen::VectorXd b;
    system(a, b);
    Eigen::VectorXd d = a.diagonal().cwiseInverse();
    Prec j = [&](const Eigen::VectorXd& r, Eigen::VectorXd& z) { z = d.cwiseProduct(r); };
    if (xprev.size() != a.rows()) xprev = Eigen::VectorXd::Zero(a.rows());
    Eigen::VectorXd x = xprev;
    const Res rj = pcg(a, b, x, j, tol);
    const Eigen::VectorXd xs = x;
    IC0 icf;
    t1 = Clock::now();
    icf.build(a);
    const double fsetup = 1e3 * secs(t1);
    x = xprev;
    const Res rf = pcg(
        a, b, x, [&](auto& r, auto& z) { icf.apply(r, z); }, tol);
    if (a.rows() != ic.n) {
      ic = icf;
      built_at = k;
      tsetup += fsetup;
      ++refreshes;
    }
    x = xprev;
    Res rs = pcg(
        a, b, x, [&](auto& r, auto& z) { ic.apply(r, z); }, tol);
    const auto lc = coarse(a);
    x = xprev;
    const Res rc = pcg(
        a, b, x,
        [&](auto& r, auto& z) {
          z = d.cwiseProduct(r);
          addCoarse(lc, r, z);
        },
        tol);
    sc += rc.it;
    std::printf(
        "| %d | %zu | %d (%.1f ms) | %d (%.1f ms, setup %.0f) | %d (%.1f ms, age %d) | "
        "%d (%.1f ms) |\n",
        k, sim.contacts().pairs.size(), rj.it, rj.ms, rf.it, rf.ms, fsetup, rs.it, rs.ms,
        k - built_at, rc.it, rc.ms);
    std::fflush(stdout);
    sj += rj.it;
    sf += rf.it;
    ss += rs.it;
    ++steps;
    tj += rj.ms;
    tf += rf.ms + fsetup;
    ts += rs.ms;
    xprev = xs;
  }
  std::printf(
      "mean: jacobi %.1f it %.1f ms; fresh %.1f it %.1f ms incl setup; stale %.1f it "
      "%.1f ms + setup %.1f ms/step (%d refreshes); jacobi + coarse %.1f it\n",
      double(sj) / steps, tj / steps, double(sf) / steps, tf / steps, double(ss) / steps,
      ts / steps, tsetup / steps, refreshes, double(sc) / steps);
  return 0;
}
