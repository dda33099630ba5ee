// The movie renderer (see render.h).
#include "render.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <stdexcept>

namespace activefoam::client {
namespace {

using Vec = std::array<double, 3>;

Vec sub(const Vec& a, const Vec& b) {
  return {a[0] - b[0], a[1] - b[1], a[2] - b[2]};
}
double dot(const Vec& a, const Vec& b) {
  return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}
Vec cross(const Vec& a, const Vec& b) {
  return {a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]};
}
Vec scaled(const Vec& a, double s) {
  return {a[0] * s, a[1] * s, a[2] * s};
}
Vec normalized(const Vec& a) {
  const double n = std::sqrt(dot(a, a));
  return n > 0 ? scaled(a, 1 / n) : a;
}
Vec point(const VtkMesh& m, std::size_t v) {
  return {m.points[3 * v], m.points[3 * v + 1], m.points[3 * v + 2]};
}

// The dashboard's colours (view3d.js): spheroid A and B, and its viridis-like ramp.
constexpr Rgb kSpheroid[2] = {{0x1c, 0x6b, 0xb0}, {0xe8, 0x59, 0x0c}};
constexpr double kRamp[5][3] = {
    {68, 1, 84}, {59, 82, 139}, {33, 145, 140}, {94, 201, 98}, {253, 231, 37}};
// three.js MeshLambertMaterial under the view's lights: ambient 0.42, a head light of 0.72.
constexpr double kAmbient = 0.42, kDiffuse = 0.72;

std::uint8_t byte(double x) {
  return static_cast<std::uint8_t>(std::lround(std::clamp(x, 0.0, 1.0) * 255));
}

// HSL → RGB as three.js' Color.setHSL computes it.
Rgb hsl(double h, double s, double l) {
  auto hue = [](double p, double q, double t) {
    if (t < 0) t += 1;
    if (t > 1) t -= 1;
    if (t < 1.0 / 6) return p + (q - p) * 6 * t;
    if (t < 0.5) return q;
    if (t < 2.0 / 3) return p + (q - p) * 6 * (2.0 / 3 - t);
    return p;
  };
  const double q = l <= 0.5 ? l * (1 + s) : l + s - l * s, p = 2 * l - q;
  return {byte(hue(p, q, h + 1.0 / 3)), byte(hue(p, q, h)), byte(hue(p, q, h - 1.0 / 3))};
}

// 5×7 glyphs, one string per row, '#' = ink.
struct Glyph {
  char c;
  const char* rows[7];
};
// clang-format off
constexpr Glyph kFont[] = {
  {'0', {".###.", "#...#", "#..##", "#.#.#", "##..#", "#...#", ".###."}},
  {'1', {"..#..", ".##..", "..#..", "..#..", "..#..", "..#..", ".###."}},
  {'2', {".###.", "#...#", "....#", "...#.", "..#..", ".#...", "#####"}},
  {'3', {"#####", "...#.", "..#..", "...#.", "....#", "#...#", ".###."}},
  {'4', {"...#.", "..##.", ".#.#.", "#..#.", "#####", "...#.", "...#."}},
  {'5', {"#####", "#....", "####.", "....#", "....#", "#...#", ".###."}},
  {'6', {"..##.", ".#...", "#....", "####.", "#...#", "#...#", ".###."}},
  {'7', {"#####", "....#", "...#.", "..#..", ".#...", ".#...", ".#..."}},
  {'8', {".###.", "#...#", "#...#", ".###.", "#...#", "#...#", ".###."}},
  {'9', {".###.", "#...#", "#...#", ".####", "....#", "...#.", ".##.."}},
  {'.', {".....", ".....", ".....", ".....", ".....", ".##..", ".##.."}},
  {',', {".....", ".....", ".....", ".....", ".##..", "..#..", ".#..."}},
  {':', {".....", ".##..", ".##..", ".....", ".##..", ".##..", "....."}},
  {'=', {".....", ".....", "#####", ".....", "#####", ".....", "....."}},
  {'-', {".....", ".....", ".....", "#####", ".....", ".....", "....."}},
  {'+', {".....", "..#..", "..#..", "#####", "..#..", "..#..", "....."}},
  {'/', {".....", "....#", "...#.", "..#..", ".#...", "#....", "....."}},
  {'(', {"...#.", "..#..", ".#...", ".#...", ".#...", "..#..", "...#."}},
  {')', {".#...", "..#..", "...#.", "...#.", "...#.", "..#..", ".#..."}},
  {'%', {"##...", "##..#", "...#.", "..#..", ".#...", "#..##", "...##"}},
  {'^', {"..#..", ".#.#.", "#...#", ".....", ".....", ".....", "....."}},
  {'A', {".###.", "#...#", "#...#", "#####", "#...#", "#...#", "#...#"}},
  {'B', {"####.", "#...#", "#...#", "####.", "#...#", "#...#", "####."}},
  {'C', {".###.", "#...#", "#....", "#....", "#....", "#...#", ".###."}},
  {'D', {"###..", "#..#.", "#...#", "#...#", "#...#", "#..#.", "###.."}},
  {'E', {"#####", "#....", "#....", "####.", "#....", "#....", "#####"}},
  {'F', {"#####", "#....", "#....", "####.", "#....", "#....", "#...."}},
  {'G', {".###.", "#...#", "#....", "#.###", "#...#", "#...#", ".####"}},
  {'H', {"#...#", "#...#", "#...#", "#####", "#...#", "#...#", "#...#"}},
  {'I', {".###.", "..#..", "..#..", "..#..", "..#..", "..#..", ".###."}},
  {'J', {"..###", "...#.", "...#.", "...#.", "...#.", "#..#.", ".##.."}},
  {'K', {"#...#", "#..#.", "#.#..", "##...", "#.#..", "#..#.", "#...#"}},
  {'L', {"#....", "#....", "#....", "#....", "#....", "#....", "#####"}},
  {'M', {"#...#", "##.##", "#.#.#", "#.#.#", "#...#", "#...#", "#...#"}},
  {'N', {"#...#", "#...#", "##..#", "#.#.#", "#..##", "#...#", "#...#"}},
  {'O', {".###.", "#...#", "#...#", "#...#", "#...#", "#...#", ".###."}},
  {'P', {"####.", "#...#", "#...#", "####.", "#....", "#....", "#...."}},
  {'Q', {".###.", "#...#", "#...#", "#...#", "#.#.#", "#..#.", ".##.#"}},
  {'R', {"####.", "#...#", "#...#", "####.", "#.#..", "#..#.", "#...#"}},
  {'S', {".####", "#....", "#....", ".###.", "....#", "....#", "####."}},
  {'T', {"#####", "..#..", "..#..", "..#..", "..#..", "..#..", "..#.."}},
  {'U', {"#...#", "#...#", "#...#", "#...#", "#...#", "#...#", ".###."}},
  {'V', {"#...#", "#...#", "#...#", "#...#", "#...#", ".#.#.", "..#.."}},
  {'W', {"#...#", "#...#", "#...#", "#.#.#", "#.#.#", "#.#.#", ".#.#."}},
  {'X', {"#...#", "#...#", ".#.#.", "..#..", ".#.#.", "#...#", "#...#"}},
  {'Y', {"#...#", "#...#", ".#.#.", "..#..", "..#..", "..#..", "..#.."}},
  {'Z', {"#####", "....#", "...#.", "..#..", ".#...", "#....", "#####"}},
  {'a', {".....", ".....", ".###.", "....#", ".####", "#...#", ".####"}},
  {'b', {"#....", "#....", "#.##.", "##..#", "#...#", "#...#", "####."}},
  {'c', {".....", ".....", ".###.", "#....", "#....", "#...#", ".###."}},
  {'d', {"....#", "....#", ".##.#", "#..##", "#...#", "#...#", ".####"}},
  {'e', {".....", ".....", ".###.", "#...#", "#####", "#....", ".###."}},
  {'f', {"..##.", ".#..#", ".#...", "###..", ".#...", ".#...", ".#..."}},
  {'g', {".....", ".####", "#...#", "#...#", ".####", "....#", ".###."}},
  {'h', {"#....", "#....", "#.##.", "##..#", "#...#", "#...#", "#...#"}},
  {'i', {"..#..", ".....", ".##..", "..#..", "..#..", "..#..", ".###."}},
  {'j', {"...#.", ".....", "..##.", "...#.", "...#.", "#..#.", ".##.."}},
  {'k', {"#....", "#....", "#..#.", "#.#..", "##...", "#.#..", "#..#."}},
  {'l', {".##..", "..#..", "..#..", "..#..", "..#..", "..#..", ".###."}},
  {'m', {".....", ".....", "##.#.", "#.#.#", "#.#.#", "#...#", "#...#"}},
  {'n', {".....", ".....", "#.##.", "##..#", "#...#", "#...#", "#...#"}},
  {'o', {".....", ".....", ".###.", "#...#", "#...#", "#...#", ".###."}},
  {'p', {".....", ".....", "####.", "#...#", "#...#", "####.", "#...."}},
  {'q', {".....", ".....", ".##.#", "#..##", ".####", "....#", "....#"}},
  {'r', {".....", ".....", "#.##.", "##..#", "#....", "#....", "#...."}},
  {'s', {".....", ".....", ".###.", "#....", ".###.", "....#", "####."}},
  {'t', {".#...", ".#...", "###..", ".#...", ".#...", ".#..#", "..##."}},
  {'u', {".....", ".....", "#...#", "#...#", "#...#", "#..##", ".##.#"}},
  {'v', {".....", ".....", "#...#", "#...#", "#...#", ".#.#.", "..#.."}},
  {'w', {".....", ".....", "#...#", "#...#", "#.#.#", "#.#.#", ".#.#."}},
  {'x', {".....", ".....", "#...#", ".#.#.", "..#..", ".#.#.", "#...#"}},
  {'y', {".....", ".....", "#...#", "#...#", ".####", "....#", ".###."}},
  {'z', {".....", ".....", "#####", "...#.", "..#..", ".#...", "#####"}},
};
// clang-format on

const Glyph* glyph(char c) {
  for (const Glyph& g : kFont)
    if (g.c == c) return &g;
  return nullptr;  // a space, or a character the font lacks: drawn as a gap
}

}  // namespace

Image::Image(int w, int h, Rgb fill) : width(w), height(h) {
  if (w <= 0 || h <= 0) throw std::invalid_argument("image size must be positive");
  rgb.resize(static_cast<std::size_t>(w) * static_cast<std::size_t>(h) * 3);
  for (std::size_t k = 0; k < rgb.size(); k += 3) {
    rgb[k] = fill.r;
    rgb[k + 1] = fill.g;
    rgb[k + 2] = fill.b;
  }
}

Rgb Image::at(int x, int y) const {
  const std::size_t k = 3 * (static_cast<std::size_t>(y) * static_cast<std::size_t>(width) +
                             static_cast<std::size_t>(x));
  return {rgb[k], rgb[k + 1], rgb[k + 2]};
}

bool parseColorBy(const std::string& name, ColorBy& out) {
  if (name == "spheroid")
    out = ColorBy::Spheroid;
  else if (name == "cell")
    out = ColorBy::Cell;
  else if (name == "pressure")
    out = ColorBy::Pressure;
  else if (name == "volume")
    out = ColorBy::Volume;
  else
    return false;
  return true;
}

Camera frameBox(const std::array<double, 6>& b, double aspect) {
  Camera cam;
  cam.target = {(b[0] + b[3]) / 2, (b[1] + b[4]) / 2, (b[2] + b[5]) / 2};
  // As the dashboard frames its first snapshot (view3d.js frameDistance): x across the width,
  // y and z as the 19° tilt projects them up the height, with a margin.
  const double tan_half = std::tan(cam.fov_deg * M_PI / 360);
  const double rx = std::max(0.5, (b[3] - b[0]) / 2), ry = std::max(0.5, (b[4] - b[1]) / 2),
               rz = (b[5] - b[2]) / 2;
  const double distance =
      1.1 * std::max((0.95 * ry + 0.35 * rz) / tan_half, rx / (tan_half * aspect)) + rz;
  const Vec dir = normalized({0, -0.35, 1});
  for (int d = 0; d < 3; ++d) cam.eye[d] = cam.target[d] + dir[d] * distance;
  return cam;
}

std::array<double, 6> meshBox(const VtkMesh& m) {
  constexpr double inf = std::numeric_limits<double>::infinity();
  std::array<double, 6> b{inf, inf, inf, -inf, -inf, -inf};
  for (std::size_t k = 0; k + 2 < m.points.size(); k += 3)
    for (std::size_t d = 0; d < 3; ++d) {
      b[d] = std::min(b[d], m.points[k + d]);
      b[d + 3] = std::max(b[d + 3], m.points[k + d]);
    }
  return b;
}

void extendBox(std::array<double, 6>& box, const std::array<double, 6>& more) {
  if (more[0] > more[3]) return;
  for (int d = 0; d < 3; ++d) {
    box[d] = std::min(box[d], more[d]);
    box[d + 3] = std::max(box[d + 3], more[d + 3]);
  }
}

std::vector<double> cellVolumes(const VtkMesh& m) {
  std::vector<double> vol;
  const std::size_t nv = m.points.size() / 3;
  for (const auto& t : m.tri) {
    if (t[0] < 0 || t[1] < 0 || t[2] < 0 || static_cast<std::size_t>(t[0]) >= nv ||
        static_cast<std::size_t>(t[1]) >= nv || static_cast<std::size_t>(t[2]) >= nv)
      continue;
    const int c = m.vertex_cell.empty() ? 0 : m.vertex_cell[static_cast<std::size_t>(t[0])];
    if (c < 0) continue;
    if (static_cast<std::size_t>(c) >= vol.size()) vol.resize(static_cast<std::size_t>(c) + 1, 0);
    const Vec a = point(m, static_cast<std::size_t>(t[0])),
              b = point(m, static_cast<std::size_t>(t[1])),
              d = point(m, static_cast<std::size_t>(t[2]));
    vol[static_cast<std::size_t>(c)] += dot(a, cross(b, d)) / 6;
  }
  return vol;
}

std::vector<double> cellValues(const VtkMesh& m, ColorBy by) {
  if (by == ColorBy::Pressure) return m.cell_pressure;
  if (by == ColorBy::Volume) return cellVolumes(m);
  return {};
}

Rgb cellColor(ColorBy by, int cell_id, int label, double value, double lo, double hi) {
  switch (by) {
    case ColorBy::Spheroid:
      return kSpheroid[label == 1 ? 1 : 0];
    case ColorBy::Cell:
      // The golden angle spreads neighbouring ids' hues apart (as the dashboard does).
      return hsl(std::fmod(cell_id * 0.618034, 1.0), 0.55, 0.55);
    case ColorBy::Pressure:
    case ColorBy::Volume: {
      double t = hi > lo ? (value - lo) / (hi - lo) : 0.5;
      if (!std::isfinite(t)) t = 0;
      const double x = std::clamp(t, 0.0, 1.0) * 4;
      const int i = std::min(3, static_cast<int>(x));
      const double f = x - i;
      auto ch = [&](int k) {
        return byte((kRamp[i][k] + (kRamp[i + 1][k] - kRamp[i][k]) * f) / 255);
      };
      return {ch(0), ch(1), ch(2)};
    }
  }
  return {};
}

void renderMesh(Image& img, const VtkMesh& m, const Camera& cam, ColorBy by, double lo, double hi,
                int ss) {
  ss = std::clamp(ss, 1, 4);
  const int W = img.width * ss, H = img.height * ss;
  const std::size_t nv = m.points.size() / 3;
  // Camera basis: f forward, s right, u up.
  const Vec f = normalized(sub(cam.target, cam.eye));
  const Vec s = normalized(cross(f, cam.up));
  const Vec u = cross(s, f);
  const Vec light = normalized(sub(scaled(s, 0.4), sub(f, scaled(u, 0.6))));
  const double focal = 0.5 * H / std::tan(cam.fov_deg * M_PI / 360);

  // Per vertex: camera-space position, screen position, area-weighted normal, colour.
  std::vector<Vec> cs(nv), normal(nv, Vec{0, 0, 0});
  std::vector<double> sx(nv), sy(nv);
  for (std::size_t v = 0; v < nv; ++v) {
    const Vec d = sub(point(m, v), cam.eye);
    cs[v] = {dot(d, s), dot(d, u), dot(d, f)};
    sx[v] = 0.5 * W + focal * cs[v][0] / cs[v][2];
    sy[v] = 0.5 * H - focal * cs[v][1] / cs[v][2];
  }
  auto valid = [&](const std::array<int, 3>& t) {
    for (int k : t)
      if (k < 0 || static_cast<std::size_t>(k) >= nv) return false;
    return true;
  };
  for (const auto& t : m.tri) {
    if (!valid(t)) continue;
    const Vec a = point(m, static_cast<std::size_t>(t[0]));
    const Vec n = cross(sub(point(m, static_cast<std::size_t>(t[1])), a),
                        sub(point(m, static_cast<std::size_t>(t[2])), a));  // |n| = twice the area
    for (int k : t)
      for (int d = 0; d < 3; ++d) normal[static_cast<std::size_t>(k)][d] += n[d];
  }
  const std::vector<double> values = cellValues(m, by);
  std::vector<Rgb> color(nv);
  for (std::size_t v = 0; v < nv; ++v) {
    const int c = m.vertex_cell.empty() ? 0 : m.vertex_cell[v];
    const auto ci = static_cast<std::size_t>(std::max(0, c));
    const int label = ci < m.cell_label.size() ? m.cell_label[ci] : 0;
    const double value = ci < values.size() ? values[ci] : 0;
    color[v] = cellColor(by, c, label, value, lo, hi);
    normal[v] = normalized(normal[v]);
  }

  // The supersampled buffer starts as the image (its background) and is averaged back into it.
  std::vector<float> buf(static_cast<std::size_t>(W) * static_cast<std::size_t>(H) * 3);
  for (int y = 0; y < H; ++y)
    for (int x = 0; x < W; ++x) {
      const Rgb p = img.at(x / ss, y / ss);
      float* q = &buf[3 * (static_cast<std::size_t>(y) * static_cast<std::size_t>(W) +
                           static_cast<std::size_t>(x))];
      q[0] = p.r;
      q[1] = p.g;
      q[2] = p.b;
    }
  std::vector<float> depth(static_cast<std::size_t>(W) * static_cast<std::size_t>(H), 0.0f);
  const double near = 1e-6 * std::sqrt(dot(sub(cam.target, cam.eye), sub(cam.target, cam.eye)));

  for (const auto& t : m.tri) {
    if (!valid(t)) continue;
    const auto i0 = static_cast<std::size_t>(t[0]), i1 = static_cast<std::size_t>(t[1]),
               i2 = static_cast<std::size_t>(t[2]);
    if (cs[i0][2] <= near || cs[i1][2] <= near || cs[i2][2] <= near) continue;
    const double area =
        (sx[i1] - sx[i0]) * (sy[i2] - sy[i0]) - (sx[i2] - sx[i0]) * (sy[i1] - sy[i0]);
    if (std::abs(area) < 1e-12) continue;
    // Both faces are drawn, each lit from its own side (three.js' DoubleSide): a face turned
    // away from the camera takes its normals reversed.
    const Vec a = point(m, i0);
    const Vec fn = cross(sub(point(m, i1), a), sub(point(m, i2), a));
    const double side = dot(fn, sub(cam.eye, a)) >= 0 ? 1.0 : -1.0;
    float col[3][3];
    const std::size_t idx[3] = {i0, i1, i2};
    for (int k = 0; k < 3; ++k) {
      const double lambert = std::max(0.0, side * dot(normal[idx[k]], light));
      const double shade = kAmbient + kDiffuse * lambert;
      const Rgb c = color[idx[k]];
      col[k][0] = static_cast<float>(std::min(255.0, c.r * shade));
      col[k][1] = static_cast<float>(std::min(255.0, c.g * shade));
      col[k][2] = static_cast<float>(std::min(255.0, c.b * shade));
    }
    const double iz[3] = {1 / cs[i0][2], 1 / cs[i1][2], 1 / cs[i2][2]};
    const int x0 = std::max(0, static_cast<int>(std::floor(std::min({sx[i0], sx[i1], sx[i2]}))));
    const int x1 = std::min(W - 1, static_cast<int>(std::ceil(std::max({sx[i0], sx[i1], sx[i2]}))));
    const int y0 = std::max(0, static_cast<int>(std::floor(std::min({sy[i0], sy[i1], sy[i2]}))));
    const int y1 = std::min(H - 1, static_cast<int>(std::ceil(std::max({sy[i0], sy[i1], sy[i2]}))));
    const double inv = 1 / area;
    for (int y = y0; y <= y1; ++y) {
      const double py = y + 0.5;
      for (int x = x0; x <= x1; ++x) {
        const double px = x + 0.5;
        const double w0 =
            ((sx[i2] - sx[i1]) * (py - sy[i1]) - (sy[i2] - sy[i1]) * (px - sx[i1])) * inv;
        const double w1 =
            ((sx[i0] - sx[i2]) * (py - sy[i2]) - (sy[i0] - sy[i2]) * (px - sx[i2])) * inv;
        const double w2 = 1 - w0 - w1;
        if (w0 < 0 || w1 < 0 || w2 < 0) continue;
        const float z = static_cast<float>(w0 * iz[0] + w1 * iz[1] + w2 * iz[2]);
        const std::size_t p =
            static_cast<std::size_t>(y) * static_cast<std::size_t>(W) + static_cast<std::size_t>(x);
        if (z <= depth[p]) continue;  // 1/z: larger is nearer
        depth[p] = z;
        for (int k = 0; k < 3; ++k)
          buf[3 * p + static_cast<std::size_t>(k)] =
              static_cast<float>(w0 * col[0][k] + w1 * col[1][k] + w2 * col[2][k]);
      }
    }
  }

  const float norm = 1.0f / static_cast<float>(ss * ss);
  for (int y = 0; y < img.height; ++y)
    for (int x = 0; x < img.width; ++x)
      for (int k = 0; k < 3; ++k) {
        float sum = 0;
        for (int dy = 0; dy < ss; ++dy)
          for (int dx = 0; dx < ss; ++dx)
            sum += buf[3 * (static_cast<std::size_t>(y * ss + dy) * static_cast<std::size_t>(W) +
                            static_cast<std::size_t>(x * ss + dx)) +
                       static_cast<std::size_t>(k)];
        img.rgb[3 * (static_cast<std::size_t>(y) * static_cast<std::size_t>(img.width) +
                     static_cast<std::size_t>(x)) +
                static_cast<std::size_t>(k)] =
            static_cast<std::uint8_t>(std::lround(std::clamp(sum * norm, 0.0f, 255.0f)));
      }
}

void fillRect(Image& img, int x, int y, int w, int h, Rgb c) {
  for (int yy = std::max(0, y); yy < std::min(img.height, y + h); ++yy)
    for (int xx = std::max(0, x); xx < std::min(img.width, x + w); ++xx) {
      const std::size_t k =
          3 * (static_cast<std::size_t>(yy) * static_cast<std::size_t>(img.width) +
               static_cast<std::size_t>(xx));
      img.rgb[k] = c.r;
      img.rgb[k + 1] = c.g;
      img.rgb[k + 2] = c.b;
    }
}

int textWidth(const std::string& text, int scale) {
  return text.empty() ? 0 : static_cast<int>(text.size()) * 6 * scale - scale;
}

int drawText(Image& img, int x, int y, const std::string& text, int scale, Rgb color) {
  int pen = x;
  for (char c : text) {
    if (const Glyph* g = glyph(c))
      for (int row = 0; row < 7; ++row)
        for (int col = 0; col < 5; ++col)
          if (g->rows[row][col] == '#')
            fillRect(img, pen + col * scale, y + row * scale, scale, scale, color);
    pen += 6 * scale;
  }
  return pen - x - (text.empty() ? 0 : scale);
}

std::string formatSimTime(double t_s) {
  double v = t_s;
  const char* unit = "s";
  if (std::abs(t_s) >= 7200) {
    v = t_s / 3600;
    unit = "h";
  } else if (std::abs(t_s) >= 1000) {
    v = t_s / 60;
    unit = "min";
  }
  char buf[64];
  std::snprintf(buf, sizeof buf, "t = %.4g %s", v, unit);
  return buf;
}

}  // namespace activefoam::client
