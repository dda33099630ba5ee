// Least-squares fits of the fusion time series (docs/model.md §8): Eq. 1, Eq. 2 and the S1 model.
//
// Every fit is a small Levenberg–Marquardt on the model's closed form, started from a coarse
// scan of its time constant (so it needs no guesses and is indifferent to the time unit), with
// time constants fitted as log τ (so they stay positive). Standard errors come from the
// covariance σ²(JᵀJ)⁻¹, σ² = RSS/(n − p), with J the Jacobian in the reported parameters at
// the optimum (equivalently the delta method through log τ).
#pragma once

#include <string>
#include <string_view>
#include <vector>

namespace activefoam {

struct FitResult {
  bool ok = false;
  std::string why;  // empty when ok; else the reason (the values may still hold the best try)
  // The p fitted parameters first, then derived quantities (e.g. theta_eq_deg for Eq. 2), whose
  // standard errors come from the same covariance by the delta method.
  std::vector<std::string> names;
  std::vector<double> value;
  std::vector<double> std_error;
  int p = 0;       // number of fitted parameters
  int n = 0;       // number of data points
  double rss = 0;  // residual sum of squares, in the squared data unit
  double r2 = 0;   // 1 − RSS/TSS (1 for an exact fit of constant data)
  int iterations = 0;

  // Value / standard error by name; NaN when there is no such name.
  double get(std::string_view name) const;
  double error(std::string_view name) const;
};

// Eq. 1: θ(t) = θ_eq + (θ_0 − θ_eq) e^{−t/τ_f}; residuals in degrees.
// Parameters: theta_eq_deg, theta0_deg, tau_f_s.
// Fails (ok = false, with why) for fewer than 4 points, non-finite data, fewer than 3 distinct
// times, constant data (θ_eq = θ_0 = the value, τ_f undetermined), τ_f beyond 10× the time span
// (no saturation in the data: θ_eq is an extrapolation), τ_f below the first sampling interval,
// a relative standard error of τ_f above 100 % (τ_f undetermined), a singular Jacobian, or no
// convergence.
FitResult fitEq1(const std::vector<double>& t_s, const std::vector<double>& theta_deg);

// Eq. 2: 2θ̇ = cot θ/τ_Γ − sin θ/τ_ε, fitted through its closed form (see fits.cc); residuals in
// degrees. Parameters: tau_gamma_s, tau_eps_s, theta0_deg (θ at t = 0, a nuisance parameter);
// derived: theta_eq_deg = arccos((√(k²+4) − k)/2), k = τ_ε/τ_Γ, and lambda_per_s.
// Both τ must be positive, so θ_eq ∈ (0°, 90°). Data that need 1/τ_Γ ≤ 0 (θ falling to 0°)
// or 1/τ_ε ≤ 0 (θ rising to 90° or beyond) drive a τ to infinity: the fit fails saying which.
// Also fails for θ outside (0°, 180°) and as fitEq1 does.
FitResult fitEq2(const std::vector<double>& t_s, const std::vector<double>& theta_deg);

// S1 alternative model: a³/R² = L_e (1 − e^{−t/τ_1}) + v_f t, with a the neck radius and R the
// spheroid radius. Residuals are in the measured neck radius a (µm), the model predicting
// a = (R² (L_e (1 − e^{−t/τ_1}) + v_f t))^{1/3}. Parameters: L_e_um, tau_1_s, v_f_um_per_s.
// Fails additionally for R ≤ 0, negative a, L_e ≤ 0, or v_f negative by more than 2 standard
// errors.
FitResult fitS1(const std::vector<double>& t_s, const std::vector<double>& neck_radius_um,
                double R_um);

// Closed-form Eq. 2 trajectory θ(t) in degrees for θ(0) = theta0_deg ∈ [0°, 180°] and
// τ_Γ, τ_ε > 0 (exposed for tests and plots).
double eq2Theta(double t_s, double tau_gamma_s, double tau_eps_s, double theta0_deg);

}  // namespace activefoam
