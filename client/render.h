// A software renderer for `foam export --movie`: snapshots' cells as shaded surfaces into RGB
// frames, with no display, GPU or browser. It draws what the dashboard's 3D view draws
// (server/dashboard/view3d.js): cells coloured by spheroid, cell id, pressure or volume, lit by
// an ambient and a head light (Gouraud-shaded Lambert, both faces), seen by a perspective
// camera across the fusion axis; plus a line of text in a built-in bitmap font.
#pragma once

#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "activefoam/vtk.h"

namespace activefoam::client {

struct Rgb {
  std::uint8_t r = 0, g = 0, b = 0;
};

struct Image {
  int width = 0, height = 0;
  std::vector<std::uint8_t> rgb;  // row-major, top row first, 3 bytes a pixel
  Image(int w, int h, Rgb fill);
  Rgb at(int x, int y) const;
};

enum class ColorBy { Spheroid, Cell, Pressure, Volume };

// "spheroid", "cell", "pressure" or "volume"; false for anything else.
bool parseColorBy(const std::string& name, ColorBy& out);

// A fixed camera for a whole movie: it frames `box` (xmin ymin zmin xmax ymax zmax, µm) from
// across the x axis (the fusion axis of the fusion scene) at the given aspect ratio.
struct Camera {
  std::array<double, 3> eye{}, target{}, up{0, 1, 0};
  double fov_deg = 30;
};
Camera frameBox(const std::array<double, 6>& box, double aspect);

// The mesh's bounding box; an empty mesh gives an inverted box (min > max), which extendBox
// ignores.
std::array<double, 6> meshBox(const VtkMesh& mesh);
void extendBox(std::array<double, 6>& box, const std::array<double, 6>& more);

// Each cell's enclosed volume (µm³) by the divergence theorem, indexed by cell id.
std::vector<double> cellVolumes(const VtkMesh& mesh);

// Per cell id, the quantity `by` colours with (empty for spheroid and cell colouring).
std::vector<double> cellValues(const VtkMesh& mesh, ColorBy by);

// The colour of a cell: by its spheroid label, its id, or its value on a ramp over [lo, hi].
Rgb cellColor(ColorBy by, int cell_id, int label, double value, double lo, double hi);

// Draws the mesh into `img` over what is there (a z-buffer of its own). `lo`/`hi` fix the ramp
// of Pressure/Volume colouring, so that colours mean the same in every frame of a movie.
// Renders at `supersample`² samples a pixel and averages them (edges without jaggies).
void renderMesh(Image& img, const VtkMesh& mesh, const Camera& camera, ColorBy by, double lo,
                double hi, int supersample = 2);

// Text in a 5×7 bitmap font scaled by `scale`, top-left at (x, y): digits, space, . , : = - + /
// ( ) % and the letters a-z, A-Z (lower case drawn as capitals where the font has no lower case
// glyph). Returns the width drawn in pixels.
int drawText(Image& img, int x, int y, const std::string& text, int scale, Rgb color);
int textWidth(const std::string& text, int scale);

void fillRect(Image& img, int x, int y, int w, int h, Rgb color);

// "t = 600 s", "t = 25 min", "t = 3.25 h": the simulated time in the unit that reads best
// (seconds below 1000 s, minutes below 2 h).
std::string formatSimTime(double t_s);

}  // namespace activefoam::client
