// The fitting machinery shared by the models of fits.cc (engine-internal): Levenberg–Marquardt
// with reported parameters and their standard errors, data checks, and τ scans.
#pragma once

#include <cmath>
#include <functional>
#include <limits>
#include <string>
#include <string_view>
#include <vector>

#include <Eigen/Core>

#include "activefoam/fits.h"

namespace activefoam::fitting {

inline constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
inline constexpr double kDeg = M_PI / 180.0;
// Bounds on log(τ/T), T the time span: τ from 3e-7 T to 3e6 T. A fit that ends near them has
// driven a time constant to zero or infinity.
inline constexpr double kLogTauMax = 15.0;
inline constexpr double kLogTauAtBound = 12.0;

using Vec = Eigen::VectorXd;
using Mat = Eigen::MatrixXd;
// Residuals r(q) (data − model) for internal parameters q; false when they are not finite.
using Residual = std::function<bool(const Vec& q, Vec& r)>;

struct LmResult {
  Vec q;
  double rss = kNaN;
  int iterations = 0;
  bool converged = false;
  std::string why;
};

// What a fit reports (finishFit).
struct Reported {
  std::vector<std::string> names;
  std::function<Vec(const Vec&)> to_phys, from_phys;
  std::vector<std::string> derived_names;
  std::function<Vec(const Vec&)> derived;
};

struct TimeScale {
  double t0 = 0, span = 0, first_step = 0;
};

// Model y = c1 (1 − e^{−t/τ}) + c2 φ2(t, τ): for a fixed τ, (c1, c2) by linear least squares.
// Scans τ = T·10^{−3 … 2} (T the time span) and returns the best (c1, c2, τ).
struct LinearScan {
  double c1 = kNaN, c2 = kNaN, tau = kNaN, rss = kNaN;
};

std::string fmt(double v);

// Central-difference Jacobian of r(q); steps relative to |q_j| (internal parameters are O(1)
// or degrees). False if any evaluation is not finite.
bool jacobian(const Residual& f, const Vec& q, Eigen::Index n, Mat& j);

// Levenberg–Marquardt with Marquardt's diagonal scaling (scale-invariant in each parameter):
// solve (JᵀJ + μ diag JᵀJ) δ = −Jᵀr, accept when the RSS falls (μ /= 3), else μ *= 4.
// Converged when an accepted step changes the RSS by < 1e-12 relative or moves every parameter
// by < 1e-10 relative, or when no damped step lowers the RSS any more (μ > 1e10: a minimum
// to within rounding).
LmResult levenbergMarquardt(const Residual& f, Vec q, Eigen::Index n, int max_iter = 400);

// Parameter k is a time constant fitted as q_k = log(τ / tscale) (kept positive and
// scale-free); the others are reported as fitted.
void logTimeConstant(Reported& rep, int k, double tscale);

// Fills names/values/errors/RSS/R² from the optimum. `to_phys` maps internal q to the reported
// parameters; `from_phys` the reverse (for the Jacobian in reported parameters); `derived`
// computes extra quantities from the reported parameters. Returns false with why on a singular
// covariance.
bool finishFit(const Residual& f, const LmResult& lm, const Vec& data, const Reported& rep,
               FitResult& res);

// Common input checks. Returns an empty string when the data can be fitted.
std::string checkData(const std::vector<double>& t, const std::vector<double>& y, int p,
                      const char* yname);

// A result with the parameter names, n and NaN values, and `why` set if the data cannot be fitted.
FitResult newFit(std::vector<std::string> names, const std::vector<double>& t,
                 const std::vector<double>& y, const char* yname);

TimeScale timeScale(const std::vector<double>& t);

LinearScan scanTau(const std::vector<double>& t, const std::vector<double>& y, double span,
                   const std::function<double(double t, double tau)>& phi2);

int indexOf(const FitResult& r, std::string_view name);

// Checks shared by the τ of every model. Returns the reason for failure, or empty.
std::string checkTau(const std::string& name, double tau, double tau_se, const TimeScale& ts);

}  // namespace activefoam::fitting
