// Observables computed from a simulation state (DESIGN.md §7).
#pragma once

#include <Eigen/Core>

#include "activefoam/contacts.h"
#include "activefoam/geometry.h"

namespace activefoam {

// Ratio of the largest to the smallest principal axis of cell c (1 for a sphere).
double aspectRatio(const CellSet& cells, int c);

struct SphereFit {
  Vec3 centre = Vec3::Zero();
  double radius = 0;
  double rms = 0;  // rms distance of the points from the sphere
  bool ok = false;
};
// Algebraic least-squares sphere through the columns of `points` (at least 4, not coplanar).
SphereFit fitSphere(const Eigen::Matrix3Xd& points);

// Contact angle θ_c of a doublet (cells 0 and 1), degrees: the angle between a cell's free
// surface and the interface plane at the contact rim; 0° for cells touching at a point, 90° for
// complete fusion. Each cell's free surface (vertices with no contact area) is fitted by a sphere
// (centre c, radius R); the interface plane passes through the centroid of the contacting
// vertices, normal to the line of the fitted centres; at distance h from c, cos θ_c = h/R.
// Returns the mean over the two cells, 0 when there is no contact.
double doubletContactAngleDeg(const CellSet& cells, const ContactList& contacts);

}  // namespace activefoam
