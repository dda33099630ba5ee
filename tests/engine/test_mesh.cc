#include <cmath>

#include <gtest/gtest.h>

#include "activefoam/mesh.h"

using namespace activefoam;

TEST(Icosphere, CountsAndInvariants) {
  const int expectV[] = {12, 42, 162, 642}, expectT[] = {20, 80, 320, 1280};
  for (int l = 0; l <= 3; ++l) {
    TriMesh m = icosphere(l);
    EXPECT_EQ(m.numVertices(), expectV[l]);
    EXPECT_EQ(m.numTriangles(), expectT[l]);
    EXPECT_EQ(checkClosedManifold(m), "");
    // Inscribed in the unit sphere: volume below 4π/3 and converging to it.
    EXPECT_LT(meshVolume(m), 4.0 * M_PI / 3.0);
  }
  EXPECT_NEAR(meshVolume(icosphere(3)), 4.0 * M_PI / 3.0, 0.02 * 4.0 * M_PI / 3.0);
  EXPECT_NEAR(meshArea(icosphere(3)), 4.0 * M_PI, 0.02 * 4.0 * M_PI);
}

TEST(Mesh, VolumeIsTranslationInvariant) {
  TriMesh m = icosphere(2);
  const double v0 = meshVolume(m);
  m.x.colwise() += Vec3(3.0, -7.0, 11.0);
  EXPECT_NEAR(meshVolume(m), v0, 1e-12 * 1e3);
}

TEST(Mesh, ManifoldCheckCatchesDefects) {
  TriMesh m = icosphere(1);
  TriMesh flipped = m;
  std::swap(flipped.tri[3][0], flipped.tri[3][1]);
  EXPECT_NE(checkClosedManifold(flipped), "");
  TriMesh open = m;
  open.tri.pop_back();
  EXPECT_NE(checkClosedManifold(open), "");
  TriMesh inward = m;
  for (auto& t : inward.tri) std::swap(t[0], t[1]);
  EXPECT_NE(checkClosedManifold(inward), "");
}

TEST(Mesh, SolidAngleOfAnOctantIsAnEighthOfTheSphere) {
  // Normal (1,1,1)/√3 points away from the origin: the origin sees the triangle from behind.
  const Vec3 a(1, 0, 0), b(0, 1, 0), c(0, 0, 1), o = Vec3::Zero();
  EXPECT_NEAR(solidAngle(o, a, b, c), M_PI / 2, 1e-12);
  EXPECT_NEAR(solidAngle(o, a, c, b), -M_PI / 2, 1e-12);
  // Seen from far in front (on the normal's side) it is −area / distance² (area √3/2).
  const Vec3 far = Vec3(1, 1, 1) * (100 / std::sqrt(3.0));
  const double d = 100 - 1 / std::sqrt(3.0);
  EXPECT_NEAR(solidAngle(far, a, b, c), -std::sqrt(3.0) / 2 / (d * d), 1e-8);
}

TEST(Mesh, WindingNumberIsOneInsideAClosedMeshAndZeroOutside) {
  TriMesh m = icosphere(2);
  m.x *= 5.0;
  m.x.colwise() += Vec3(1, 2, 3);
  EXPECT_NEAR(windingNumber(m, Vec3(1, 2, 3)), 1.0, 1e-12);
  EXPECT_NEAR(windingNumber(m, Vec3(1 + 4.5, 2, 3)), 1.0, 1e-9);
  EXPECT_NEAR(windingNumber(m, Vec3(1 + 5.5, 2, 3)), 0.0, 1e-9);
  EXPECT_NEAR(windingNumber(m, Vec3(40, -30, 3)), 0.0, 1e-12);
  // Turned inside out, the same mesh winds −1 around its centre.
  for (auto& t : m.tri) std::swap(t[0], t[1]);
  EXPECT_NEAR(windingNumber(m, Vec3(1, 2, 3)), -1.0, 1e-12);
}
