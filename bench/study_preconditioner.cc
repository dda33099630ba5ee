// Experiment (issue 15 item 2): which preconditioner pays on the relaxed reduced fusion
// (2 × n cells)? Loads the spheroids from a cache (the fusion study's), runs `warm` steps, then
// for the next 120 steps assembles the full Γ + Δt K_c and solves it (ε_CG of the spec, warm start
// from the previous step's solution) with: Jacobi; a scalar IC(0) on Γ's pattern (the same
// factor as the engine's block IncompleteCholesky) built fresh at every step; the same factor
// kept while the mesh keeps its vertex count (stale: the pattern and values of an older step);
// and Jacobi plus a coarse correction on the cells' translations (additive two-level).
// Eigen's IncompleteCholesky (AMD ordering) is timed once for its setup.
//
//   OMP_NUM_THREADS=1 build/release/bench/study_preconditioner CACHE [n] [dt] [warm]
// Results: docs/benchmarks.md, "Preconditioners".
#include <Eigen/Cholesky>
#include <Eigen/IterativeLinearSolvers>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <functional>
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
  base.numerics.integrator =
      integ == "ros2" ? IntegratorKind::Ros2 : IntegratorKind::ContactImplicit;
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
  const double tol = base.numerics.cg_tol;
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
