// How a fusion run ended, and the fits that only make sense when it fused.
//
// The supplement sorts its experiments into "no contact", "no fusion" and "(partial) fusion"
// and fits Eq. 1 only to the last (its Supp. Fig. 1B); simulated spheroids can also touch and
// come apart again. A run's outcome is decided from its sampled trajectory: the contact area
// between the two spheroids, the neck radius a and the fusion angle θ (docs/fusion-outcome.md
// gives the thresholds and why).
//   no-contact  no sample has a contact area between the spheroids above A_min;
//   separated   some sample had, the last one has not (or has no neck, a = 0);
//   fused       in contact at the end, and θ still rising over the last quarter of the run
//               (by more than max(2°, 2 standard errors of the trend)) or θ ≥ 80° (complete);
//   arrested    in contact at the end, θ below 80° and no longer rising: fusion stopped at a
//               partial angle (the supplement's arrested fusion, Supp. Fig. 14), including
//               spheroids that touch and never fuse perceptibly (θ stays small).
// A_min = 1 % of π r², r the mean cell radius: less than one triangle of a 320-triangle cell.
#pragma once

#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "activefoam/cellset.h"
#include "activefoam/contacts.h"
#include "activefoam/fits.h"

namespace activefoam {

enum class FusionOutcome { Fused, Arrested, Separated, NoContact };
std::string_view toString(FusionOutcome);  // fused | arrested | separated | no-contact

// The sampled series of a fusion run (aligned; NaN where θ or a is undefined: no neck).
struct FusionTrajectory {
  std::vector<double> t_s, theta_deg, neck_um, contact_area_um2;
};

struct FusionOutcomeThresholds {
  double area_fraction = 0.01;    // A_min / (π r²)
  double complete_deg = 80;       // θ at or above: fused, rising or not
  double rise_min_deg = 2;        // θ's trend over the last quarter must exceed this ...
  double rise_sigmas = 2;         // ... and this many standard errors of the trend
  double window_fraction = 0.25;  // the last part of the run whose trend is measured
};

struct FusionClassification {
  FusionOutcome outcome = FusionOutcome::NoContact;
  std::string why;  // one line with the numbers that decided it
  bool fitted() const {
    return outcome == FusionOutcome::Fused || outcome == FusionOutcome::Arrested;
  }
};

// Contact area between the two spheroids (cells.label 0 and 1): Σ S_AB over contact pairs of
// triangles of cells with different labels, µm².
double spheroidContactArea(const CellSet& cells, const ContactList& contacts);

// Throws std::invalid_argument if the series are not aligned.
FusionClassification classifyFusion(const FusionTrajectory& traj, double cell_radius_um,
                                    const FusionOutcomeThresholds& th = {});

// The fits of a fusion run ("eq1", "eq2" over θ(t), "s1" over a(t), see fits.h) on the samples
// with a neck (θ > 0). When the outcome is neither fused nor arrested no fit is tried: each is
// returned not ok, its values NaN, with `why` naming the outcome.
std::vector<std::pair<std::string, FitResult>> fusionFits(const FusionTrajectory& traj,
                                                          const FusionClassification& outcome,
                                                          double spheroid_radius_um);

}  // namespace activefoam
