// Where does the fusing aggregate's power go? Fig. 14 of the supplement has cell–cell friction
// "sharply" slowing relative motion over L_η/r 0.25–2 (ξ over a factor 64); ours barely moves
// (docs/science/fig14-reduced/). A run's motion is overdamped: every step solves Γ v = F, so the
// power the forces put in, vᵀF, is dissipated term by term as vᵀΓ_term v; this driver measures
// the shares. (They describe one step, not the response to a change: at the base point friction
// takes the larger share of the cells' translation, yet ξ ÷ 16 barely speeds them —
// docs/science/fig14-friction/.)
//
// Every configuration starts from the same aggregate, prepared once at the base spec's ξ (the
// key=value settings), and is driven by the same polarity noise (one Wiener path per cell, a
// function of time): configurations differ by their L_η/r alone. Every sample_s it takes the
// velocity of the next step, v = Δx/Δt (exactly the solved v of a one-stage integrator; under
// ros2 it is not, and the balance below says so; a step that remeshes is skipped for the next
// one), and prints per configuration and sample:
//   - the dissipation of medium drag, cortex viscosity and the contact friction's tangential
//     and normal parts, nW (nN·µm/s): vᵀΓ_term v with Γ_term built by the term itself from the
//     step's start geometry and contacts;
//   - the contact springs' implicit part Δt vᵀK_c v (contact-implicit integrators: Γ carries it;
//     no dissipation of the model, the spring's force taken at the end of the step);
//   - the power of the forces, vᵀF (= the sum above to the solve's tolerance: the check that Γ
//     is rebuilt as the step used it), and of the active forces alone;
//   - the same dissipations of each cell's affine part of v (translation, rotation, uniform
//     strain: cell-scale motion) and the cortex's and tangential friction's of the rest;
//   - the cortex's dissipation of v less its one-ring mean (vertex-scale jitter);
//   - medium drag's and friction's dissipation of each cell's translation alone;
//   - the RMS speed of the cell centroids and of their motion relative to their contacting
//     neighbours' centroids, µm/min, and the MSRD from t = 0 (pairs in contact then);
//   - the aggregate as a body: the net force and the net torque (about its centroid) of the
//     forces at the step's start, nN and nN·µm (the terms are balanced: both should vanish), the
//     rigid part of v (translation speed, µm/h, and angular speed, °/h: the area-weighted
//     least-squares V + ω × (x − x̄)), and, from the cells' centroids, how far the aggregate's
//     centre has moved since the first sample (µm) and the angle it has turned (°, the rotation
//     that best carries the centroids then onto those now) — remeshing included, which the
//     step's v is not. Without active forces the forces exert no net force or torque, yet the
//     aggregate turns: through the dissipative couplings, the next columns;
//   - the torque the medium drag exerts on v (nN·µm) and, as shares along it (> 0 drives the turn
//     the medium resists), the cortex viscosity's, the contact friction's and the contact
//     springs' implicit part's: Γ v = F with F torque-free, so they sum to the medium's up to
//     the solve's residual (a fifth of it at ε_CG 1e-2, ≤ 6 % at 1e-4: docs/science/jam-day/).
//
//   OMP_NUM_THREADS=1 build/release/bench/study_dissipation CACHE_DIR n_cells seed T_s sample_s
//       integrator:Δt:preconditioner[:ε_CG] l_eta_1[:key=value…][,l_eta_2…] [key=value …]
//
// The key=value settings at the end apply to every configuration and to the preparation; those
// after a configuration's L_η/r to it alone (0.5:cells.eta_m=0.1), the aggregate unchanged.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include "activefoam/contacts.h"
#include "activefoam/friction_operator.h"
#include "activefoam/geometry.h"
#include "activefoam/motility.h"
#include "activefoam/observables.h"
#include "activefoam/probe.h"
#include "activefoam/simulation.h"
#include "activefoam/spec_io.h"
#include "activefoam/spheroid.h"
#include "activefoam/terms.h"
#include "base_point.h"
#include "scheme_config.h"

using namespace activefoam;

namespace {

// The torque about xbar of a term's dissipative forces on v, Σ (x_i − x̄) × (Γ_term v)_i: what the
// term takes out of (or, with the opposite sign, puts into) the aggregate's turning.
Vec3 torqueOf(const ForceTerm& term, const StepContext& ctx, const Eigen::VectorXd& v,
              const Vec3& xbar) {
  FrictionOperator op;
  op.reset(ctx.cells.numVertices(), ctx.cells.topology_version);
  term.addFriction(ctx, op);
  Eigen::VectorXd y(v.size());
  op.apply(v.data(), y.data());
  Vec3 t = Vec3::Zero();
  for (int i = 0; i < ctx.cells.numVertices(); ++i)
    t += (Vec3(ctx.cells.x.col(i)) - xbar).cross(Vec3(y.segment<3>(3 * i)));
  return t;
}

}  // namespace

int main(int argc, char** argv) {
  const auto driver = bench::configDriver(argc, argv, "study_dissipation");
  if (!driver) return 2;
  const bench::BasePoint* point = &driver->point;
  const std::vector<bench::Config>& configs = driver->configs;

  std::printf(
      "config,l_eta_reduced,xi,t_s,p_medium,p_cortex,p_friction_t,p_friction_n,p_spring_implicit,"
      "p_forces,p_active,p_medium_affine,p_cortex_affine,p_friction_t_affine,p_friction_n_affine,"
      "p_cortex_rest,p_friction_t_rest,p_cortex_vertex_scale,p_medium_translation,"
      "p_friction_t_translation,p_friction_n_translation,v_centroid_um_min,v_relative_um_min,"
      "msrd_um2,unique_contacts,wall_s,f_net_nN,torque_net_nN_um,v_rigid_um_h,omega_deg_h,"
      "drift_um,turned_deg,torque_medium_nN_um,torque_cortex_nN_um,torque_friction_nN_um,"
      "torque_springs_nN_um\n");
  for (const bench::Config& config : configs) {
    const double l_eta = config.l_eta;
    bench::SchemeConfig scheme;
    const std::optional<SceneSpec> resolved =
        bench::configSpec(*point, config, driver->step, scheme);
    if (!resolved) return 2;
    const SceneSpec& s = *resolved;
    Simulation sim(s, point->cells, scheme.scheme(s));
    MsrdTracker msrd;
    ContactHistory history;
    const auto t0 = std::chrono::steady_clock::now();
    int k = 0;
    // Terms built on their own: each one's Γ block, nothing else.
    CellParams tangential = s.cells, normal = s.cells;
    tangential.xi_normal = 0.0;
    normal.xi_tangential = 0.0;
    const MediumDrag medium(s.cells);
    const CortexViscosity cortex(s.cells);
    const ContactFriction fric_t(tangential), fric_n(normal);
    CellParams springs_only = s.cells;
    springs_only.xi_normal = 0.0;
    springs_only.xi_tangential = 0.0;
    const ContactFriction springs(springs_only);
    const ActiveMigration act(s.cells, s.seed);
    const ContactFriction fric_all(s.cells);
    std::vector<Vec3> first_centroids;  // the cells' centroids at the first sample
    auto sample = [&]() -> bool {
      sim.detect();
      // The step's start: copies, since the step changes them.
      const CellSet c0 = sim.cells();
      const Geometry g0 = sim.geometry();
      const ContactList con0 = sim.contacts();
      Eigen::Matrix3Xd f;
      sim.computeForces(f);
      const double dt = sim.dt();
      const double stiffness_dt = sim.scheme().contactStiffnessDt(dt);
      const bool consistent = sim.scheme().consistentStiffness();
      const StepReport r = sim.step();
      if (!r.ok()) {
        std::fprintf(stderr, "L_eta %g: failed at t = %g s: %s\n", l_eta, sim.time(),
                     std::string(toString(r.failure)).c_str());
        return false;
      }
      if (sim.cells().topology_version != c0.topology_version ||
          sim.cells().numVertices() != c0.numVertices())
        return true;  // remeshed: the next step gives the velocity
      const int nv = c0.numVertices();
      Eigen::VectorXd v(3 * nv);
      for (int i = 0; i < nv; ++i) v.segment<3>(3 * i) = (sim.cells().x.col(i) - c0.x.col(i)) / dt;
      Topology topo;
      updateTopology(c0, topo);
      StepContext plain{c0, g0, topo, dt, sim.time() - dt, &con0, 0.0};
      plain.consistent_stiffness = consistent;
      StepContext stiff = plain;
      stiff.contact_stiffness_dt = stiffness_dt;
      const double pm = frictionPower(medium, plain, v), pc = frictionPower(cortex, plain, v);
      const double pt = frictionPower(fric_t, plain, v), pn = frictionPower(fric_n, plain, v);
      const double ps = stiffness_dt > 0 ? frictionPower(springs, stiff, v) : 0.0;
      double pf = 0;
      for (int i = 0; i < nv; ++i) pf += v.segment<3>(3 * i).dot(f.col(i));
      // The active forces alone: the migration term's forces at the start.
      double pa = 0;
      Eigen::Matrix3Xd fa = Eigen::Matrix3Xd::Zero(3, nv);
      act.addForces(plain, fa);
      for (int i = 0; i < nv; ++i) pa += v.segment<3>(3 * i).dot(fa.col(i));
      msrd.addSample(plain.t, c0, g0, con0);
      history.add(c0, con0);
      // Each cell's affine part of v (translation, rotation, uniform strain; affinePart): the
      // motion at the cell's scale. What the terms dissipate on it against on the rest says
      // whether the power goes into moving and reshaping whole cells or into finer ripples of
      // their shells.
      const int nc = c0.numCells();
      const Eigen::VectorXd v_aff = affinePart(c0, g0, v);
      Eigen::VectorXd v_move(3 * nv);
      {
        std::vector<Vec3> vm(nc, Vec3::Zero());
        std::vector<double> sw(nc, 0.0);
        for (int i = 0; i < nv; ++i) {
          vm[c0.vertex_cell[i]] += g0.vertex_area[i] * v.segment<3>(3 * i);
          sw[c0.vertex_cell[i]] += g0.vertex_area[i];
        }
        for (int i = 0; i < nv; ++i)
          v_move.segment<3>(3 * i) = vm[c0.vertex_cell[i]] / sw[c0.vertex_cell[i]];
      }
      // Each cell's translation alone: what carries cells apart (the MSRD's motion).
      const double pm_m = frictionPower(medium, plain, v_move),
                   pt_m = frictionPower(fric_t, plain, v_move),
                   pn_m = frictionPower(fric_n, plain, v_move);
      const Eigen::VectorXd v_rest = v - v_aff;
      // The vertex-scale part: v less its one-ring mean (ringJitter).
      const Eigen::VectorXd v_ring = ringJitter(topo, v);
      const double pc_ring = frictionPower(cortex, plain, v_ring);
      const double pm_a = frictionPower(medium, plain, v_aff),
                   pc_a = frictionPower(cortex, plain, v_aff);
      const double pt_a = frictionPower(fric_t, plain, v_aff),
                   pn_a = frictionPower(fric_n, plain, v_aff);
      const double pc_r = frictionPower(cortex, plain, v_rest),
                   pt_r = frictionPower(fric_t, plain, v_rest);
      // Centroid speeds, absolute and relative to the contacting neighbours' mean (the
      // dissipation probe's; this CSV has always printed 0 where no cell touches another).
      const CellSpeeds speeds = cellSpeeds(c0, g0, &con0, v);
      const double rel_speed =
          std::isnan(speeds.relative_rms_um_min) ? 0.0 : speeds.relative_rms_um_min;
      // The aggregate as a body: net force and torque of f, the rigid part of v.
      Vec3 xbar = Vec3::Zero(), vbar = Vec3::Zero(), f_net = Vec3::Zero(), torque = Vec3::Zero();
      double wsum = 0;
      for (int i = 0; i < nv; ++i) {
        const double w = g0.vertex_area[i];
        xbar += w * c0.x.col(i);
        vbar += w * v.segment<3>(3 * i);
        wsum += w;
      }
      xbar /= wsum;
      vbar /= wsum;
      Eigen::Matrix3d inertia = Eigen::Matrix3d::Zero();
      Vec3 ang = Vec3::Zero();
      for (int i = 0; i < nv; ++i) {
        const double w = g0.vertex_area[i];
        const Vec3 rx = c0.x.col(i) - xbar;
        f_net += f.col(i);
        torque += rx.cross(Vec3(f.col(i)));
        inertia += w * (rx.squaredNorm() * Eigen::Matrix3d::Identity() - rx * rx.transpose());
        ang += w * rx.cross(Vec3(v.segment<3>(3 * i)) - vbar);
      }
      const Vec3 omega = inertia.ldlt().solve(ang);
      // Which term turns it: Γ v = F and F exerts no torque, so the medium's torque on v is the
      // others' with the opposite sign. Each printed as its share along the medium's (signed:
      // > 0 drives the turn the medium resists).
      const Vec3 tq_m = torqueOf(medium, plain, v, xbar);
      const Vec3 axis = tq_m.norm() > 0 ? Vec3(tq_m.normalized()) : Vec3::UnitX();
      const double tq_c = -torqueOf(cortex, plain, v, xbar).dot(axis);
      const double tq_f = -torqueOf(fric_all, plain, v, xbar).dot(axis);
      const double tq_s = stiffness_dt > 0 ? -torqueOf(springs, stiff, v, xbar).dot(axis) : 0.0;
      // Since the first sample, from the cells' centroids (the remesher's moves included).
      std::vector<Vec3> cen(nc, Vec3::Zero());
      {
        std::vector<double> cw(nc, 0.0);
        for (int i = 0; i < nv; ++i) {
          const int c = c0.vertex_cell[i];
          cen[c] += g0.vertex_area[i] * c0.x.col(i);
          cw[c] += g0.vertex_area[i];
        }
        for (int c = 0; c < nc; ++c) cen[c] /= cw[c];
      }
      if (first_centroids.empty()) first_centroids = cen;
      double drift = 0, turned = 0;
      if (static_cast<int>(first_centroids.size()) == nc) {
        Vec3 m0 = Vec3::Zero(), m1 = Vec3::Zero();
        for (int c = 0; c < nc; ++c) {
          m0 += first_centroids[c];
          m1 += cen[c];
        }
        m0 /= nc;
        m1 /= nc;
        drift = (m1 - m0).norm();
        turned = rotationAngle(bestRotation(first_centroids, cen)) * 180 / M_PI;
      }
      const double wall =
          std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
      std::printf(
          "%s,%g,%.6g,%g,%.6g,%.6g,%.6g,%.6g,%.6g,%.6g,%.6g,%.6g,%.6g,%.6g,%.6g,%.6g,%.6g,%.6g,%."
          "6g,"
          "%.6g,%.6g,%.6g,%.6g,%.6g,%.6g,%.1f,%.6g,%.6g,%.6g,%.6g,%.6g,%.6g,%.6g,%.6g,%.6g,%.6g\n",
          config.label.c_str(), l_eta, s.cells.xi, plain.t, pm, pc, pt, pn, ps, pf, pa, pm_a, pc_a,
          pt_a, pn_a, pc_r, pt_r, pc_ring, pm_m, pt_m, pn_m, speeds.rms_um_min, rel_speed,
          msrd.msrd(k), history.normalized(), wall, f_net.norm(), torque.norm(), 3600 * vbar.norm(),
          3600 * omega.norm() * 180 / M_PI, drift, turned, tq_m.norm(), tq_c, tq_f, tq_s);
      std::fflush(stdout);
      ++k;
      return true;
    };
    if (!sample()) continue;
    while (sim.time() < point->duration_s - 1e-9) {
      if (sim.time() + 1e-9 >= k * point->sample_s) {
        if (!sample()) break;
        continue;
      }
      const StepReport r = sim.step();
      if (!r.ok()) {
        std::fprintf(stderr, "L_eta %g: failed at t = %g s: %s\n", l_eta, sim.time(),
                     std::string(toString(r.failure)).c_str());
        break;
      }
    }
  }
  return 0;
}
