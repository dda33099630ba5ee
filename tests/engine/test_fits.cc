// Fits of the fusion time series (docs/model.md §8.2–§8.4): Eq. 1, Eq. 2 (closed form), S1.
#include <cmath>
#include <functional>
#include <iostream>
#include <limits>
#include <vector>

#include <gtest/gtest.h>

#include "activefoam/fits.h"
#include "activefoam/rng.h"

using namespace activefoam;

namespace {

constexpr double kDeg = M_PI / 180.0;

std::vector<double> times(int n, double span, double start = 0) {
  std::vector<double> t(static_cast<size_t>(n));
  for (int i = 0; i < n; ++i) t[static_cast<size_t>(i)] = start + (span - start) * i / (n - 1);
  return t;
}

std::vector<double> sample(const std::vector<double>& t, const std::function<double(double)>& f,
                           double sigma, std::uint64_t seed) {
  Rng rng(seed, 7);
  std::vector<double> y;
  for (double ti : t) y.push_back(f(ti) + sigma * rng.normal());
  return y;
}

double eq1(double t, double theta_eq, double theta0, double tau) {
  return theta_eq + (theta0 - theta_eq) * std::exp(-t / tau);
}

double s1NeckRadius(double t, double R, double le, double tau1, double vf) {
  return std::cbrt(R * R * (le * (1 - std::exp(-t / tau1)) + vf * t));
}

// RK4 of 2θ̇ = cot θ/τ_Γ − sin θ/τ_ε (θ in radians), any sign of the τ; stops when θ leaves
// (0, π). Returns θ in degrees at the requested times.
std::vector<double> rk4Eq2(const std::vector<double>& t, double tau_gamma, double tau_eps,
                           double theta0_deg, double dt = 0.5) {
  auto rhs = [&](double th) {
    return 0.5 * (std::cos(th) / std::sin(th) / tau_gamma - std::sin(th) / tau_eps);
  };
  std::vector<double> out;
  double th = theta0_deg * kDeg, now = 0;
  for (double target : t) {
    while (now < target - 1e-12) {
      const double h = std::min(dt, target - now);
      const double k1 = rhs(th), k2 = rhs(th + 0.5 * h * k1), k3 = rhs(th + 0.5 * h * k2),
                   k4 = rhs(th + h * k3);
      th += h / 6 * (k1 + 2 * k2 + 2 * k3 + k4);
      now += h;
    }
    out.push_back(th / kDeg);
  }
  return out;
}

// Checks each named parameter against its true value: within 3 standard errors and within
// `rel` relative error.
void expectRecovered(const FitResult& r, const std::vector<std::pair<const char*, double>>& truth,
                     double rel) {
  ASSERT_TRUE(r.ok) << r.why;
  for (const auto& [name, value] : truth) {
    const double v = r.get(name), se = r.error(name);
    std::cout << "[ fit      ] " << name << " = " << v << " ± " << se << " (true " << value
              << ")\n";
    EXPECT_GT(se, 0) << name;
    EXPECT_LT(std::abs(v - value), 3 * se) << name;
    EXPECT_LT(std::abs(v - value), rel * std::abs(value)) << name;
  }
  EXPECT_GT(r.r2, 0.99);
}

// Over many noise realisations, the spread (sample standard deviation) of each estimate agrees
// with the mean reported standard error within a factor 1.5.
void expectConsistentErrors(const std::function<FitResult(std::uint64_t seed)>& fit,
                            const std::vector<const char*>& names, int realisations = 50) {
  const size_t m = names.size();
  std::vector<double> sum(m, 0), sum2(m, 0), se_sum(m, 0);
  for (int s = 0; s < realisations; ++s) {
    const FitResult r = fit(1000 + static_cast<std::uint64_t>(s));
    ASSERT_TRUE(r.ok) << "realisation " << s << ": " << r.why;
    for (size_t k = 0; k < m; ++k) {
      const double v = r.get(names[k]);
      sum[k] += v;
      sum2[k] += v * v;
      se_sum[k] += r.error(names[k]);
    }
  }
  for (size_t k = 0; k < m; ++k) {
    const double n = realisations, mean = sum[k] / n;
    const double spread = std::sqrt((sum2[k] - n * mean * mean) / (n - 1));
    const double se = se_sum[k] / n;
    std::cout << "[ fit      ] " << names[k] << ": spread " << spread << ", mean stderr " << se
              << "\n";
    EXPECT_LT(spread, 1.5 * se) << names[k];
    EXPECT_GT(spread, se / 1.5) << names[k];
  }
}

}  // namespace

// ---------------------------------------------------------------------------------------------
// Eq. 1

TEST(FitsEq1, RecoversParameters) {
  const auto t = times(100, 15000);
  const auto y = sample(
      t, [](double s) { return eq1(s, 60, 10, 3000); }, 0.5, 1);
  const FitResult r = fitEq1(t, y);
  expectRecovered(r, {{"theta_eq_deg", 60}, {"theta0_deg", 10}, {"tau_f_s", 3000}}, 0.03);
  EXPECT_EQ(r.n, 100);
  EXPECT_EQ(r.p, 3);
}

TEST(FitsEq1, ScaleRobust) {
  // The same curve in hours and in milliseconds; a decreasing relaxation.
  for (double unit : {1.0 / 3600, 1000.0}) {
    std::vector<double> t = times(100, 15000);
    const auto y = sample(
        t, [](double s) { return eq1(s, 20, 70, 3000); }, 0.5, 2);
    for (double& ti : t) ti *= unit;
    const FitResult r = fitEq1(t, y);
    expectRecovered(r, {{"theta_eq_deg", 20}, {"theta0_deg", 70}, {"tau_f_s", 3000 * unit}}, 0.03);
  }
}

TEST(FitsEq1, StandardErrorsMatchSpread) {
  const auto t = times(100, 15000);
  expectConsistentErrors(
      [&](std::uint64_t seed) {
        return fitEq1(t, sample(
                             t, [](double s) { return eq1(s, 60, 10, 3000); }, 0.5, seed));
      },
      {"theta_eq_deg", "theta0_deg", "tau_f_s"});
}

TEST(FitsEq1, FailuresSayWhy) {
  const FitResult two = fitEq1({0, 1}, {10, 20});
  EXPECT_FALSE(two.ok);
  EXPECT_NE(two.why.find("too few points"), std::string::npos) << two.why;

  const auto t = times(50, 1000);
  std::vector<double> flat(t.size(), 42.0);
  const FitResult c = fitEq1(t, flat);
  EXPECT_FALSE(c.ok);
  EXPECT_NE(c.why.find("constant"), std::string::npos) << c.why;
  EXPECT_NEAR(c.get("theta_eq_deg"), 42.0, 1e-9);  // the sensible part is still reported
  EXPECT_TRUE(std::isnan(c.get("tau_f_s")));

  auto y = sample(
      t, [](double s) { return eq1(s, 60, 10, 300); }, 0.5, 3);
  y[7] = std::numeric_limits<double>::quiet_NaN();
  const FitResult nan = fitEq1(t, y);
  EXPECT_FALSE(nan.ok);
  EXPECT_NE(nan.why.find("non-finite"), std::string::npos) << nan.why;

  // A straight line: no saturation, θ_eq would be an extrapolation.
  const auto line = sample(
      t, [](double s) { return 10 + 0.05 * s; }, 0.5, 4);
  const FitResult l = fitEq1(t, line);
  EXPECT_FALSE(l.ok);
  EXPECT_FALSE(l.why.empty());
  std::cout << "[ fit      ] line: " << l.why << "\n";

  // Noise about a constant: no relaxation to find.
  const auto noise = sample(
      t, [](double) { return 30.0; }, 0.5, 5);
  const FitResult nz = fitEq1(t, noise);
  EXPECT_FALSE(nz.ok);
  std::cout << "[ fit      ] noise: " << nz.why << "\n";

  const FitResult len = fitEq1({0, 1, 2, 3}, {1, 2, 3});
  EXPECT_FALSE(len.ok);
  EXPECT_NE(len.why.find("values but"), std::string::npos) << len.why;
}

// ---------------------------------------------------------------------------------------------
// Eq. 2

TEST(FitsEq2, ClosedFormMatchesRk4) {
  const auto t = times(41, 20000);
  struct Case {
    double tg, te, th0;
  };
  // Rising from a small angle, falling from above θ_eq, k ≪ 1 and k ≫ 1.
  for (const Case c :
       {Case{2000, 3000, 5}, Case{2000, 3000, 85}, Case{40000, 1000, 30}, Case{500, 20000, 10}}) {
    const auto ode = rk4Eq2(t, c.tg, c.te, c.th0, 0.25);
    double worst = 0;
    for (size_t i = 0; i < t.size(); ++i)
      worst = std::max(worst, std::abs(eq2Theta(t[i], c.tg, c.te, c.th0) - ode[i]));
    EXPECT_LT(worst, 1e-6) << "tau_gamma " << c.tg << " tau_eps " << c.te << " theta0 " << c.th0;
    // The fixed point: cos θ_eq = (√(k²+4) − k)/2.
    const double k = c.te / c.tg;
    EXPECT_NEAR(eq2Theta(1e9, c.tg, c.te, c.th0), std::acos((std::sqrt(k * k + 4) - k) / 2) / kDeg,
                1e-9);
  }
}

TEST(FitsEq2, RecoversParameters) {
  // k = 1.5 → θ_eq = 60°, λ = 1/2400 s.
  const auto t = times(100, 15000);
  const auto y = sample(
      t, [](double s) { return eq2Theta(s, 2000, 3000, 10); }, 0.5, 11);
  const FitResult r = fitEq2(t, y);
  expectRecovered(r, {{"tau_gamma_s", 2000}, {"tau_eps_s", 3000}, {"theta0_deg", 10}}, 0.05);
  EXPECT_NEAR(r.get("theta_eq_deg"), 60, 3 * r.error("theta_eq_deg"));
  EXPECT_NEAR(r.get("lambda_per_s"), 1.0 / 2400, 3 * r.error("lambda_per_s"));
}

TEST(FitsEq2, RecoversParametersFromRk4Data) {
  // Data from the ODE itself, falling from above θ_eq; k = 0.25 → θ_eq ≈ 27.9°.
  const auto t = times(100, 10000);
  auto y = rk4Eq2(t, 4000, 1000, 80);
  Rng rng(12, 7);
  for (double& v : y) v += 0.5 * rng.normal();
  const FitResult r = fitEq2(t, y);
  expectRecovered(r, {{"tau_gamma_s", 4000}, {"tau_eps_s", 1000}, {"theta0_deg", 80}}, 0.05);
}

TEST(FitsEq2, StandardErrorsMatchSpread) {
  const auto t = times(100, 15000);
  expectConsistentErrors(
      [&](std::uint64_t seed) {
        return fitEq2(t, sample(
                             t, [](double s) { return eq2Theta(s, 2000, 3000, 10); }, 0.5, seed));
      },
      {"tau_gamma_s", "tau_eps_s", "theta0_deg", "theta_eq_deg"});
}

TEST(FitsEq2, FailuresSayWhy) {
  const FitResult two = fitEq2({0, 1}, {10, 20});
  EXPECT_FALSE(two.ok);
  EXPECT_NE(two.why.find("too few points"), std::string::npos) << two.why;

  const auto t = times(100, 10000);
  // θ falls towards 0°, reached in finite time: this needs τ_Γ < 0 (here −10⁵ s).
  auto falling = rk4Eq2(t, -1e5, 3000, 60);
  ASSERT_GT(falling.back(), 1.0);
  ASSERT_LT(falling.back(), 10.0);
  Rng rng(13, 7);
  for (double& v : falling) v += 0.3 * rng.normal();
  const FitResult f = fitEq2(t, falling);
  EXPECT_FALSE(f.ok);
  EXPECT_NE(f.why.find("tau_gamma"), std::string::npos) << f.why;
  std::cout << "[ fit      ] falling to 0: " << f.why << " (tau_gamma " << f.get("tau_gamma_s")
            << " s, tau_eps " << f.get("tau_eps_s") << " s)\n";

  // θ rising beyond 90°: this needs τ_ε < 0.
  auto rising = rk4Eq2(t, 1500, -4000, 20);
  ASSERT_GT(rising.back(), 95.0);
  ASSERT_LT(rising.back(), 179.0);
  for (double& v : rising) v += 0.3 * rng.normal();
  const FitResult g = fitEq2(t, rising);
  EXPECT_FALSE(g.ok);
  EXPECT_NE(g.why.find("tau_eps"), std::string::npos) << g.why;
  std::cout << "[ fit      ] rising past 90: " << g.why << " (tau_gamma " << g.get("tau_gamma_s")
            << " s, tau_eps " << g.get("tau_eps_s") << " s)\n";

  std::vector<double> flat(t.size(), 42.0);
  const FitResult c = fitEq2(t, flat);
  EXPECT_FALSE(c.ok);
  EXPECT_NE(c.why.find("constant"), std::string::npos) << c.why;

  auto y = sample(
      t, [](double s) { return eq2Theta(s, 2000, 3000, 10); }, 0.5, 14);
  y[3] = std::numeric_limits<double>::infinity();
  const FitResult inf = fitEq2(t, y);
  EXPECT_FALSE(inf.ok);
  EXPECT_NE(inf.why.find("non-finite"), std::string::npos) << inf.why;

  y[3] = -5;
  const FitResult neg = fitEq2(t, y);
  EXPECT_FALSE(neg.ok);
  EXPECT_NE(neg.why.find("outside"), std::string::npos) << neg.why;
}

// ---------------------------------------------------------------------------------------------
// S1

TEST(FitsS1, RecoversParameters) {
  const double R = 50;
  const auto t = times(100, 20000, 200);
  const auto a = sample(
      t, [&](double s) { return s1NeckRadius(s, R, 5, 2000, 1e-4); }, 0.2, 21);
  const FitResult r = fitS1(t, a, R);
  expectRecovered(r, {{"L_e_um", 5}, {"tau_1_s", 2000}}, 0.05);
  // v_f contributes 2 µm of the 7 µm at the end: a looser relative check.
  EXPECT_NEAR(r.get("v_f_um_per_s"), 1e-4, 3 * r.error("v_f_um_per_s"));
  EXPECT_NEAR(r.get("v_f_um_per_s"), 1e-4, 0.1e-4);
}

TEST(FitsS1, StandardErrorsMatchSpread) {
  const double R = 50;
  const auto t = times(100, 20000, 200);
  expectConsistentErrors(
      [&](std::uint64_t seed) {
        return fitS1(t,
                     sample(
                         t, [&](double s) { return s1NeckRadius(s, R, 5, 2000, 1e-4); }, 0.2, seed),
                     R);
      },
      {"L_e_um", "tau_1_s", "v_f_um_per_s"});
}

TEST(FitsS1, FailuresSayWhy) {
  const FitResult two = fitS1({0, 1}, {1, 2}, 50);
  EXPECT_FALSE(two.ok);
  EXPECT_NE(two.why.find("too few points"), std::string::npos) << two.why;

  const auto t = times(50, 20000, 200);
  const auto a = sample(
      t, [&](double s) { return s1NeckRadius(s, 50, 5, 2000, 1e-4); }, 0.2, 22);
  const FitResult badR = fitS1(t, a, 0);
  EXPECT_FALSE(badR.ok);
  EXPECT_NE(badR.why.find("R must be positive"), std::string::npos) << badR.why;

  auto nan = a;
  nan[5] = std::numeric_limits<double>::quiet_NaN();
  const FitResult n = fitS1(t, nan, 50);
  EXPECT_FALSE(n.ok);
  EXPECT_NE(n.why.find("non-finite"), std::string::npos) << n.why;

  // A shrinking neck: L_e or v_f would have to be negative.
  const auto shrink = sample(
      t, [&](double s) { return 30 - s1NeckRadius(s, 50, 5, 2000, 1e-4); }, 0.2, 23);
  const FitResult sh = fitS1(t, shrink, 50);
  EXPECT_FALSE(sh.ok);
  std::cout << "[ fit      ] shrinking neck: " << sh.why << "\n";
}
