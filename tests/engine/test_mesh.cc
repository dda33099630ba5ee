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
