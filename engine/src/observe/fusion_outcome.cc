#include "activefoam/fusion_outcome.h"

#include <cmath>
#include <cstdio>
#include <stdexcept>

namespace activefoam {

namespace {

std::string fmt(double v) {
  char b[32];
  std::snprintf(b, sizeof b, "%.3g", v);
  return b;
}

bool inContact(const FusionTrajectory& tr, std::size_t k, double a_min) {
  return tr.contact_area_um2[k] > a_min;
}

}  // namespace

std::string_view toString(FusionOutcome o) {
  switch (o) {
    case FusionOutcome::Fused:
      return "fused";
    case FusionOutcome::Arrested:
      return "arrested";
    case FusionOutcome::Separated:
      return "separated";
    case FusionOutcome::NoContact:
      return "no-contact";
  }
  return "?";
}

double spheroidContactArea(const CellSet& cells, const ContactList& contacts) {
  double area = 0;
  for (const ContactPair& p : contacts.pairs)
    if (cells.label[cells.tri_cell[p.ta]] != cells.label[cells.tri_cell[p.tb]]) area += p.c.area;
  return area;
}

FusionClassification classifyFusion(const FusionTrajectory& tr, double cell_radius_um,
                                    const FusionOutcomeThresholds& th) {
  const std::size_t n = tr.t_s.size();
  if (tr.theta_deg.size() != n || tr.neck_um.size() != n || tr.contact_area_um2.size() != n)
    throw std::invalid_argument("classifyFusion: series of different lengths");
  const double a_min = th.area_fraction * M_PI * cell_radius_um * cell_radius_um;
  FusionClassification out;
  std::size_t touched = n;
  for (std::size_t k = 0; k < n && touched == n; ++k)
    if (inContact(tr, k, a_min)) touched = k;
  if (touched == n) {
    out.outcome = FusionOutcome::NoContact;
    out.why = "no sample has a contact area between the spheroids above " + fmt(a_min) + " um2";
    return out;
  }
  const std::size_t last = n - 1;
  const double theta_end = tr.theta_deg[last];
  if (!inContact(tr, last, a_min) || !(tr.neck_um[last] > 0) || !std::isfinite(theta_end)) {
    out.outcome = FusionOutcome::Separated;
    out.why = "in contact from t = " + fmt(tr.t_s[touched]) +
              " s, apart at the end (t = " + fmt(tr.t_s[last]) + " s: contact area " +
              fmt(tr.contact_area_um2[last]) + " um2, neck radius " + fmt(tr.neck_um[last]) +
              " um)";
    return out;
  }
  if (theta_end >= th.complete_deg) {
    out.outcome = FusionOutcome::Fused;
    out.why = "theta = " + fmt(theta_end) + " deg at the end (complete from " +
              fmt(th.complete_deg) + " deg)";
    return out;
  }
  // θ's trend over the last part of the run: least squares slope × window, and its standard
  // error (motility makes θ fluctuate by a few degrees; a plateau must not read as a rise).
  const double t_from = tr.t_s[last] - th.window_fraction * (tr.t_s[last] - tr.t_s[0]);
  std::vector<double> t, y;
  for (std::size_t k = 0; k < n; ++k)
    if (tr.t_s[k] >= t_from && std::isfinite(tr.theta_deg[k])) {
      t.push_back(tr.t_s[k]);
      y.push_back(tr.theta_deg[k]);
    }
  if (t.size() < 3) {
    t.clear();
    y.clear();
    for (std::size_t k = n; k-- > 0 && t.size() < 3;)
      if (std::isfinite(tr.theta_deg[k])) {
        t.insert(t.begin(), tr.t_s[k]);
        y.insert(y.begin(), tr.theta_deg[k]);
      }
  }
  if (t.size() < 3) {
    out.outcome = FusionOutcome::Arrested;
    out.why = "theta = " + fmt(theta_end) + " deg at the end; too few samples (" +
              std::to_string(t.size()) + ") to see it rise";
    return out;
  }
  const double m = static_cast<double>(t.size());
  double tm = 0, ym = 0;
  for (std::size_t k = 0; k < t.size(); ++k) {
    tm += t[k] / m;
    ym += y[k] / m;
  }
  double stt = 0, sty = 0;
  for (std::size_t k = 0; k < t.size(); ++k) {
    stt += (t[k] - tm) * (t[k] - tm);
    sty += (t[k] - tm) * (y[k] - ym);
  }
  const double slope = stt > 0 ? sty / stt : 0;
  double rss = 0;
  for (std::size_t k = 0; k < t.size(); ++k) {
    const double r = y[k] - ym - slope * (t[k] - tm);
    rss += r * r;
  }
  const double span = t.back() - t.front();
  const double slope_se = t.size() > 2 && stt > 0 ? std::sqrt(rss / (m - 2) / stt) : 0;
  const double rise = slope * span, rise_se = slope_se * span;
  const std::string trend = "theta = " + fmt(theta_end) + " deg at the end, trend over the last " +
                            fmt(span) + " s " + fmt(rise) + " +- " + fmt(rise_se) + " deg";
  if (rise > th.rise_min_deg && rise > th.rise_sigmas * rise_se) {
    out.outcome = FusionOutcome::Fused;
    out.why = trend + ": still rising";
  } else {
    out.outcome = FusionOutcome::Arrested;
    out.why = trend + ": no longer rising";
  }
  return out;
}

std::vector<std::pair<std::string, FitResult>> fusionFits(const FusionTrajectory& tr,
                                                          const FusionClassification& outcome,
                                                          double spheroid_radius_um) {
  // Samples without a neck (θ undefined: no contact yet) are left out; with no fit to try, the
  // fitters' own empty-data answer carries the parameter names, and `why` is replaced.
  std::vector<double> t, theta, neck;
  if (outcome.fitted())
    for (std::size_t k = 0; k < tr.t_s.size(); ++k)
      if (std::isfinite(tr.theta_deg[k]) && tr.theta_deg[k] > 0) {
        t.push_back(tr.t_s[k]);
        theta.push_back(tr.theta_deg[k]);
        neck.push_back(tr.neck_um[k]);
      }
  std::vector<std::pair<std::string, FitResult>> fits;
  fits.emplace_back("eq1", fitEq1(t, theta));
  fits.emplace_back("eq2", fitEq2(t, theta));
  fits.emplace_back("s1", fitS1(t, neck, spheroid_radius_um));
  if (!outcome.fitted())
    for (auto& [model, f] : fits) {
      f.ok = false;
      f.why = "not fitted: the outcome is " + std::string(toString(outcome.outcome)) + " (" +
              outcome.why + ")";
    }
  return fits;
}

}  // namespace activefoam
