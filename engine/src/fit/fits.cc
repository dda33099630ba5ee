#include "activefoam/fits.h"

#include <algorithm>
#include <cmath>
#include <functional>
#include <limits>
#include <sstream>

#include <Eigen/Dense>

#include "least_squares.h"

namespace activefoam {

using namespace fitting;

double FitResult::get(std::string_view name) const {
  const int k = indexOf(*this, name);
  return k < 0 ? kNaN : value[static_cast<size_t>(k)];
}

double FitResult::error(std::string_view name) const {
  const int k = indexOf(*this, name);
  return k < 0 || static_cast<size_t>(k) >= std_error.size() ? kNaN
                                                             : std_error[static_cast<size_t>(k)];
}

// Levenberg–Marquardt from q0 for a model with one time constant fitted as its logarithm (at
// parameter log_tau, in units of tscale); fills res. False, res.why set, where the covariance is
// singular or the iteration did not converge.
static bool solveWithLogTau(const Residual& f, const Vec& q0, int n, int log_tau, double tscale,
                            const Vec& data, FitResult& res) {
  const LmResult lm = levenbergMarquardt(f, q0, n);
  Reported rep;
  rep.names = res.names;
  logTimeConstant(rep, log_tau, tscale);
  if (!finishFit(f, lm, data, rep, res)) return false;
  if (!lm.converged) {
    res.why = lm.why;
    return false;
  }
  return true;
}

// ---------------------------------------------------------------------------------------------
// Eq. 1

FitResult fitEq1(const std::vector<double>& t, const std::vector<double>& theta) {
  FitResult res = newFit({"theta_eq_deg", "theta0_deg", "tau_f_s"}, t, theta, "theta");
  if (!res.why.empty()) return res;
  const int n = res.n;
  const auto [lo, hi] = std::minmax_element(theta.begin(), theta.end());
  double mean = 0;
  for (double v : theta) mean += v / n;
  if (*hi - *lo <= 1e-12 * std::max(1.0, std::abs(mean))) {
    res.value = {mean, mean, kNaN};
    res.std_error = {0, 0, kNaN};
    res.r2 = 1;
    res.why = "constant data (" + fmt(mean) + " deg): no relaxation, tau_f undetermined";
    return res;
  }
  const TimeScale ts = timeScale(t);
  const LinearScan scan =
      scanTau(t, theta, ts.span, [](double ti, double tau) { return std::exp(-ti / tau); });
  if (!std::isfinite(scan.rss)) {
    res.why = "no finite initial guess";
    return res;
  }
  const Eigen::Map<const Vec> data(theta.data(), n);
  const double tscale = ts.span;
  // q = (θ_eq, θ_0, log(τ/T)).
  const Residual f = [&](const Vec& q, Vec& r) {
    const double tau = tscale * std::exp(std::clamp(q(2), -kLogTauMax, kLogTauMax));
    for (int i = 0; i < n; ++i) r(i) = data(i) - (q(0) + (q(1) - q(0)) * std::exp(-t[i] / tau));
    return r.allFinite();
  };
  Vec q0(3);
  q0 << scan.c1, scan.c2, std::log(scan.tau / tscale);
  if (!solveWithLogTau(f, q0, n, 2, tscale, data, res)) return res;
  res.why = checkTau("tau_f_s", res.value[2], res.std_error[2], ts);
  res.ok = res.why.empty();
  return res;
}

// ---------------------------------------------------------------------------------------------
// Eq. 2
//
// With u = cos θ: du/dt = −sin θ θ̇ = −(cos θ/τ_Γ − sin²θ/τ_ε)/2 = (1 − u² − k u)/(2τ_ε),
// k = τ_ε/τ_Γ, i.e. du/dt = −(u − u₊)(u − u₋)/(2τ_ε) with u± the roots of u² + k u − 1 = 0:
// u₊ = (√(k²+4) − k)/2 = 2/(√(k²+4) + k) ∈ (0, 1) (= cos θ_eq), u₋ = −1/u₊ < −1.
// For w = (u − u₊)/(u − u₋):  dw/dt = u̇ (u₊ − u₋)/(u − u₋)² = −w (u₊ − u₋)/(2τ_ε), so
// w(t) = w(0) e^{−λt} with λ = (u₊ − u₋)/(2τ_ε) = √(k²+4)/(2τ_ε) = ½√(1/τ_Γ² + 4/τ_ε²)
// (multiply √(k²+4) = √(τ_ε²/τ_Γ² + 4) by 1/τ_ε): the same λ as docs/model.md §8.3.
// Back: u = (u₊ − w u₋)/(1 − w); u − u₋ > 0 for u ∈ [−1, 1], so w < 1 and this is finite.

double eq2Theta(double t, double tau_gamma, double tau_eps, double theta0_deg) {
  const double k = tau_eps / tau_gamma;
  const double s = std::sqrt(k * k + 4);
  const double up = 2 / (s + k), um = -1 / up;
  const double lambda = s / (2 * tau_eps);
  const double u0 = std::cos(theta0_deg * kDeg);
  const double w = (u0 - up) / (u0 - um) * std::exp(-lambda * t);
  const double u = (up - w * um) / (1 - w);
  return std::acos(std::clamp(u, -1.0, 1.0)) / kDeg;
}

FitResult fitEq2(const std::vector<double>& t, const std::vector<double>& theta) {
  FitResult res = newFit({"tau_gamma_s", "tau_eps_s", "theta0_deg"}, t, theta, "theta");
  if (!res.why.empty()) return res;
  const int n = res.n;
  for (int i = 0; i < n; ++i)
    if (!(theta[i] > 0 && theta[i] < 180)) {
      res.why = "theta outside (0, 180) deg at index " + std::to_string(i);
      return res;
    }
  const auto [lo, hi] = std::minmax_element(theta.begin(), theta.end());
  if (*hi - *lo <= 1e-12 * *hi) {
    res.why = "constant data (" + fmt(*hi) +
              " deg): no relaxation, the time constants are "
              "undetermined";
    return res;
  }
  const TimeScale ts = timeScale(t);
  const double tscale = ts.span;
  const Eigen::Map<const Vec> data(theta.data(), n);
  // q = (log(τ_Γ/T), log(τ_ε/T), θ_0). θ_0 enters through cos θ_0 (even): reported as |θ_0|.
  auto taus = [&](const Vec& q) {
    return std::pair{tscale * std::exp(std::clamp(q(0), -kLogTauMax, kLogTauMax)),
                     tscale * std::exp(std::clamp(q(1), -kLogTauMax, kLogTauMax))};
  };
  const Residual f = [&](const Vec& q, Vec& r) {
    const auto [tg, te] = taus(q);
    for (int i = 0; i < n; ++i) r(i) = data(i) - eq2Theta(t[i], tg, te, q(2));
    return r.allFinite();
  };
  // Starting points: a scan over (θ_eq, λ) with θ_0 from the Eq. 1 fit (or the earliest
  // point), plus the Eq. 1 fit mapped onto Eq. 2 (λ ≈ 1/τ_f).
  const FitResult e1 = fitEq1(t, theta);
  double theta0 = theta[static_cast<size_t>(std::min_element(t.begin(), t.end()) - t.begin())];
  if (std::isfinite(e1.value[1]) && e1.value[1] > 0 && e1.value[1] < 180) theta0 = e1.value[1];
  auto start = [&](double theta_eq_deg, double lambda) {
    const double up = std::cos(std::clamp(theta_eq_deg, 0.5, 89.5) * kDeg);
    const double k = (1 - up * up) / up;
    const double te = std::sqrt(k * k + 4) / (2 * lambda);
    Vec q(3);
    q << std::log(te / k / tscale), std::log(te / tscale), theta0;
    return q;
  };
  std::vector<Vec> starts;
  {
    Vec r(n);
    double best = std::numeric_limits<double>::infinity();
    Vec best_q;
    for (int a = 0; a <= 22; ++a) {
      for (int l = 0; l <= 30; ++l) {
        const Vec q = start(0.5 + 89.0 * a / 22, std::pow(10.0, 3.0 - 4.0 * l / 30) / tscale);
        if (f(q, r) && r.squaredNorm() < best) {
          best = r.squaredNorm();
          best_q = q;
        }
      }
    }
    if (best_q.size()) starts.push_back(best_q);
    if (std::isfinite(e1.value[0]) && std::isfinite(e1.value[2]) && e1.value[2] > 0)
      starts.push_back(start(e1.value[0], 1 / e1.value[2]));
  }
  if (starts.empty()) {
    res.why = "no finite initial guess";
    return res;
  }
  LmResult lm;
  for (const Vec& q0 : starts) {
    LmResult l = levenbergMarquardt(f, q0, n);
    if (std::isfinite(l.rss) && !(l.rss >= lm.rss)) lm = l;
  }
  if (!std::isfinite(lm.rss)) {
    res.why = "model not finite at the initial guesses";
    return res;
  }
  lm.q(2) = std::abs(lm.q(2));
  Reported rep;
  rep.names = res.names;
  rep.to_phys = [&](const Vec& q) {
    const auto [tg, te] = taus(q);
    Vec p(3);
    p << tg, te, q(2);
    return p;
  };
  rep.from_phys = [&](const Vec& p) {
    Vec q(3);
    q << std::log(p(0) / tscale), std::log(p(1) / tscale), p(2);
    return q;
  };
  rep.derived_names = {"theta_eq_deg", "lambda_per_s"};
  rep.derived = [](const Vec& p) {
    const double k = p(1) / p(0), s = std::sqrt(k * k + 4);
    Vec d(2);
    d << std::acos(2 / (s + k)) / kDeg, s / (2 * p(1));
    return d;
  };
  const bool finite_cov = finishFit(f, lm, data, rep, res);
  // Time constants driven to infinity: the data need a non-positive rate.
  const double theta_eq = res.get("theta_eq_deg");
  // A time constant beyond 10 T that the data do not determine, or at the bound of the search.
  auto unbounded = [&](int k) {
    const bool undetermined =
        !finite_cov || !(res.std_error[static_cast<size_t>(k)] <= res.value[k]);
    return lm.q(k) > kLogTauAtBound || (lm.q(k) > std::log(10.0) && undetermined);
  };
  if (unbounded(0) && theta_eq < 45) {
    res.why =
        "tau_gamma_s -> infinity (theta_eq -> 0 deg): the data need 1/tau_gamma <= 0, "
        "i.e. a negative tau_gamma";
    return res;
  }
  if (unbounded(1) && theta_eq >= 45) {
    res.why =
        "tau_eps_s -> infinity (theta_eq -> 90 deg): the data need 1/tau_eps <= 0, "
        "i.e. a negative tau_eps";
    return res;
  }
  if (lm.q(0) < -kLogTauAtBound || lm.q(1) < -kLogTauAtBound) {
    res.why = "a time constant -> 0: the data jump at t = 0";
    return res;
  }
  if (!finite_cov) return res;
  if (!lm.converged) {
    res.why = lm.why;
    return res;
  }
  const double lambda = res.get("lambda_per_s");
  const double relax = 1 / lambda, relax_se = res.error("lambda_per_s") / (lambda * lambda);
  res.why = checkTau("1/lambda", relax, relax_se, ts);
  for (int k = 0; k < 2 && res.why.empty(); ++k)
    if (!(res.std_error[k] <= res.value[k]))
      res.why = res.names[k] + " undetermined (relative standard error " +
                fmt(100 * res.std_error[k] / res.value[k]) + " %)";
  res.ok = res.why.empty();
  return res;
}

// ---------------------------------------------------------------------------------------------
// S1

FitResult fitS1(const std::vector<double>& t, const std::vector<double>& a, double R) {
  FitResult res = newFit({"L_e_um", "tau_1_s", "v_f_um_per_s"}, t, a, "neck radius");
  if (!(R > 0) || !std::isfinite(R)) {
    res.why = "R must be positive and finite (got " + fmt(R) + ")";
    return res;
  }
  if (!res.why.empty()) return res;
  const int n = res.n;
  for (int i = 0; i < n; ++i)
    if (a[i] < 0) {
      res.why = "negative neck radius at index " + std::to_string(i);
      return res;
    }
  const auto [lo, hi] = std::minmax_element(a.begin(), a.end());
  if (*hi - *lo <= 1e-12 * std::max(1.0, *hi)) {
    res.why = "constant neck radius (" + fmt(*hi) + " um): no growth, tau_1 undetermined";
    return res;
  }
  const TimeScale ts = timeScale(t);
  const double tscale = ts.span;
  // Initial guess: the model is linear in (L_e, v_f) in y = a³/R².
  std::vector<double> y(a.size());
  for (size_t i = 0; i < a.size(); ++i) y[i] = a[i] * a[i] * a[i] / (R * R);
  const LinearScan scan = scanTau(t, y, ts.span, [](double ti, double) { return ti; });
  if (!std::isfinite(scan.rss)) {
    res.why = "no finite initial guess";
    return res;
  }
  const Eigen::Map<const Vec> data(a.data(), n);
  const double r2 = R * R;
  // q = (L_e, log(τ_1/T), v_f); residuals in a.
  const Residual f = [&](const Vec& q, Vec& r) {
    const double tau = tscale * std::exp(std::clamp(q(1), -kLogTauMax, kLogTauMax));
    for (int i = 0; i < n; ++i)
      r(i) = data(i) - std::cbrt(r2 * (-q(0) * std::expm1(-t[i] / tau) + q(2) * t[i]));
    return r.allFinite();
  };
  Vec q0(3);
  q0 << scan.c1, std::log(scan.tau / tscale), scan.c2;
  if (!solveWithLogTau(f, q0, n, 1, tscale, data, res)) return res;
  if (!(res.value[0] > 0)) {
    res.why = "L_e_um = " + fmt(res.value[0]) + " is not positive";
    return res;
  }
  if (res.value[2] < -2 * res.std_error[2]) {
    res.why = "v_f_um_per_s = " + fmt(res.value[2]) +
              " is negative (more than 2 standard "
              "errors)";
    return res;
  }
  res.why = checkTau("tau_1_s", res.value[1], res.std_error[1], ts);
  res.ok = res.why.empty();
  return res;
}

}  // namespace activefoam
