// Fusion observables (docs/model.md §8): fusion angle, shape index, surface contact angle, pure
// functions of the state (the MSRD and the unique contacts, accumulated over samples: msrd.cc).
#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <tuple>

#include <Eigen/Dense>

#include "activefoam/observables.h"

namespace activefoam {

namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
constexpr double kDeg = M_PI / 180.0;

// Unique undirected edges (i < j) of the packed meshes: in a closed oriented mesh every edge
// appears once as i→j and once as j→i.
std::vector<std::pair<int, int>> uniqueEdges(const CellSet& cells) {
  std::vector<std::pair<int, int>> e;
  e.reserve(cells.tri.size() * 3 / 2);
  for (const Tri& f : cells.tri)
    for (int k = 0; k < 3; ++k)
      if (f[k] < f[(k + 1) % 3]) e.emplace_back(f[k], f[(k + 1) % 3]);
  return e;
}

bool isFree(const ContactList& contacts, int i) {
  return contacts.vertex_contact_area.empty() || contacts.vertex_contact_area[i] <= 0;
}

}  // namespace

// ---------------------------------------------------------------------------------------------
// Fusion angle

FusionAngle fusionAngle(const CellSet& cells, const ContactList& contacts, bool free_surface_only) {
  FusionAngle out;
  const int nc = cells.numCells(), nv = cells.numVertices();
  if (static_cast<int>(cells.label.size()) != nc) {
    out.why = "cells.label has " + std::to_string(cells.label.size()) + " entries for " +
              std::to_string(nc) + " cells";
    return out;
  }
  if (free_surface_only && !contacts.vertex_contact_area.empty() &&
      static_cast<int>(contacts.vertex_contact_area.size()) != nv) {
    out.why = "contacts do not match the cells (vertex count)";
    return out;
  }
  Geometry geo;
  computeGeometry(cells, geo);
  double vol[2] = {0, 0};
  Vec3 moment[2] = {Vec3::Zero(), Vec3::Zero()};
  for (int c = 0; c < nc; ++c) {
    const int l = cells.label[c];
    if (l != 0 && l != 1) {
      out.why = "cell " + std::to_string(c) + " has spheroid label " + std::to_string(l) +
                " (0 or 1 expected)";
      return out;
    }
    vol[l] += geo.cell_volume[c];
    moment[l] += geo.cell_volume[c] * geo.cell_centroid[c];
  }
  if (!(vol[0] > 0) || !(vol[1] > 0)) {
    out.why = "needs cells of both spheroids (labels 0 and 1)";
    return out;
  }
  for (int l = 0; l < 2; ++l) out.centroid[l] = moment[l] / vol[l];
  const Vec3 o = out.centroid[0];
  out.distance_um = (out.centroid[1] - o).norm();
  if (!(out.distance_um > 0)) {
    out.why = "the two spheroid centroids coincide: no axis";
    return out;
  }
  const Vec3 e = (out.centroid[1] - o) / out.distance_um;
  // Axial coordinate s and the perpendicular offset q of every vertex; along an edge both are
  // linear, so a crossing's distance from the axis is |q_a + t (q_b − q_a)|.
  std::vector<double> s(nv);
  Eigen::Matrix3Xd q(3, nv);
  double smin = std::numeric_limits<double>::infinity(), smax = -smin;
  for (int i = 0; i < nv; ++i) {
    const Vec3 r = cells.x.col(i) - o;
    s[i] = r.dot(e);
    q.col(i) = r - s[i] * e;
    smin = std::min(smin, s[i]);
    smax = std::max(smax, s[i]);
  }
  out.length_um = smax - smin;
  std::vector<std::pair<int, int>> edges = uniqueEdges(cells);
  if (free_surface_only)
    std::erase_if(edges, [&](const auto& ed) {
      return !isFree(contacts, ed.first) || !isFree(contacts, ed.second);
    });
  // Largest distance from the axis at which the surface crosses the section at s0. Where no
  // edge crosses: 0 (a gap between the spheroids) — or no data (NaN) for the free surface only,
  // whose crossings are missing near every junction.
  const double none = free_surface_only ? kNaN : 0.0;
  auto section = [&](double s0) {
    double best2 = -1;
    for (const auto& [a, b] : edges) {
      const double da = s[a] - s0, db = s[b] - s0;
      if (da * db > 0) continue;
      if (da == db) {  // both on the section
        best2 = std::max({best2, q.col(a).squaredNorm(), q.col(b).squaredNorm()});
        continue;
      }
      const double t = da / (da - db);
      best2 = std::max(best2, (q.col(a) + t * (q.col(b) - q.col(a))).squaredNorm());
    }
    return best2 < 0 ? none : std::sqrt(best2);
  };
  // Coarse profile r_k over sections s_k = k d / K between the centroids. The neck is the
  // lowest section with a section at least as wide on each side of it (a trapped minimum): the
  // centroid sections of nearly fused spheroids (θ ≳ 70° for truncated spheres) are narrower
  // than the neck, but no bulge lies beyond them. No trapped minimum (one bulge: fully fused):
  // a = the widest section.
  const double d = out.distance_um;
  const int sections = 64;
  std::vector<double> r(sections + 1);
  for (int k = 0; k <= sections; ++k) r[k] = section(d * k / sections);
  std::vector<double> left(sections + 1, kNaN), right(sections + 1, kNaN);
  for (int k = 1; k <= sections; ++k)
    left[k] = std::isnan(left[k - 1]) ? r[k - 1] : std::fmax(left[k - 1], r[k - 1]);
  for (int k = sections - 1; k >= 0; --k)
    right[k] = std::isnan(right[k + 1]) ? r[k + 1] : std::fmax(right[k + 1], r[k + 1]);
  int best_k = -1, widest_k = -1;
  for (int k = 0; k <= sections; ++k) {
    if (std::isnan(r[k])) continue;
    if (widest_k < 0 || r[k] > r[widest_k]) widest_k = k;
    if (k > 0 && k < sections && r[k] <= left[k] && r[k] <= right[k] &&
        (best_k < 0 || r[k] < r[best_k]))
      best_k = k;
  }
  if (widest_k < 0) {
    out.why = "no surface crosses the axis between the centroids";
    return out;
  }
  double best = r[best_k < 0 ? widest_k : best_k];
  double best_s = d * (best_k < 0 ? widest_k : best_k) / sections;
  // Golden-section refinement of a trapped minimum between its neighbouring sections (the
  // profile is V-shaped at a neck); keeps the smallest value seen.
  if (best_k >= 0) {
    const double g = (std::sqrt(5.0) - 1) / 2;
    double lo = d * (best_k - 1) / sections, hi = d * (best_k + 1) / sections;
    auto f = [&](double x) {
      const double v = section(x);
      return std::isnan(v) ? std::numeric_limits<double>::infinity() : v;
    };
    double x1 = hi - g * (hi - lo), x2 = lo + g * (hi - lo);
    double f1 = f(x1), f2 = f(x2);
    for (int it = 0; it < 60 && hi - lo > 1e-9 * d; ++it) {
      if (f1 < best) best = f1, best_s = x1;
      if (f2 < best) best = f2, best_s = x2;
      if (f1 <= f2) {
        hi = x2;
        x2 = x1;
        f2 = f1;
        x1 = hi - g * (hi - lo);
        f1 = f(x1);
      } else {
        lo = x1;
        x1 = x2;
        f1 = f2;
        x2 = lo + g * (hi - lo);
        f2 = f(x2);
      }
    }
    if (f1 < best) best = f1, best_s = x1;
    if (f2 < best) best = f2, best_s = x2;
  }
  out.neck_radius_um = best;
  out.neck_position_um = best_s;
  out.theta_deg = 2 * std::atan(2 * best / out.length_um) / kDeg;
  out.ok = std::isfinite(out.theta_deg);
  if (!out.ok) out.why = "non-finite fusion angle";
  return out;
}

// ---------------------------------------------------------------------------------------------
// Shape index

double shapeIndex(const Geometry& geo, int c) {
  return geo.cell_area[c] / std::cbrt(geo.cell_volume[c] * geo.cell_volume[c]);
}

double meanShapeIndex(const Geometry& geo) {
  const int nc = static_cast<int>(geo.cell_volume.size());
  if (nc == 0) return kNaN;
  double sum = 0;
  for (int c = 0; c < nc; ++c) sum += shapeIndex(geo, c);
  return sum / nc;
}

// ---------------------------------------------------------------------------------------------
// Surface contact angle

SurfaceContactAngle surfaceContactAngle(const CellSet& cells, const ContactList& contacts) {
  SurfaceContactAngle out;
  const int nv = cells.numVertices();
  if (static_cast<int>(contacts.vertex_contact_area.size()) != nv) {
    out.why = "contacts do not match the cells (vertex count)";
    return out;
  }
  if (contacts.pairs.empty()) {
    out.why = "no contacts";
    return out;
  }
  // Vertex adjacency (CSR) and the mean edge length.
  const auto edges = uniqueEdges(cells);
  std::vector<int> start(nv + 1, 0), nbr(edges.size() * 2);
  double edge_sum = 0;
  for (const auto& [a, b] : edges) {
    ++start[a + 1];
    ++start[b + 1];
    edge_sum += (cells.x.col(a) - cells.x.col(b)).norm();
  }
  const double mean_edge = edges.empty() ? 0 : edge_sum / edges.size();
  for (int i = 0; i < nv; ++i) start[i + 1] += start[i];
  {
    std::vector<int> fill(start.begin(), start.end() - 1);
    for (const auto& [a, b] : edges) {
      nbr[fill[a]++] = b;
      nbr[fill[b]++] = a;
    }
  }
  // Free patches: connected components of free vertices.
  std::vector<int> patch(nv, -1);
  std::vector<std::vector<int>> patch_vertices;
  for (int i = 0; i < nv; ++i) {
    if (patch[i] >= 0 || !isFree(contacts, i)) continue;
    const int id = static_cast<int>(patch_vertices.size());
    patch_vertices.emplace_back();
    std::vector<int> stack{i};
    patch[i] = id;
    while (!stack.empty()) {
      const int v = stack.back();
      stack.pop_back();
      patch_vertices[id].push_back(v);
      for (int k = start[v]; k < start[v + 1]; ++k) {
        const int w = nbr[k];
        if (patch[w] < 0 && isFree(contacts, w)) {
          patch[w] = id;
          stack.push_back(w);
        }
      }
    }
  }
  std::vector<SphereFit> fits(patch_vertices.size());
  std::vector<char> fitted(patch_vertices.size(), 0);
  auto patchFit = [&](int p) -> const SphereFit& {
    if (!fitted[p]) {
      fitted[p] = 1;
      const auto& vs = patch_vertices[p];
      if (vs.size() >= 10) {
        Eigen::Matrix3Xd pts(3, static_cast<Eigen::Index>(vs.size()));
        for (size_t k = 0; k < vs.size(); ++k)
          pts.col(static_cast<Eigen::Index>(k)) = cells.x.col(vs[k]);
        fits[p] = fitSphere(pts);
        if (fits[p].ok && !(fits[p].rms <= 0.1 * fits[p].radius)) fits[p].ok = false;
      }
    }
    return fits[p];
  };
  // (vertex, other cell) for every vertex of a triangle in contact with another cell.
  std::vector<std::pair<int, int>> touch;
  for (const ContactPair& p : contacts.pairs) {
    const int ca = cells.tri_cell[p.ta], cb = cells.tri_cell[p.tb];
    for (int k = 0; k < 3; ++k) {
      touch.emplace_back(cells.tri[p.ta][k], cb);
      touch.emplace_back(cells.tri[p.tb][k], ca);
    }
  }
  std::sort(touch.begin(), touch.end());
  touch.erase(std::unique(touch.begin(), touch.end()), touch.end());
  // Rim points: (cell, other cell, free patch of cell, vertex) — a contact vertex of `cell`
  // touching `other`, next to a free vertex of that patch.
  struct Rim {
    int cell, other, patch, vertex;
    bool operator<(const Rim& r) const {
      return std::tie(cell, other, patch, vertex) < std::tie(r.cell, r.other, r.patch, r.vertex);
    }
    bool operator==(const Rim& r) const = default;
  };
  std::vector<Rim> rims;
  for (const auto& [v, other] : touch) {
    const int cell = cells.vertex_cell[v];
    for (int k = start[v]; k < start[v + 1]; ++k)
      if (patch[nbr[k]] >= 0) rims.push_back({cell, other, patch[nbr[k]], v});
  }
  std::sort(rims.begin(), rims.end());
  rims.erase(std::unique(rims.begin(), rims.end()), rims.end());
  // Groups of equal (cell, other, patch).
  struct Group {
    int cell, other, patch;
    size_t begin, end;
  };
  std::vector<Group> groups;
  for (size_t k = 0; k < rims.size();) {
    size_t e = k;
    while (e < rims.size() && rims[e].cell == rims[k].cell && rims[e].other == rims[k].other &&
           rims[e].patch == rims[k].patch)
      ++e;
    groups.push_back({rims[k].cell, rims[k].other, rims[k].patch, k, e});
    k = e;
  }
  const double tol2 = std::pow(3 * mean_edge, 2);
  double sum = 0, sum2 = 0;
  for (const Group& ga : groups) {
    if (ga.cell > ga.other) continue;  // each unordered cell pair once, from its lower cell
    if (!patchFit(ga.patch).ok) continue;
    for (const Group& gb : groups) {
      if (gb.cell != ga.other || gb.other != ga.cell || !patchFit(gb.patch).ok) continue;
      bool near = false;
      for (size_t i = ga.begin; i < ga.end && !near; ++i)
        for (size_t j = gb.begin; j < gb.end && !near; ++j)
          near = (cells.x.col(rims[i].vertex) - cells.x.col(rims[j].vertex)).squaredNorm() <= tol2;
      if (!near) continue;
      const SphereFit &a = fits[ga.patch], &b = fits[gb.patch];
      const double dd = (a.centre - b.centre).squaredNorm();
      const double cos_psi =
          (a.radius * a.radius + b.radius * b.radius - dd) / (2 * a.radius * b.radius);
      if (cos_psi > 1) continue;  // one sphere inside the other: no junction circle
      const double psi = std::acos(std::max(cos_psi, -1.0)) / kDeg;
      const double theta = 90 - psi / 2;
      sum += theta;
      sum2 += theta * theta;
      ++out.junctions;
    }
  }
  if (out.junctions == 0) {
    out.why = "no junction between free surface patches of contacting cells";
    return out;
  }
  out.theta_deg = sum / out.junctions;
  out.theta_sd_deg =
      out.junctions > 1
          ? std::sqrt(std::max(
                0.0, (sum2 - out.junctions * out.theta_deg * out.theta_deg) / (out.junctions - 1)))
          : 0.0;
  out.gsi = std::cos(out.theta_deg * kDeg);
  out.ok = true;
  return out;
}

}  // namespace activefoam
