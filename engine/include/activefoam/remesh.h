// Brakke-style remeshing of one closed cell surface (docs/model.md §6.3).
#pragma once

#include <functional>
#include <vector>

#include "activefoam/mesh.h"

namespace activefoam {

struct RemeshParams {
  double min_area = 0;  // A_m: collapse the shortest edge of triangles smaller than this (0: off)
  double max_area = 0;  // A_M: split the longest edge of triangles larger than this (≤ 0: off)
  int max_passes = 8;   // bound on split/collapse/flip sweeps per call (see remesh())

  // Added to the original API:
  // A flip changes the enclosed volume by the tetrahedron spanned by its two triangles (on a
  // curved cell typically 1e-5…1e-4 of the volume per flip: with a 1e-5 cap most Delaunay flips
  // would be refused). With flip_volume_correction the four quad vertices are then moved along
  // their volume gradients so that the volume is restored exactly; each move is at most 5% of
  // the shortest quad edge, else the flip is refused (measured: tens of nm on a 320-triangle
  // cell of radius 8.9 µm). flip_max_volume (fraction of the cell volume, per flip) then only
  // guards against flipping across creases. Without the correction set it small (e.g. 1e-5):
  // every flip then changes the volume by up to that much.
  bool flip_volume_correction = true;
  double flip_max_volume = 1e-3;
  // Refuse a collapse whose volume change exceeds this fraction of the cell volume (reachable
  // only when the volume-preserving placement is ill-conditioned and skipped).
  double collapse_max_volume = 1e-4;
  int min_vertices = 12;       // never collapse below this many vertices
  int max_vertices = 1 << 16;  // never split beyond this many (bounds a tiny max_area)
  bool flips = true;           // Delaunay flips on/off
  // A collapse that would leave a neighbour of its edge with valence 3 is refused, which keeps
  // the valence ≥ 4 but can lock a patch: a small triangle whose vertices are all of valence 4
  // (three such vertices inside a triangle of three others, on a crumpled cell of a motile
  // fusion) can be neither collapsed nor flipped, and flattens until it inverts. With rescue, a
  // remesh that leaves a triangle below half of min_area runs its passes once more, allowing
  // such collapses; a remesh that needs no rescue is the same as without it.
  bool rescue = false;
  // With rebuild_triangles > 0 (80, 320 or 1280), a remesh that still leaves a triangle below
  // half of min_area (after the rescue, when that is on) replaces the cell's mesh by a fresh
  // icosphere of that many triangles laid on the surface it had (rebuildRadially), when that
  // succeeds and leaves its smallest triangle larger. The rescue's collapses can be refused in
  // turn in a crumpled cell that has lost a quarter of its vertices (a cell of a motile fusion at
  // p_a r/2γ = 1 and Δt 0.5 s, its smallest triangle flattening from 0.4 to 9e-4 of min_area over
  // 25 remeshes until it inverted; docs/numerics.md). A remesh that leaves no such triangle is
  // the same as without it.
  int rebuild_triangles = 0;
  // Tangential smoothing of the vertices of triangles smaller than min_area or with an angle
  // below this (degrees; 0: off): what the collapse and flip guards refuse (see smoothing.cc).
  // The simulation uses 15°.
  double smooth_min_angle_deg = 0;
  // Smoothing keeps every vertex on the surface it had (numerics.remesh_on_surface): a smoothed
  // vertex is projected back onto its old ring instead of being moved along its volume gradient,
  // and the volume smoothing changed is restored once at the end by offsetting the whole cell
  // along its vertex normals (10⁻³–10⁻² µm). Smoothing's local correction moved vertices along
  // their normals by up to half an edge, which at a contact put them inside the neighbouring
  // cell (a smoothed vertex 1.0 µm into its neighbour on 80-triangle cells). Collapses and
  // flips keep their local volume placement either way (see remesh.cc).
  bool on_surface = false;
  // With keep_out set (a function of a point: how deep it lies inside the other cells near this
  // one, 0 outside), a collapse whose merged vertex would lie deeper than keep_out_um inside
  // another cell, and deeper than both vertices it merges, is refused. The volume-preserving
  // placement moves the merged vertex along its ring's normal by up to half the edge, and
  // chained collapses add up: on a cell pressed against its neighbour (fig9, τ_p = 40 min) two
  // collapses merged three vertices into one 1.28 µm inside the neighbour, a remesh that failed
  // the step at every Δt down to the floor (docs/numerics.md). Unset: every such collapse is
  // done (earlier versions).
  std::function<double(const Vec3&)> keep_out;
  double keep_out_um = 0;
  // With keep_out_points set (it fills the vertices of the cells this one touches; called only
  // when a rebuild is about to be done), a rebuild that would put one of them deeper than
  // keep_out_um inside the rebuilt surface, and deeper than inside the surface before, is refused:
  // the cell keeps its mesh, as for any refused rebuild. The rebuild lays each direction's new
  // vertex at the outermost crossing, over the crumpled cell's folds, and a neighbour's vertex
  // pressed into a fold ended 1.71 µm inside the rebuilt cell (fig8, p_a r/2γ = 1, α 0.4375: a
  // failure at every Δt; docs/numerics.md). Unset: every such rebuild is done (earlier versions).
  std::function<void(std::vector<Vec3>&)> keep_out_points;
};

struct RemeshStats {
  int splits = 0;
  int collapses = 0;
  int flips = 0;
  int smooths = 0;            // vertices moved by tangential smoothing
  int rescues = 0;            // 1 when the remesh ran the rescue (RemeshParams::rescue)
  int rebuilds = 0;           // 1 when it rebuilt the mesh (RemeshParams::rebuild_triangles)
  double volume_offset = 0;   // on_surface: the cell's normal offset that restored its volume
  int refused_collapses = 0;  // candidates rejected by the manifold/orientation/valence guards
  int refused_flips = 0;      // Delaunay-violating edges kept by the flip guards
  int kept_out = 0;  // collapses refused by RemeshParams::keep_out (also refused_collapses)
  int rebuilds_kept_out = 0;  // 1 when RemeshParams::keep_out_points refused a rebuild
  double volume_before = 0;
  double volume_after = 0;
  int operations() const { return splits + collapses + flips + smooths + rebuilds; }
};

// Splits, collapses and Delaunay flips in place. Keeps the mesh closed, 2-manifold, oriented,
// with vertex valence ≥ 4 (≥ 3 after a rescue: RemeshParams::rescue); keeps the enclosed volume
// (collapsed vertices are placed to preserve it). Velocities are carried along (averaged on
// split/collapse) for the CG warm start.
//
// Passes: each pass runs split sweeps until none applies, then collapse sweeps, then flip sweeps
// (each kind at most max_passes sweeps per pass); passes repeat until one changes nothing or
// max_passes passes ran. Within a sweep no triangle/vertex is modified twice.
//
// Volume: splits put the new vertex on the straight edge (exact up to round-off); collapses
// place the merged vertex so that the enclosed volume is unchanged (closed form, round-off
// level); flips are volume-corrected (see RemeshParams), else change it by their tetrahedron.
//
// Refusal counters count refusal events: a candidate refused in several sweeps counts each time.
//
// Vertex numbering: on any operation vertices are renumbered (surviving vertices keep their
// relative order, removed ones are compacted out, split vertices are appended). A call that
// changes nothing leaves the mesh bit-identical.
RemeshStats remesh(TriMesh& mesh, const RemeshParams& params);

// Same, and reports the renumbering: old_to_new has one entry per vertex of the input mesh, the
// index in the output mesh of the vertex it became (a collapsed vertex maps to the vertex it was
// merged into). Vertices created by splits are the ones no input vertex maps to. After a rebuild
// (RemeshStats::rebuilds) each input vertex maps to the new vertex nearest to it.
RemeshStats remesh(TriMesh& mesh, const RemeshParams& params, std::vector<int>& old_to_new);

// Replaces a closed cell mesh by the unit icosphere of `triangles` triangles (80, 320 or 1280)
// laid on it: each icosphere vertex goes, along its direction from the cell's volume centroid, to
// the outermost crossing of that ray with the old surface (a fold the ray crosses three times is
// covered from outside), takes the velocity interpolated there, and the new mesh is then scaled
// about the centroid to the old volume. Refuses (returns false, mesh unchanged) when a ray misses
// the surface or a new triangle does not face away from the centroid: a cell that is not
// star-shaped enough from its centroid.
bool rebuildRadially(TriMesh& mesh, int triangles);

}  // namespace activefoam
