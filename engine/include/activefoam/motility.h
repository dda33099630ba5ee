// The motility force term (docs/model.md §4.2): each cell's traction along its polarity, the
// reaction on its contacting nodes, and the polarity's rotational diffusion.
#pragma once

#include <cstdint>
#include <string_view>

#include <Eigen/Core>

#include "activefoam/force_term.h"
#include "activefoam/mesh.h"
#include "activefoam/spec.h"

namespace activefoam {

// S8–S11: active migration. P_i^a = p_a (S_c,l/S_l) ((x_i − x_c,l)/‖x_i − x_c,l‖)·p̂_l acts as a
// pressure on the nodal area, F_i^act = P_i^a S_i n̂_i; the reaction −(S_i^c/S_c,l) Σ_j F_j^act on
// contacting nodes makes every cell's internal force sum zero (docs/model.md §4.2). After the
// step, p̂_l diffuses on the sphere with D_r = 1/τ_p (S10), driven by one Wiener path per cell
// that is a pure function of (seed, cell, absolute time): reproducible for any thread count,
// nothing to checkpoint, and the same path whatever the steps are — a run at another Δt, or one
// whose steps were halved after a rejection, sees the same noise (keyed by step number, every
// rejection changed all later noise and a Δt study compared different realisations).
class ActiveMigration : public ForceTerm {
 public:
  ActiveMigration(const CellParams& p, std::uint64_t seed)
      : p_a_(p.p_a), d_r_(1.0 / p.tau_p_s), seed_(seed) {}
  std::string_view name() const override { return "active_migration"; }
  double addForces(const StepContext& ctx, Eigen::Matrix3Xd& f) const override;
  void endStep(const StepContext& ctx, CellSet& cells) const override;
  // One rotational-diffusion step of a unit vector over [t0, t1] (exactly unit afterwards).
  static Vec3 diffuse(const Vec3& p, double d_r, double t0, double t1, std::uint64_t seed,
                      int cell);
  // W(t1) − W(t0) of the cell's 3-D standard Wiener path W (unit variance per second and axis).
  // W is sampled on a fixed grid of kNoiseGridS (increments drawn in blocks of kNoiseBlock grid
  // cells from a stream keyed by (seed, cell, block)) and linear between grid points: sums of
  // increments over adjacent intervals telescope, intervals of whole grid cells have the exact
  // variance, and only steps shorter than the grid (halved steps at Δt = 0.1 s) see a smoothed
  // path — at persistence times of minutes a difference nothing measures.
  static Vec3 wienerIncrement(std::uint64_t seed, int cell, double t0, double t1);
  static constexpr double kNoiseGridS = 0.1;
  static constexpr int kNoiseBlock = 10;

 private:
  double p_a_, d_r_;
  std::uint64_t seed_;
};

}  // namespace activefoam
