// foam's movie renderer (client/render.h) on meshes made by hand: what is drawn where, which
// surface hides which, the colours, the framing, the text and the time label.
#include <gtest/gtest.h>

#include <cmath>

#include "render.h"

using activefoam::VtkMesh;
using namespace activefoam::client;

namespace {

constexpr Rgb kBg{0xf4, 0xf6, 0xf9};

bool isBackground(const Rgb& p) {
  return p.r == kBg.r && p.g == kBg.g && p.b == kBg.b;
}

// A closed octahedron of "radius" r around c, as cell `cell` (its 8 triangles wound outwards).
void addOctahedron(VtkMesh& m, double cx, double cy, double cz, double r, int cell) {
  const int base = static_cast<int>(m.points.size() / 3);
  const double v[6][3] = {{r, 0, 0}, {-r, 0, 0}, {0, r, 0}, {0, -r, 0}, {0, 0, r}, {0, 0, -r}};
  for (const auto& p : v) {
    m.points.insert(m.points.end(), {cx + p[0], cy + p[1], cz + p[2]});
    m.vertex_cell.push_back(cell);
  }
  const int f[8][3] = {{0, 2, 4}, {2, 1, 4}, {1, 3, 4}, {3, 0, 4},
                       {2, 0, 5}, {1, 2, 5}, {3, 1, 5}, {0, 3, 5}};
  for (const auto& t : f) m.tri.push_back({base + t[0], base + t[1], base + t[2]});
}

bool bluish(const Rgb& p) {
  return p.b > p.r + 40;
}
bool orangish(const Rgb& p) {
  return p.r > p.b + 60;
}

}  // namespace

TEST(Render, TwoSpheroidsFramedSideBySideInTheirColours) {
  VtkMesh m;
  addOctahedron(m, -12, 0, 0, 10, 0);
  addOctahedron(m, 12, 0, 0, 10, 1);
  m.cell_label = {0, 1};
  Image img(320, 180, kBg);
  const Camera cam = frameBox(meshBox(m), 320.0 / 180);
  renderMesh(img, m, cam, ColorBy::Spheroid, 0, 0);
  // Spheroid A (label 0) left of the middle, B right of it; the corners stay background.
  EXPECT_TRUE(bluish(img.at(110, 90))) << int(img.at(110, 90).r) << "," << int(img.at(110, 90).b);
  EXPECT_TRUE(orangish(img.at(210, 90)));
  for (auto [x, y] : {std::pair{0, 0}, {319, 0}, {0, 179}, {319, 179}})
    EXPECT_TRUE(isBackground(img.at(x, y))) << x << "," << y;
  // Framed: every drawn pixel inside the image, and the scene spans a good part of it.
  int left = 320, right = -1;
  for (int y = 0; y < 180; ++y)
    for (int x = 0; x < 320; ++x)
      if (!isBackground(img.at(x, y))) {
        left = std::min(left, x);
        right = std::max(right, x);
      }
  EXPECT_GT(left, 0);
  EXPECT_LT(right, 319);
  EXPECT_GT(right - left, 320 / 3);
}

TEST(Render, TheNearerSurfaceHidesTheFartherWhateverTheOrder) {
  Camera cam;  // on the z axis, looking at the origin
  cam.eye = {0, 0, 100};
  cam.target = {0, 0, 0};
  for (bool near_first : {true, false}) {
    VtkMesh m;
    if (near_first) addOctahedron(m, 0, 0, 30, 5, 1);
    addOctahedron(m, 0, 0, 0, 12, 0);
    if (!near_first) addOctahedron(m, 0, 0, 30, 5, 1);
    m.cell_label = {0, 1};
    Image img(200, 200, kBg);
    renderMesh(img, m, cam, ColorBy::Spheroid, 0, 0);
    // The small near cell (orange) covers the middle of the big far one (blue).
    int orange = 0, blue = 0;
    for (int y = 90; y < 110; ++y)
      for (int x = 90; x < 110; ++x) {
        orange += orangish(img.at(x, y));
        blue += bluish(img.at(x, y));
      }
    EXPECT_EQ(orange, 400) << "near cell listed " << (near_first ? "first" : "last");
    EXPECT_EQ(blue, 0) << "near cell listed " << (near_first ? "first" : "last");
    EXPECT_TRUE(bluish(img.at(100, 68)));  // the far cell around it
  }
}

TEST(Render, ColoursByCellAndByValueOnAFixedRamp) {
  EXPECT_NE(cellColor(ColorBy::Cell, 0, 0, 0, 0, 0).r, cellColor(ColorBy::Cell, 1, 0, 0, 0, 0).r);
  const Rgb lo = cellColor(ColorBy::Pressure, 0, 0, 1.0, 1.0, 3.0);
  const Rgb hi = cellColor(ColorBy::Pressure, 0, 0, 3.0, 1.0, 3.0);
  const Rgb over = cellColor(ColorBy::Pressure, 0, 0, 9.0, 1.0, 3.0);
  EXPECT_EQ(lo.r, 68);  // the ramp's ends (viridis'), as the dashboard's
  EXPECT_EQ(lo.b, 84);
  EXPECT_EQ(hi.r, 253);
  EXPECT_EQ(hi.g, 231);
  EXPECT_EQ(over.r, hi.r);  // clamped
  bool parsed = false;
  ColorBy by = ColorBy::Spheroid;
  for (const char* name : {"spheroid", "cell", "pressure", "volume"})
    parsed = parseColorBy(name, by);
  EXPECT_TRUE(parsed);
  EXPECT_EQ(by, ColorBy::Volume);
  EXPECT_FALSE(parseColorBy("rainbow", by));
}

TEST(Render, CellVolumesByTheDivergenceTheorem) {
  VtkMesh m;
  addOctahedron(m, 3, -2, 7, 1.5, 0);
  addOctahedron(m, 0, 0, 0, 2, 2);
  const std::vector<double> v = cellVolumes(m);
  ASSERT_EQ(v.size(), 3u);
  EXPECT_NEAR(v[0], 4.0 / 3 * 1.5 * 1.5 * 1.5, 1e-12);  // an octahedron: (4/3) r³
  EXPECT_EQ(v[1], 0.0);
  EXPECT_NEAR(v[2], 4.0 / 3 * 8, 1e-12);
}

TEST(Render, TextInkAndWidth) {
  Image img(100, 20, kBg);
  const int w = drawText(img, 2, 2, "t = 5 s", 2, Rgb{0, 0, 0});
  EXPECT_EQ(w, textWidth("t = 5 s", 2));
  EXPECT_EQ(w, 7 * 12 - 2);
  int ink = 0, outside = 0;
  for (int y = 0; y < 20; ++y)
    for (int x = 0; x < 100; ++x) {
      const bool black = img.at(x, y).r == 0;
      ink += black;
      outside += black && (x < 2 || x >= 2 + w || y < 2 || y >= 2 + 14);
    }
  EXPECT_GT(ink, 40);
  EXPECT_EQ(outside, 0);
}

TEST(Render, SimulatedTimeInTheUnitThatReadsBest) {
  EXPECT_EQ(formatSimTime(0), "t = 0 s");
  EXPECT_EQ(formatSimTime(600), "t = 600 s");
  EXPECT_EQ(formatSimTime(1500), "t = 25 min");
  EXPECT_EQ(formatSimTime(3 * 3600), "t = 3 h");
}
