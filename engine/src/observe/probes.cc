#include "activefoam/probe.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <stdexcept>

#include "../integrate/bytes.h"
#include "activefoam/contacts.h"
#include "activefoam/motility.h"
#include "activefoam/observables.h"
#include "activefoam/simulation.h"
#include "activefoam/terms.h"

namespace activefoam {
namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

// The cells' centroids at t = 0 (the first sample) against those now.
class RigidMotionProbe : public Probe {
 public:
  std::vector<std::string> columns() const override { return {"rigid_turn_deg", "rigid_drift_um"}; }
  void sample(const Simulation& sim, std::vector<double>& out) override {
    const std::vector<Vec3>& now = sim.geometry().cell_centroid;
    if (reference_.empty()) reference_ = now;
    const RigidMotion m = rigidMotion(reference_, now);
    out.push_back(m.turn_deg);
    out.push_back(m.drift_um);
  }
  std::string save() const override {
    std::vector<double> flat;
    flat.reserve(3 * reference_.size());
    for (const Vec3& x : reference_) flat.insert(flat.end(), {x[0], x[1], x[2]});
    bytes::Writer w;
    w.vec(flat);
    return w.take();
  }
  void restore(const std::string& data) override {
    bytes::Reader r(data, "checkpoint");
    const std::vector<double> flat = r.vec<double>();
    if (!r.done() || flat.size() % 3 != 0)
      throw std::invalid_argument("checkpoint: malformed state of observe.rigid_motion");
    reference_.clear();
    for (std::size_t i = 0; i < flat.size(); i += 3)
      reference_.emplace_back(flat[i], flat[i + 1], flat[i + 2]);
  }

 private:
  std::vector<Vec3> reference_;
};

// The last solve shown (the step that ends on the sample); NaN at t = 0, before any step.
class DissipationProbe : public Probe {
 public:
  std::vector<std::string> columns() const override {
    return {"diss_medium_nw",
            "diss_cortex_nw",
            "diss_friction_t_nw",
            "diss_friction_n_nw",
            "diss_springs_nw",
            "power_forces_nw",
            "power_active_nw",
            "diss_medium_affine_nw",
            "diss_cortex_affine_nw",
            "diss_friction_t_affine_nw",
            "diss_friction_n_affine_nw",
            "diss_cortex_jitter_nw",
            "speed_rms_um_min",
            "speed_relative_rms_um_min"};
  }
  bool readsSolve() const override { return true; }
  void solved(const StartSolve& s) override {
    last_ = dissipation(s);
    cells_ = cellScaleDissipation(s);
    seen_ = true;
  }
  void sample(const Simulation& /*sim*/, std::vector<double>& out) override {
    const Dissipation& d = last_;
    const CellScaleDissipation& c = cells_;
    for (double v : {d.medium, d.cortex, d.friction_t, d.friction_n, d.springs, d.forces, d.active,
                     c.medium_affine, c.cortex_affine, c.friction_t_affine, c.friction_n_affine,
                     c.cortex_jitter, c.speeds.rms_um_min, c.speeds.relative_rms_um_min})
      out.push_back(seen_ ? v : kNaN);
    seen_ = false;  // each sample its own step's
  }

 private:
  Dissipation last_;
  CellScaleDissipation cells_;
  bool seen_ = false;
};

// The cells' shape at each sample; the mesh's edges are rebuilt where it was remeshed.
class ShapeProbe : public Probe {
 public:
  std::vector<std::string> columns() const override {
    return {"shape_index_smoothed_mean",  "elongation_mean",
            "contact_fraction_mean",      "shape_on_contact_slope",
            "shape_on_contact_intercept", "shape_on_contact_r"};
  }
  void sample(const Simulation& sim, std::vector<double>& out) override {
    updateTopology(sim.cells(), topo_);
    const CellShapes c = cellShapes(sim.cells(), sim.geometry(), sim.contacts(), topo_);
    const auto mean = [](const std::vector<double>& x) {
      double sum = 0;
      for (double v : x) sum += v;
      return x.empty() ? kNaN : sum / static_cast<double>(x.size());
    };
    const LineFit fit = lineFit(c.contact_fraction, c.shape_index);
    for (double v : {mean(c.shape_index_smoothed), mean(c.elongation), mean(c.contact_fraction),
                     fit.slope, fit.intercept, fit.r})
      out.push_back(v);
  }

 private:
  Topology topo_;
};

// The last solve shown, as the dissipation's.
class TorqueProbe : public Probe {
 public:
  std::vector<std::string> columns() const override {
    return {"net_force_nn",          "net_torque_nnum",     "rigid_speed_um_h",
            "rigid_spin_deg_h",      "torque_medium_nnum",  "torque_share_cortex",
            "torque_share_friction", "torque_share_springs"};
  }
  bool readsSolve() const override { return true; }
  void solved(const StartSolve& s) override {
    last_ = bodyTorques(s);
    seen_ = true;
  }
  void sample(const Simulation& /*sim*/, std::vector<double>& out) override {
    const BodyTorques& b = last_;
    for (double v : {b.net_force_nn, b.net_torque_nnum, b.rigid_speed_um_h, b.rigid_spin_deg_h,
                     b.torque_medium_nnum, b.share_cortex, b.share_friction, b.share_springs})
      out.push_back(seen_ ? v : kNaN);
    seen_ = false;
  }

 private:
  BodyTorques last_;
  bool seen_ = false;
};

// Every sample's cells, classified, and at the end the MSRD split by class with its mixing times
// by MsrdTracker's rule: capped at the run's length where not reached (…_reached 0), NaN for a
// class that never had a pair.
class MsrdByDepthProbe : public Probe {
 public:
  MsrdByDepthProbe(double r_um, double after_s) : r_um_(r_um), after_s_(after_s) {}
  std::vector<std::string> columns() const override { return {"cells_surface", "cells_buried"}; }
  void sample(const Simulation& sim, std::vector<double>& out) override {
    const std::vector<double> free = freeFractions(sim.geometry(), sim.contacts());
    const auto buried =
        std::count_if(free.begin(), free.end(), [](double f) { return f < kBuriedBelow; });
    // Samples fall on multiples of sample_every_s up to the schedule's rounding.
    if (sim.time() >= after_s_ - 1e-9)
      split_.addSample(sim.time(), sim.geometry().cell_centroid,
                       contactingCellPairs(sim.cells(), sim.contacts()), free);
    out.push_back(static_cast<double>(free.size()) - static_cast<double>(buried));
    out.push_back(static_cast<double>(buried));
  }
  std::string save() const override { return split_.save(); }
  void restore(const std::string& data) override {
    try {
      split_.restore(data);
    } catch (const std::invalid_argument& e) {
      throw std::invalid_argument(std::string("checkpoint: malformed state of "
                                              "observe.msrd_by_depth: ") +
                                  e.what());
    }
  }
  void finish(RunSummary& sum) const override {
    const MsrdTracker& t = split_.tracker();
    const int n = t.numSamples();
    std::array<std::vector<double>, 6> curve;  // the burial classes', then the layers', by lag
    std::array<long, 6> pairs{};
    for (auto& c : curve) c.assign(static_cast<std::size_t>(n), kNaN);
    for (int k = 0; k < n; ++k) {
      const MsrdByDepth::Split s = split_.pooled(k);
      for (int c = 0; c < 3; ++c) {
        curve[c][k] = s.burial[c].mean();
        curve[3 + c][k] = s.layer[c].mean();
        if (k > 0) {
          pairs[c] += s.burial[c].pairs;
          pairs[3 + c] += s.layer[c].pairs;
        }
      }
    }
    static const char* const kName[6] = {"msrd_surface", "msrd_mixed",  "msrd_buried",
                                         "msrd_layer0",  "msrd_layer1", "msrd_layer2plus"};
    for (int c = 0; c < 6; ++c) {
      RunSummary::Curve out{kName[c], {}, {}};
      for (int k = 1; k < n; ++k)
        if (std::isfinite(curve[c][k])) {
          out.x.push_back(t.lagTime(k));
          out.y.push_back(curve[c][k]);
        }
      sum.curves.push_back(std::move(out));
    }
    static const char* const kClass[3] = {"surface", "mixed", "buried"};
    for (int c = 0; c < 3; ++c) {
      const MsrdTracker::Mixing m = t.mixingTime(r_um_, curve[c]);
      std::string time = "mixing_time_", reached = "mixing_";
      time.append(kClass[c]).append("_s");
      reached.append(kClass[c]).append("_reached");
      sum.final_values.emplace_back(time, pairs[c] > 0 ? m.time_s : kNaN);
      sum.final_values.emplace_back(reached, m.reached ? 1 : 0);
    }
  }

 private:
  double r_um_;     // the cells' mean radius: mixing at MSRD = r²
  double after_s_;  // the first origin's time
  MsrdByDepth split_;
};

bool asked(const SceneSpec& spec, const char* key, bool on) {
  return on && findField(key)->readBy(spec.scene);
}

}  // namespace

// A fresh operator each time: FrictionOperator keys its couplings by the term's address, and the
// parts of the contact friction are temporaries.
Eigen::VectorXd frictionForce(const ForceTerm& term, const StepContext& ctx,
                              const Eigen::VectorXd& v) {
  FrictionOperator op;
  op.reset(ctx.cells.numVertices(), ctx.cells.topology_version);
  term.addFriction(ctx, op);
  Eigen::VectorXd y(v.size());
  op.apply(v.data(), y.data());
  return y;
}

double frictionPower(const ForceTerm& term, const StepContext& ctx, const Eigen::VectorXd& v) {
  return v.dot(frictionForce(term, ctx, v));
}

RigidMotion rigidMotion(const std::vector<Vec3>& from, const std::vector<Vec3>& to) {
  if (from.size() != to.size() || from.empty())
    throw std::invalid_argument("rigidMotion: the same cells at both times");
  Vec3 a = Vec3::Zero(), b = Vec3::Zero();
  for (std::size_t i = 0; i < from.size(); ++i) {
    a += from[i];
    b += to[i];
  }
  const double n = static_cast<double>(from.size());
  RigidMotion m;
  m.turn_deg = rotationAngle(bestRotation(from, to)) * 180.0 / M_PI;
  m.drift_um = (b / n - a / n).norm();
  return m;
}

Dissipation dissipation(const StartSolve& s) {
  Dissipation d;
  const StepContext& ctx = s.ctx;
  const Eigen::VectorXd& v = s.v;
  d.forces = Eigen::Map<const Eigen::VectorXd>(s.f.data(), s.f.size()).dot(v);
  for (const auto& term : s.terms) {
    const ForceTerm& t = *term;
    if (dynamic_cast<const MediumDrag*>(&t)) {
      d.medium += frictionPower(t, ctx, v);
    } else if (dynamic_cast<const CortexViscosity*>(&t)) {
      d.cortex += frictionPower(t, ctx, v);
    } else if (const auto* cf = dynamic_cast<const ContactFriction*>(&t)) {
      using Part = ContactFriction::Part;
      d.friction_t += frictionPower(cf->part(Part::Tangential), ctx, v);
      d.friction_n += frictionPower(cf->part(Part::Normal), ctx, v);
      if (ctx.contact_stiffness_dt > 0) d.springs += frictionPower(cf->part(Part::Springs), ctx, v);
    } else if (dynamic_cast<const SurfaceTension*>(&t) && ctx.tension_stiffness_dt > 0) {
      d.springs += frictionPower(t, ctx, v);
    } else if (dynamic_cast<const ActiveMigration*>(&t)) {
      Eigen::Matrix3Xd fa = Eigen::Matrix3Xd::Zero(3, ctx.cells.numVertices());
      t.addForces(ctx, fa);
      d.active += Eigen::Map<const Eigen::VectorXd>(fa.data(), fa.size()).dot(v);
    }
  }
  return d;
}

std::vector<std::unique_ptr<Probe>> makeProbes(const SceneSpec& spec) {
  std::vector<std::unique_ptr<Probe>> probes;
  if (asked(spec, "observe.rigid_motion", spec.observe.rigid_motion))
    probes.push_back(std::make_unique<RigidMotionProbe>());
  if (asked(spec, "observe.dissipation", spec.observe.dissipation))
    probes.push_back(std::make_unique<DissipationProbe>());
  if (asked(spec, "observe.msrd_by_depth", spec.observe.msrd_by_depth))
    probes.push_back(std::make_unique<MsrdByDepthProbe>(spec.cells.radius_mean_um,
                                                        spec.observe.msrd_by_depth_after_s));
  if (asked(spec, "observe.shape", spec.observe.shape))
    probes.push_back(std::make_unique<ShapeProbe>());
  if (asked(spec, "observe.torque", spec.observe.torque))
    probes.push_back(std::make_unique<TorqueProbe>());
  return probes;
}

std::vector<std::string> probeColumns(const SceneSpec& spec) {
  std::vector<std::string> cols;
  for (const auto& p : makeProbes(spec)) {
    const std::vector<std::string> c = p->columns();
    cols.insert(cols.end(), c.begin(), c.end());
  }
  return cols;
}

}  // namespace activefoam
