#include "least_squares.h"

#include <algorithm>
#include <sstream>

#include <Eigen/Dense>

namespace activefoam::fitting {

std::string fmt(double v) {
  std::ostringstream s;
  s.precision(4);
  s << v;
  return s.str();
}

// Central-difference Jacobian of r(q); steps relative to |q_j| (internal parameters are O(1)
// or degrees). False if any evaluation is not finite.
bool jacobian(const Residual& f, const Vec& q, Eigen::Index n, Mat& j) {
  j.resize(n, q.size());
  Vec rp(n), rm(n);
  for (Eigen::Index k = 0; k < q.size(); ++k) {
    const double h = 1e-6 * std::max(1.0, std::abs(q(k)));
    Vec qp = q, qm = q;
    qp(k) += h;
    qm(k) -= h;
    if (!f(qp, rp) || !f(qm, rm)) return false;
    j.col(k) = (rp - rm) / (2 * h);
  }
  return true;
}

// Levenberg–Marquardt with Marquardt's diagonal scaling (scale-invariant in each parameter):
// solve (JᵀJ + μ diag JᵀJ) δ = −Jᵀr, accept when the RSS falls (μ /= 3), else μ *= 4.
// Converged when an accepted step changes the RSS by < 1e-12 relative or moves every parameter
// by < 1e-10 relative, or when no damped step lowers the RSS any more (μ > 1e10: a minimum
// to within rounding).
LmResult levenbergMarquardt(const Residual& f, Vec q, Eigen::Index n, int max_iter) {
  LmResult out;
  Vec r(n), rt(n);
  if (!f(q, r)) {
    out.why = "model not finite at the initial guess";
    out.q = q;
    return out;
  }
  double rss = r.squaredNorm();
  double mu = 1e-3;
  Mat j;
  for (int it = 0; it < max_iter; ++it) {
    out.iterations = it + 1;
    if (rss == 0) {
      out.converged = true;
      break;
    }
    if (!jacobian(f, q, n, j)) {
      out.why = "model not finite near the parameters";
      break;
    }
    const Mat a = j.transpose() * j;
    const Vec g = j.transpose() * r;
    Vec d = a.diagonal();
    const double dmax = d.maxCoeff();
    if (!(dmax > 0)) {
      out.why = "singular Jacobian (the model does not depend on its parameters)";
      break;
    }
    d = d.cwiseMax(1e-12 * dmax);
    bool accepted = false;
    while (mu <= 1e10) {
      Mat m = a;
      m.diagonal() += mu * d;
      const Vec step = -m.ldlt().solve(g);
      const Vec qt = q + step;
      if (step.allFinite() && f(qt, rt)) {
        const double rss_t = rt.squaredNorm();
        if (rss_t < rss) {
          const double rel = (rss - rss_t) / rss;
          bool small = true;
          for (Eigen::Index k = 0; k < q.size(); ++k)
            small = small && std::abs(step(k)) <= 1e-10 * std::max(1e-3, std::abs(q(k)));
          q = qt;
          r = rt;
          rss = rss_t;
          mu = std::max(mu / 3, 1e-12);
          accepted = true;
          if (rel < 1e-12 || small) out.converged = true;
          break;
        }
      }
      mu *= 4;
    }
    if (!accepted) out.converged = true;  // no damped step lowers the RSS: at a minimum
    if (out.converged) break;
  }
  if (!out.converged && out.why.empty())
    out.why = "no convergence in " + std::to_string(max_iter) + " iterations";
  out.q = q;
  out.rss = rss;
  return out;
}

// Parameter k is a time constant fitted as q_k = log(τ / tscale) (kept positive and
// scale-free); the others are reported as fitted.
void logTimeConstant(Reported& rep, int k, double tscale) {
  rep.to_phys = [k, tscale](const Vec& q) {
    Vec p = q;
    p(k) = tscale * std::exp(std::clamp(q(k), -kLogTauMax, kLogTauMax));
    return p;
  };
  rep.from_phys = [k, tscale](const Vec& p) {
    Vec q = p;
    q(k) = std::log(p(k) / tscale);
    return q;
  };
}

bool finishFit(const Residual& f, const LmResult& lm, const Vec& data, const Reported& rep,
               FitResult& res) {
  const Eigen::Index n = data.size(), p = lm.q.size();
  res.n = static_cast<int>(n);
  res.p = static_cast<int>(p);
  res.iterations = lm.iterations;
  res.rss = lm.rss;
  const double mean = data.mean();
  const double tss = (data.array() - mean).square().sum();
  res.r2 = tss > 0 ? 1 - lm.rss / tss : (lm.rss == 0 ? 1.0 : 0.0);
  const Vec phys = rep.to_phys(lm.q);
  res.names = rep.names;
  res.value.assign(phys.data(), phys.data() + p);
  res.std_error.assign(p, kNaN);
  Vec derived;
  if (rep.derived) {
    derived = rep.derived(phys);
    res.names.insert(res.names.end(), rep.derived_names.begin(), rep.derived_names.end());
    res.value.insert(res.value.end(), derived.data(), derived.data() + derived.size());
    res.std_error.resize(res.value.size(), kNaN);
  }
  // Jacobian in the reported parameters.
  const Residual fp = [&](const Vec& x, Vec& r) { return f(rep.from_phys(x), r); };
  Mat j(n, p);
  {
    Vec rp(n), rm(n);
    for (Eigen::Index k = 0; k < p; ++k) {
      const double h = 1e-6 * std::max(std::abs(phys(k)), 1e-300);
      Vec xp = phys, xm = phys;
      xp(k) += h;
      xm(k) -= h;
      if (!fp(xp, rp) || !fp(xm, rm)) {
        res.why = "model not finite near the optimum";
        return false;
      }
      j.col(k) = (rp - rm) / (2 * h);
    }
  }
  // Column-scaled normal matrix: its conditioning says whether the parameters are identifiable.
  Vec scale = j.colwise().norm().transpose();
  for (Eigen::Index k = 0; k < p; ++k)
    if (!(scale(k) > 0)) {
      res.why =
          "singular Jacobian: the model does not depend on " + rep.names[static_cast<size_t>(k)];
      return false;
    }
  const Mat js = j * scale.cwiseInverse().asDiagonal();
  const Mat a = js.transpose() * js;
  Eigen::SelfAdjointEigenSolver<Mat> es(a);
  if (!(es.eigenvalues()(0) > 1e-13 * es.eigenvalues()(p - 1))) {
    res.why = "singular Jacobian: the parameters are not separately identifiable from the data";
    return false;
  }
  const double sigma2 = n > p ? lm.rss / static_cast<double>(n - p) : kNaN;
  const Mat cov = sigma2 * (scale.cwiseInverse().asDiagonal() * es.operatorInverseSqrt() *
                            es.operatorInverseSqrt() * scale.cwiseInverse().asDiagonal());
  for (Eigen::Index k = 0; k < p; ++k) res.std_error[k] = std::sqrt(std::max(cov(k, k), 0.0));
  if (rep.derived) {
    for (Eigen::Index m = 0; m < derived.size(); ++m) {
      Vec g(p);
      for (Eigen::Index k = 0; k < p; ++k) {
        const double h = 1e-6 * std::max(std::abs(phys(k)), 1e-300);
        Vec xp = phys, xm = phys;
        xp(k) += h;
        xm(k) -= h;
        g(k) = (rep.derived(xp)(m) - rep.derived(xm)(m)) / (2 * h);
      }
      res.std_error[p + m] = std::sqrt(std::max(g.dot(cov * g), 0.0));
    }
  }
  return true;
}

// Common input checks. Returns an empty string when the data can be fitted.
std::string checkData(const std::vector<double>& t, const std::vector<double>& y, int p,
                      const char* yname) {
  if (t.size() != y.size())
    return "t has " + std::to_string(t.size()) + " values but " + yname + " has " +
           std::to_string(y.size());
  const int n = static_cast<int>(t.size());
  if (n < p + 1)
    return "too few points (n = " + std::to_string(n) + "; need at least " + std::to_string(p + 1) +
           " for " + std::to_string(p) + " parameters)";
  for (int i = 0; i < n; ++i) {
    if (!std::isfinite(t[i])) return "non-finite time at index " + std::to_string(i);
    if (!std::isfinite(y[i]))
      return std::string("non-finite ") + yname + " at index " + std::to_string(i);
  }
  std::vector<double> ts = t;
  std::sort(ts.begin(), ts.end());
  const int distinct = static_cast<int>(std::unique(ts.begin(), ts.end()) - ts.begin());
  if (distinct < p)
    return "fewer than " + std::to_string(p) + " distinct times (" + std::to_string(distinct) + ")";
  return "";
}

// A result with the parameter names, n and NaN values, and `why` set if the data cannot be fitted.
FitResult newFit(std::vector<std::string> names, const std::vector<double>& t,
                 const std::vector<double>& y, const char* yname) {
  FitResult res;
  res.p = static_cast<int>(names.size());
  res.names = std::move(names);
  res.n = static_cast<int>(t.size());
  res.value.assign(res.p, kNaN);
  res.std_error.assign(res.p, kNaN);
  res.why = checkData(t, y, res.p, yname);
  return res;
}

TimeScale timeScale(const std::vector<double>& t) {
  std::vector<double> ts = t;
  std::sort(ts.begin(), ts.end());
  ts.erase(std::unique(ts.begin(), ts.end()), ts.end());
  TimeScale s;
  s.t0 = ts.front();
  s.span = ts.back() - ts.front();
  s.first_step = ts.size() > 1 ? ts[1] - ts[0] : 0;
  return s;
}

LinearScan scanTau(const std::vector<double>& t, const std::vector<double>& y, double span,
                   const std::function<double(double t, double tau)>& phi2) {
  LinearScan best;
  const int n = static_cast<int>(t.size());
  Eigen::MatrixXd a(n, 2);
  Eigen::VectorXd b = Eigen::Map<const Eigen::VectorXd>(y.data(), n);
  const int steps = 101;
  for (int s = 0; s < steps; ++s) {
    const double tau = span * std::pow(10.0, -3.0 + 5.0 * s / (steps - 1));
    for (int i = 0; i < n; ++i) {
      a(i, 0) = -std::expm1(-t[i] / tau);
      a(i, 1) = phi2(t[i], tau);
    }
    const Eigen::Vector2d c = a.colPivHouseholderQr().solve(b);
    if (!c.allFinite()) continue;
    const double rss = (a * c - b).squaredNorm();
    if (std::isfinite(rss) && !(rss >= best.rss)) best = {c(0), c(1), tau, rss};
  }
  return best;
}

int indexOf(const FitResult& r, std::string_view name) {
  for (size_t k = 0; k < r.names.size(); ++k)
    if (r.names[k] == name) return static_cast<int>(k);
  return -1;
}

// Checks shared by the τ of every model. Returns the reason for failure, or empty.
std::string checkTau(const std::string& name, double tau, double tau_se, const TimeScale& ts) {
  if (tau > 10 * ts.span)
    return name + " = " + fmt(tau) + " s exceeds 10x the time span (" + fmt(ts.span) +
           " s): the data do not saturate";
  if (tau < ts.first_step)
    return name + " = " + fmt(tau) + " s is below the first sampling interval (" +
           fmt(ts.first_step) + " s): the relaxation is not resolved";
  if (!(tau_se <= tau))
    return name + " undetermined (relative standard error " + fmt(100 * tau_se / tau) + " %)";
  return "";
}

}  // namespace activefoam::fitting
