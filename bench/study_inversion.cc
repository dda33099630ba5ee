// What makes a triangle invert within one step of the motile fusion (docs/science/
// motion-convergence.md, "The contact law"): steps the 2 × N fusion without the adaptive step
// until a step fails, then describes the failing triangle as it was before the step — its shape
// (area, smallest height, largest angle), how far its corners moved in the step, its contact
// pairs — against the same quantities over all triangles (quantiles). Without the adaptive step
// the run ends at its first failure: max_events > 1 only matters for failures other runs would
// survive.
//
//   OMP_NUM_THREADS=1 build/release/bench/study_inversion CACHE [n_cells] [prep_max_s] [config]
//       [t_end_s] [max_events] [scan_every]
// scan_every > 0: every that many steps, a CSV row on stderr of the pairs whose mean gap is far
// below zero (t, pairs, below −h0, below −0.3 µm, below −1 µm, the deepest gap, its n̂_A·n̂_B and
// force, the median n̂_A·n̂_B of the pairs below −0.3 µm, the 99 % quantile of n̂_A·n̂_B, the
// share of the contact area in pairs with n̂_A·n̂_B > −0.5 and > −0.2).
// config as study_fusion_cost's (default contact-implicit-consistent:1:block-jacobi:1e-3).
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>

#include <Eigen/SparseCholesky>

#include "activefoam/simulation.h"
#include "activefoam/spheroid.h"
#include "scheme_config.h"

using namespace activefoam;

namespace {

struct Shape {
  double area, min_height, max_angle_deg, longest;
};

Shape shapeOf(const Eigen::Matrix3Xd& x, const Tri& t) {
  const Vec3 p[3] = {x.col(t[0]), x.col(t[1]), x.col(t[2])};
  Shape s{};
  s.area = 0.5 * (p[1] - p[0]).cross(p[2] - p[0]).norm();
  double longest = 0, max_angle = 0;
  for (int i = 0; i < 3; ++i) {
    const Vec3 e = p[(i + 1) % 3] - p[i];
    longest = std::max(longest, e.norm());
    const Vec3 u = p[(i + 1) % 3] - p[i], w = p[(i + 2) % 3] - p[i];
    const double c = u.dot(w) / (u.norm() * w.norm());
    max_angle = std::max(max_angle, std::acos(std::clamp(c, -1.0, 1.0)) * 180 / M_PI);
  }
  s.longest = longest;
  s.min_height = longest > 0 ? 2 * s.area / longest : 0;
  s.max_angle_deg = max_angle;
  return s;
}

double quantile(std::vector<double> v, double q) {
  if (v.empty()) return 0;
  std::sort(v.begin(), v.end());
  return v[static_cast<std::size_t>(q * (v.size() - 1))];
}

// The rank of `x` in `all` as a fraction (0: smallest).
double rank(const std::vector<double>& all, double x) {
  return all.empty()
             ? 0
             : double(std::count_if(all.begin(), all.end(), [&](double y) { return y < x; })) /
                   all.size();
}

// The pairs of a contact list that report a gap far below zero: how many, how deep, and how
// their triangles face each other (n̂_A·n̂_B: −1 antiparallel, 0 perpendicular).
void scan(double t, const CellSet& cells, const Geometry& geo, const ContactList& con, double h0) {
  int below_h0 = 0, below_03 = 0, below_1 = 0;
  double deepest = 0, dot_deepest = 0, force_deepest = 0;
  std::vector<double> dots_deep, dots_all;
  for (const ContactPair& p : con.pairs) {
    const double d = geo.tri_normal[p.ta].dot(geo.tri_normal[p.tb]);
    dots_all.push_back(d);
    if (p.c.mean_gap < -h0) ++below_h0;
    if (p.c.mean_gap < -0.3) ++below_03, dots_deep.push_back(d);
    if (p.c.mean_gap < -1) ++below_1;
    if (p.c.mean_gap < deepest)
      deepest = p.c.mean_gap, dot_deepest = d,
      force_deepest =
          std::abs(p.c.force_weight_a[0] + p.c.force_weight_a[1] + p.c.force_weight_a[2]);
  }
  (void)cells;
  // The share of the contact area in pairs that face each other at more than 60° and 78°
  // (n̂_A·n̂_B > −0.5, > −0.2).
  double area = 0, area_60 = 0, area_78 = 0;
  for (const ContactPair& p : con.pairs) {
    const double d = geo.tri_normal[p.ta].dot(geo.tri_normal[p.tb]);
    area += p.c.area;
    if (d > -0.5) area_60 += p.c.area;
    if (d > -0.2) area_78 += p.c.area;
  }
  char line[400];
  std::snprintf(line, sizeof line, "%.0f,%zu,%d,%d,%d,%.3g,%.3f,%.3g,%.3f,%.3f,%.4f,%.4f\n", t,
                con.pairs.size(), below_h0, below_03, below_1, deepest, dot_deepest, force_deepest,
                dots_deep.empty() ? 0.0 : quantile(dots_deep, 0.5), quantile(dots_all, 0.99),
                area > 0 ? area_60 / area : 0.0, area > 0 ? area_78 / area : 0.0);
  std::fputs(line, stderr);
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 2) {
    std::fprintf(stderr,
                 "usage: study_inversion CACHE_DIR [n_cells] [prep_max_s] [config] [t_end_s] "
                 "[max_events]\n");
    return 2;
  }
  const SpheroidCache cache(argv[1]);
  const int n = argc > 2 ? std::atoi(argv[2]) : 20;
  const double prep = argc > 3 ? std::atof(argv[3]) : 600;
  const std::string config = argc > 4 ? argv[4] : "contact-implicit-consistent:1:block-jacobi:1e-3";
  const double t_end = argc > 5 ? std::atof(argv[5]) : 5400;
  const int max_events = argc > 6 ? std::atoi(argv[6]) : 1;
  SceneSpec s;
  bench::SchemeConfig scheme;
  if (const std::string error = bench::fusionSpec(config, n, prep, s, scheme); !error.empty()) {
    std::fprintf(stderr, "%s: %s\n", config.c_str(), error.c_str());
    return 2;
  }
  s.numerics.adaptive = false;  // a failing step returns, and the state before it is ours
  s = resolve(s);
  const CellSet cells0 = buildFusionCells(
      s, &cache, {[](const std::string& l) { std::fprintf(stderr, "%s\n", l.c_str()); }});
  Simulation sim(s, cells0, scheme.scheme(s));
  std::printf("# %s, 2 × %d cells, seed 1, without the adaptive step, until t = %g s\n",
              config.c_str(), n, t_end);
  const double h0 = contactRangeH0(s.cells);
  const int scan_every = argc > 7 ? std::atoi(argv[7]) : 0;
  int events = 0;
  std::int64_t steps = 0;
  StepReport prev;
  while (sim.time() < t_end && events < max_events) {
    const std::string before = sim.saveState();
    const CellSet cells_before = sim.cells();
    const Geometry geo_before = sim.geometry();
    const ContactList contacts_before = sim.contacts();
    if (scan_every > 0 && steps % scan_every == 0)
      scan(sim.time(), cells_before, geo_before, contacts_before, h0);
    const StepReport r = sim.step();
    ++steps;
    if (r.ok()) {
      prev = r;
      continue;
    }
    ++events;
    const double t0 = sim.time();
    std::printf("\n## event %d at step %lld, t = %.1f s: %s\n", events,
                static_cast<long long>(steps), t0, r.reason.c_str());
    std::printf(
        "the step before: %d remesh operations at its end (largest |ΔV|/V of a cell "
        "%.3g), %d CG iterations\n",
        prev.remesh_ops, prev.remesh_volume_jump, prev.cg.iterations);
    if (r.failure == FailureKind::InvertedTriangle) {
      const CellSet& after = sim.cells();
      const Geometry& geo = sim.geometry();
      std::vector<double> heights, areas, angles, moves;
      int bad = -1;
      for (int t = 0; t < after.numTriangles(); ++t) {
        const Shape sh = shapeOf(cells_before.x, cells_before.tri[t]);
        heights.push_back(sh.min_height);
        areas.push_back(sh.area);
        angles.push_back(sh.max_angle_deg);
        if (bad < 0 &&
            !(geo.tri_area[t] > 0 && geo.tri_normal[t].dot(geo_before.tri_normal[t]) >= 0))
          bad = t;
      }
      for (int v = 0; v < after.numVertices(); ++v)
        moves.push_back((after.x.col(v) - cells_before.x.col(v)).norm());
      if (bad >= 0) {
        const Tri& tr = cells_before.tri[bad];
        const Shape sh = shapeOf(cells_before.x, tr);
        const Shape sa = shapeOf(after.x, tr);
        int pairs = 0;
        double pair_area = 0;
        for (const ContactPair& p : contacts_before.pairs)
          if (p.ta == bad || p.tb == bad) ++pairs, pair_area += p.c.area;
        std::printf(
            "triangle %d of cell %d, before the step: area %.3g µm² (rank %.3f), smallest "
            "height %.3g µm (rank %.4f), largest angle %.1f° (rank %.4f), longest edge "
            "%.3g µm; after: area %.3g µm², normal turned by %.0f°\n",
            bad, cells_before.tri_cell[bad], sh.area, rank(areas, sh.area), sh.min_height,
            rank(heights, sh.min_height), sh.max_angle_deg, rank(angles, sh.max_angle_deg),
            sh.longest, sa.area,
            std::acos(std::clamp(geo.tri_normal[bad].dot(geo_before.tri_normal[bad]), -1.0, 1.0)) *
                180 / M_PI);
        for (int k = 0; k < 3; ++k) {
          const double m = (after.x.col(tr[k]) - cells_before.x.col(tr[k])).norm();
          std::printf("  corner %d (vertex %d): moved %.3g µm in the step (rank %.5f)\n", k, tr[k],
                      m, rank(moves, m));
        }
        std::printf("  contact pairs before the step: %d (area %.3g µm²)\n", pairs, pair_area);
        // The step's linear system at the state before it, solved exactly: is the corner's jump
        // the system's answer, or CG's error (its tolerance is relative to the whole ‖F‖)?
        const Eigen::Matrix3Xd x_after = after.x;
        sim.loadState(before);
        Eigen::Matrix3Xd f(3, sim.cells().numVertices());
        f.setZero();
        sim.computeForces(f);
        const Eigen::SparseMatrix<double> a = sim.assembleFriction();
        const Eigen::Map<const Eigen::VectorXd> b(f.data(), f.size());
        Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> ldlt(a);
        const Eigen::VectorXd v = ldlt.solve(b);
        std::vector<double> fnorm;
        for (int i = 0; i < f.cols(); ++i) fnorm.push_back(f.col(i).norm());
        const double dt = r.dt;
        for (int k = 0; k < 3; ++k) {
          const int i = tr[k];
          const Vec3 ve = v.segment<3>(3 * i);
          const Vec3 vs = (x_after.col(i) - cells_before.x.col(i)) / dt;
          std::printf(
              "  corner %d: |F| %.3g nN (rank %.5f); exact solve moves it %.3g µm, the "
              "step's CG moved it %.3g µm (difference %.3g µm)\n",
              k, f.col(i).norm(), rank(fnorm, f.col(i).norm()), dt * ve.norm(), dt * vs.norm(),
              dt * (ve - vs).norm());
          // Its contact force alone (S17-S18) and the deepest pair it takes part in.
          Vec3 fc = Vec3::Zero();
          double min_gap = 1e9;
          int n_pairs = 0;
          for (const ContactPair& p : contacts_before.pairs)
            for (int side = 0; side < 2; ++side) {
              const Tri& t = cells_before.tri[side == 0 ? p.ta : p.tb];
              for (int j = 0; j < 3; ++j)
                if (t[j] == i) {
                  fc += (side == 0 ? p.c.force_weight_a[j] : -p.c.force_weight_b[j]) * p.c.normal;
                  min_gap = std::min(min_gap, p.c.mean_gap);
                  ++n_pairs;
                }
            }
          std::printf(
              "    its contact force %.3g nN from %d pairs, the smallest mean gap among "
              "them %.3g µm (h0 %.3g)\n",
              fc.norm(), n_pairs, n_pairs ? min_gap : 0.0, contactRangeH0(s.cells));
        }
        double worst = 0;
        int worst_v = -1;
        for (int i = 0; i < f.cols(); ++i) {
          const double d =
              dt * (v.segment<3>(3 * i) - (x_after.col(i) - cells_before.x.col(i)) / dt).norm();
          if (d > worst) worst = d, worst_v = i;
        }
        std::printf(
            "  largest difference of CG from the exact solve over all vertices: %.3g µm "
            "(vertex %d); |F| q50 %.3g, q99.9 %.3g nN; ldlt %s\n",
            worst, worst_v, quantile(fnorm, 0.5), quantile(fnorm, 0.999),
            ldlt.info() == Eigen::Success ? "ok" : "FAILED");
      }
      std::printf(
          "all triangles before the step: smallest height q01 %.3g, q50 %.3g µm; largest "
          "angle q50 %.1f°, q99.9 %.1f°; vertex moves q50 %.3g, q99.9 %.3g, max %.3g µm\n",
          quantile(heights, 0.01), quantile(heights, 0.5), quantile(angles, 0.5),
          quantile(angles, 0.999), quantile(moves, 0.5), quantile(moves, 0.999),
          quantile(moves, 1.0));
    }
    std::fflush(stdout);
  }
  std::printf("\n# %lld steps, t = %.0f s, %d event(s)\n", static_cast<long long>(steps),
              sim.time(), events);
  return 0;
}
