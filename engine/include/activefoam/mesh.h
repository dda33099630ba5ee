// Closed, consistently oriented triangle meshes (outward normals) and their geometry.
#pragma once

#include <array>
#include <string>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

namespace activefoam {

using Vec3 = Eigen::Vector3d;
using Tri = std::array<int, 3>;  // vertex indices, counter-clockwise seen from outside

// One cell surface with local vertex indices. The engine keeps all cells packed in a CellSet;
// TriMesh is the per-cell form used by builders, the remesher and tests.
struct TriMesh {
  Eigen::Matrix3Xd x;  // positions, µm
  Eigen::Matrix3Xd v;  // velocities, µm/s (carried through remeshing for CG warm starts)
  std::vector<Tri> tri;

  int numVertices() const { return static_cast<int>(x.cols()); }
  int numTriangles() const { return static_cast<int>(tri.size()); }
};

// Unit icosahedron subdivided `levels` times, projected onto the unit sphere.
// levels = 1, 2, 3 give 80, 320, 1280 triangles (42, 162, 642 vertices).
TriMesh icosphere(int levels);

// Subdivision level for a triangle count (80 → 1, 320 → 2, 1280 → 3); -1 if not one of those.
int icosphereLevelForTriangles(int triangles);

// Signed volume Σ (1/6) x_i·(x_j × x_k) (positive for outward orientation).
double meshVolume(const TriMesh& m);
double meshArea(const TriMesh& m);
double triangleArea(const TriMesh& m, int t);

// Closest point of triangle abc to p (Ericson, Real-Time Collision Detection §5.1.5).
Vec3 closestOnTriangle(const Vec3& p, const Vec3& a, const Vec3& b, const Vec3& c);

// Solid angle of triangle abc seen from p (Van Oosterom & Strackee), positive when p lies behind
// it (on the side its normal points away from): summed over a closed outward mesh, 4π inside
// and 0 outside.
double solidAngle(const Vec3& p, const Vec3& a, const Vec3& b, const Vec3& c);

// The generalised winding number of the closed mesh m around p (1 inside, 0 outside).
double windingNumber(const TriMesh& m, const Vec3& p);

// Topological and geometric invariants: every edge shared by exactly two triangles with
// opposite orientation, vertex links are single cycles (2-manifold), no unused or out-of-range
// vertices, positive volume. Returns an empty string when valid, else the first violation.
std::string checkClosedManifold(const TriMesh& m);

}  // namespace activefoam
