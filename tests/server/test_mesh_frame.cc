// The 3D view's binary mesh (server/mesh_frame.h): cells grouped whatever the snapshot's vertex
// order, triangles renumbered with them, per-cell labels and pressures by cell id.
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <cstdint>
#include <cstring>
#include <stdexcept>

#include "mesh_frame.h"

using activefoam::VtkMesh;
using activefoam::server::encodeMeshFrame;

namespace {

struct Decoded {
  nlohmann::json header;
  std::vector<float> pos;
  std::vector<std::uint32_t> tri;
};

Decoded decode(const std::string& bin) {
  Decoded d;
  EXPECT_EQ(bin.substr(0, 4), "AFM1");
  std::uint32_t n = 0;
  std::memcpy(&n, bin.data() + 4, 4);
  d.header = nlohmann::json::parse(bin.substr(8, n));
  const auto nv = d.header.at("vertices").get<std::size_t>();
  const auto nt = d.header.at("triangles").get<std::size_t>();
  d.pos.resize(3 * nv);
  d.tri.resize(3 * nt);
  std::memcpy(d.pos.data(), bin.data() + d.header.at("positions_offset").get<std::size_t>(),
              4 * d.pos.size());
  std::memcpy(d.tri.data(), bin.data() + d.header.at("triangles_offset").get<std::size_t>(),
              4 * d.tri.size());
  EXPECT_EQ(bin.size(), d.header.at("triangles_offset").get<std::size_t>() + 4 * d.tri.size());
  return d;
}

}  // namespace

// Two cells (ids 7 and 3) whose vertices interleave, and a cell id beyond the label and
// pressure lists (written as 0 and left out of nothing: pressure 0).
TEST(MeshFrame, GroupsCellsAndRenumbersTriangles) {
  VtkMesh m;
  m.t_s = 12.5;
  m.step = 25;
  // Vertex v sits at (v, 10 v, 100 v): its new place tells where it came from.
  for (int v = 0; v < 6; ++v)
    for (double s : {1.0, 10.0, 100.0}) m.points.push_back(v * s);
  m.vertex_cell = {7, 3, 7, 3, 7, 3};
  m.tri = {{0, 2, 4}, {1, 3, 5}, {4, 2, 0}};
  m.cell_label.assign(8, 0);
  m.cell_label[7] = 1;
  m.cell_pressure.assign(8, 0.0);
  m.cell_pressure[3] = 0.25;
  m.cell_pressure[7] = 0.5;
  const Decoded d = decode(encodeMeshFrame(m, 4));
  const nlohmann::json& h = d.header;
  EXPECT_EQ(h.at("format"), "activefoam-mesh/1");
  EXPECT_EQ(h.at("index"), 4);
  EXPECT_EQ(h.at("t_s"), 12.5);
  EXPECT_EQ(h.at("step"), 25);
  EXPECT_EQ(h.at("cells"), 2);
  EXPECT_EQ(h.at("cell_id"), nlohmann::json({3, 7}));
  EXPECT_EQ(h.at("spheroid"), nlohmann::json({0, 1}));
  EXPECT_EQ(h.at("pressure_kPa"), nlohmann::json({0.25, 0.5}));
  EXPECT_EQ(h.at("vertex_start"), nlohmann::json({0, 3, 6}));
  EXPECT_EQ(h.at("triangle_start"), nlohmann::json({0, 1, 3}));
  EXPECT_EQ(h.at("bounds"), nlohmann::json({0, 0, 0, 5, 50, 500}));
  EXPECT_EQ(h.at("positions_offset").get<std::size_t>() % 4, 0u);
  // Cell 3's vertices (old 1, 3, 5) first, then cell 7's (old 0, 2, 4), each in its own order.
  const int old_of_new[6] = {1, 3, 5, 0, 2, 4};
  for (int k = 0; k < 6; ++k) {
    EXPECT_EQ(d.pos[3 * k], static_cast<float>(old_of_new[k])) << k;
    EXPECT_EQ(d.pos[3 * k + 2], static_cast<float>(100 * old_of_new[k])) << k;
  }
  // Every triangle still joins the same points.
  const std::vector<std::uint32_t> want = {0, 1, 2, 3, 4, 5, 5, 4, 3};
  EXPECT_EQ(d.tri, want);
}

TEST(MeshFrame, WithoutCellIdsOrPressuresOneCellAndNoPressureKey) {
  VtkMesh m;
  m.points = {0, 0, 0, 1, 0, 0, 0, 1, 0};
  m.tri = {{0, 1, 2}};
  const Decoded d = decode(encodeMeshFrame(m, 0));
  EXPECT_EQ(d.header.at("cells"), 1);
  EXPECT_EQ(d.header.at("cell_id"), nlohmann::json({0}));
  EXPECT_FALSE(d.header.contains("pressure_kPa"));
  EXPECT_EQ(d.tri, (std::vector<std::uint32_t>{0, 1, 2}));
}

TEST(MeshFrame, RefusesTrianglesOutOfRange) {
  VtkMesh m;
  m.points = {0, 0, 0, 1, 0, 0, 0, 1, 0};
  m.tri = {{0, 1, 3}};
  EXPECT_THROW(encodeMeshFrame(m, 0), std::invalid_argument);
  m.tri = {{0, 1, 2}};
  m.vertex_cell = {0, 1};
  EXPECT_THROW(encodeMeshFrame(m, 0), std::invalid_argument);
}
