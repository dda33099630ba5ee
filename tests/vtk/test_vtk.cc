// VTK XML writers: well-formed XML, declared counts match the data, values round-trip.
#include <map>
#include <memory>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "activefoam/run_output.h"
#include "activefoam/vtk.h"

namespace activefoam {
namespace {

// ---- a minimal XML reader: elements, attributes, text; throws on anything unbalanced ----------

struct Element {
  std::string name;
  std::map<std::string, std::string> attrs;
  std::string text;
  std::vector<std::unique_ptr<Element>> children;

  const Element* child(const std::string& n) const {
    for (const auto& c : children)
      if (c->name == n) return c.get();
    return nullptr;
  }
  // Depth-first search for an element by name and, optionally, its Name attribute.
  const Element* find(const std::string& n, const std::string& attr_name = "") const {
    if (name == n && (attr_name.empty() || attr("Name") == attr_name)) return this;
    for (const auto& c : children)
      if (const Element* e = c->find(n, attr_name)) return e;
    return nullptr;
  }
  std::string attr(const std::string& a) const {
    const auto it = attrs.find(a);
    return it == attrs.end() ? "" : it->second;
  }
};

std::string unescape(const std::string& s) {
  std::string out;
  for (std::size_t i = 0; i < s.size(); ++i) {
    if (s[i] != '&') {
      out += s[i];
      continue;
    }
    const auto semi = s.find(';', i);
    if (semi == std::string::npos) throw std::runtime_error("bad entity");
    const std::string ent = s.substr(i + 1, semi - i - 1);
    static const std::map<std::string, char> kEntities{
        {"amp", '&'}, {"lt", '<'}, {"gt", '>'}, {"quot", '"'}, {"apos", '\''}};
    const auto it = kEntities.find(ent);
    if (it == kEntities.end()) throw std::runtime_error("unknown entity &" + ent + ";");
    out += it->second;
    i = semi;
  }
  return out;
}

class XmlReader {
 public:
  explicit XmlReader(std::string text) : s_(std::move(text)) {}

  std::unique_ptr<Element> document() {
    skipMisc();
    if (s_.compare(pos_, 5, "<?xml") == 0) {
      pos_ = s_.find("?>", pos_);
      if (pos_ == std::string::npos) throw std::runtime_error("unterminated declaration");
      pos_ += 2;
    }
    skipMisc();
    auto root = element();
    skipMisc();
    if (pos_ != s_.size()) throw std::runtime_error("content after the root element");
    return root;
  }

 private:
  void skipSpace() {
    while (pos_ < s_.size() && std::isspace(static_cast<unsigned char>(s_[pos_]))) ++pos_;
  }
  void skipMisc() {
    for (;;) {
      skipSpace();
      if (s_.compare(pos_, 4, "<!--") != 0) return;
      pos_ = s_.find("-->", pos_);
      if (pos_ == std::string::npos) throw std::runtime_error("unterminated comment");
      pos_ += 3;
    }
  }
  std::string name() {
    const std::size_t start = pos_;
    while (pos_ < s_.size() && (std::isalnum(static_cast<unsigned char>(s_[pos_])) ||
                                s_[pos_] == '_' || s_[pos_] == '-' || s_[pos_] == ':'))
      ++pos_;
    if (pos_ == start) throw std::runtime_error("expected a name at " + std::to_string(pos_));
    return s_.substr(start, pos_ - start);
  }
  void expect(char c) {
    if (pos_ >= s_.size() || s_[pos_] != c)
      throw std::runtime_error(std::string("expected '") + c + "' at " + std::to_string(pos_));
    ++pos_;
  }
  std::unique_ptr<Element> element() {
    expect('<');
    auto e = std::make_unique<Element>();
    e->name = name();
    for (;;) {
      skipSpace();
      if (s_.compare(pos_, 2, "/>") == 0) {
        pos_ += 2;
        return e;
      }
      if (pos_ < s_.size() && s_[pos_] == '>') {
        ++pos_;
        break;
      }
      const std::string a = name();
      skipSpace();
      expect('=');
      skipSpace();
      expect('"');
      const auto end = s_.find('"', pos_);
      if (end == std::string::npos) throw std::runtime_error("unterminated attribute");
      const std::string raw = s_.substr(pos_, end - pos_);
      if (raw.find('<') != std::string::npos) throw std::runtime_error("'<' in attribute");
      if (!e->attrs.emplace(a, unescape(raw)).second)
        throw std::runtime_error("duplicate attribute " + a);
      pos_ = end + 1;
    }
    for (;;) {
      const auto lt = s_.find('<', pos_);
      if (lt == std::string::npos) throw std::runtime_error("unclosed <" + e->name + ">");
      e->text += unescape(s_.substr(pos_, lt - pos_));
      pos_ = lt;
      if (s_.compare(pos_, 2, "</") == 0) {
        pos_ += 2;
        const std::string closing = name();
        if (closing != e->name)
          throw std::runtime_error("</" + closing + "> closes <" + e->name + ">");
        skipSpace();
        expect('>');
        return e;
      }
      if (s_.compare(pos_, 4, "<!--") == 0) {
        skipMisc();
        continue;
      }
      e->children.push_back(element());
    }
  }

  std::string s_;
  std::size_t pos_ = 0;
};

std::vector<double> numbers(const Element* e) {
  if (!e) throw std::runtime_error("missing element");
  std::istringstream in(e->text);
  std::vector<double> v;
  std::string tok;
  while (in >> tok) v.push_back(std::stod(tok));
  return v;
}

// ---- fixtures ----------------------------------------------------------------------------------

// Two tetrahedra (two cells, two spheroids), outward oriented.
Snapshot twoTetrahedra() {
  Snapshot s;
  s.t_s = 12.5;
  s.step = 125;
  s.x.resize(3, 8);
  s.x << 0, 1, 0, 0, 3, 4, 3, 3,  //
      0, 0, 1, 0, 0, 0, 1, 0,     //
      0, 0, 0, 1, 0.1, 0, 0, 1.0 / 3.0;
  s.tri = {{0, 2, 1}, {0, 1, 3}, {0, 3, 2}, {1, 2, 3}, {4, 6, 5}, {4, 5, 7}, {4, 7, 6}, {5, 6, 7}};
  s.vertex_cell = {0, 0, 0, 0, 1, 1, 1, 1};
  s.cell_pressure = {0.1126, -0.25};
  s.cell_label = {0, 1};
  return s;
}

TEST(Vtk, PolyDataIsWellFormedAndComplete) {
  const Snapshot snap = twoTetrahedra();
  std::ostringstream out;
  writeVtp(out, toVtkMesh(snap));
  std::unique_ptr<Element> root;
  ASSERT_NO_THROW(root = XmlReader(out.str()).document()) << out.str();

  EXPECT_EQ(root->name, "VTKFile");
  EXPECT_EQ(root->attr("type"), "PolyData");
  EXPECT_EQ(root->attr("version"), "1.0");
  EXPECT_EQ(root->attr("byte_order"), "LittleEndian");
  const Element* piece = root->find("Piece");
  ASSERT_NE(piece, nullptr);
  const int np = std::stoi(piece->attr("NumberOfPoints"));
  const int nt = std::stoi(piece->attr("NumberOfPolys"));
  EXPECT_EQ(np, 8);
  EXPECT_EQ(nt, 8);

  // Points round-trip exactly.
  const auto pts = numbers(piece->child("Points")->find("DataArray"));
  ASSERT_EQ(pts.size(), 3u * np);
  for (int i = 0; i < np; ++i)
    for (int d = 0; d < 3; ++d) EXPECT_EQ(pts[3 * i + d], snap.x(d, i)) << i << "," << d;

  const Element* polys = piece->child("Polys");
  ASSERT_NE(polys, nullptr);
  const auto conn = numbers(polys->find("DataArray", "connectivity"));
  const auto offs = numbers(polys->find("DataArray", "offsets"));
  ASSERT_EQ(conn.size(), 3u * nt);
  ASSERT_EQ(offs.size(), static_cast<std::size_t>(nt));
  for (int t = 0; t < nt; ++t) {
    EXPECT_EQ(offs[t], 3.0 * (t + 1));
    for (int k = 0; k < 3; ++k) EXPECT_EQ(conn[3 * t + k], snap.tri[t][k]);
  }
  for (double v : conn) {
    EXPECT_GE(v, 0);
    EXPECT_LT(v, np);
  }

  const Element* pd = piece->child("PointData");
  ASSERT_NE(pd, nullptr);
  const auto pcell = numbers(pd->find("DataArray", "cell_id"));
  ASSERT_EQ(pcell.size(), static_cast<std::size_t>(np));
  for (int i = 0; i < np; ++i) EXPECT_EQ(pcell[i], snap.vertex_cell[i]);

  const Element* cd = piece->child("CellData");
  ASSERT_NE(cd, nullptr);
  const auto tcell = numbers(cd->find("DataArray", "cell_id"));
  const auto label = numbers(cd->find("DataArray", "spheroid"));
  const auto press = numbers(cd->find("DataArray", "pressure"));
  ASSERT_EQ(tcell.size(), static_cast<std::size_t>(nt));
  ASSERT_EQ(label.size(), static_cast<std::size_t>(nt));
  ASSERT_EQ(press.size(), static_cast<std::size_t>(nt));
  for (int t = 0; t < nt; ++t) {
    const int cell = t < 4 ? 0 : 1;
    EXPECT_EQ(tcell[t], cell);
    EXPECT_EQ(label[t], snap.cell_label[cell]);
    EXPECT_EQ(press[t], snap.cell_pressure[cell]);
  }

  // Time travels with the file.
  const auto time = numbers(root->find("DataArray", "TIME"));
  ASSERT_EQ(time.size(), 1u);
  EXPECT_EQ(time[0], 12.5);
}

TEST(Vtk, EmptySnapshotAndMissingPerCellData) {
  Snapshot empty;
  std::ostringstream out;
  writeVtp(out, toVtkMesh(empty));
  auto root = XmlReader(out.str()).document();
  EXPECT_EQ(root->find("Piece")->attr("NumberOfPoints"), "0");
  EXPECT_EQ(root->find("Piece")->attr("NumberOfPolys"), "0");

  Snapshot bare = twoTetrahedra();
  bare.cell_pressure.clear();
  bare.cell_label.clear();
  std::ostringstream out2;
  writeVtp(out2, toVtkMesh(bare));
  root = XmlReader(out2.str()).document();
  for (double v : numbers(root->find("DataArray", "pressure"))) EXPECT_EQ(v, 0);
}

TEST(Vtk, InconsistentSnapshotsAreRejected) {
  Snapshot s = twoTetrahedra();
  s.vertex_cell.pop_back();
  std::ostringstream out;
  EXPECT_THROW(writeVtp(out, toVtkMesh(s)), std::invalid_argument);
  s = twoTetrahedra();
  s.tri.push_back({0, 1, 8});
  EXPECT_THROW(writeVtp(out, toVtkMesh(s)), std::invalid_argument);
  VtkMesh m = toVtkMesh(twoTetrahedra());
  m.points.pop_back();  // not whole points
  EXPECT_THROW(writeVtp(out, m), std::invalid_argument);
}

TEST(Vtk, CollectionIndex) {
  std::ostringstream out;
  writePvd(out, {{0.0, "snap_000000.vtp"}, {600.0, "snap_000001.vtp"}, {1200.5, "a&b\".vtp"}});
  std::unique_ptr<Element> root;
  ASSERT_NO_THROW(root = XmlReader(out.str()).document()) << out.str();
  EXPECT_EQ(root->attr("type"), "Collection");
  const Element* coll = root->child("Collection");
  ASSERT_NE(coll, nullptr);
  ASSERT_EQ(coll->children.size(), 3u);
  EXPECT_EQ(coll->children[0]->attr("file"), "snap_000000.vtp");
  EXPECT_EQ(coll->children[1]->attr("timestep"), "600");
  EXPECT_EQ(coll->children[2]->attr("file"), "a&b\".vtp");
  EXPECT_EQ(std::stod(coll->children[2]->attr("timestep")), 1200.5);
}

TEST(Vtk, TheCheckerCatchesBrokenXml) {
  EXPECT_THROW(XmlReader("<a><b></a></b>").document(), std::runtime_error);
  EXPECT_THROW(XmlReader("<a>").document(), std::runtime_error);
  EXPECT_THROW(XmlReader("<a x=\"1\" x=\"2\"/>").document(), std::runtime_error);
  EXPECT_NO_THROW(XmlReader("<?xml version=\"1.0\"?>\n<a><b/>t</a>\n").document());
}

TEST(Vtk, ReadVtpGivesBackExactlyWhatWasWritten) {
  // Slurm tasks report their snapshots from the .vtp files foam-run wrote: the store must get
  // the same numbers the local pool stores.
  const Snapshot snap = twoTetrahedra();
  const VtkMesh m = toVtkMesh(snap);
  std::ostringstream out;
  writeVtp(out, m);
  const VtkMesh back = readVtp(out.str());
  EXPECT_EQ(back.t_s, m.t_s);
  EXPECT_EQ(back.step, m.step);
  EXPECT_EQ(back.points, m.points);  // bit for bit (1/3 included)
  EXPECT_EQ(back.tri, m.tri);
  EXPECT_EQ(back.vertex_cell, m.vertex_cell);
  EXPECT_EQ(back.cell_pressure, m.cell_pressure);
  EXPECT_EQ(back.cell_label, m.cell_label);
  std::string broken = out.str();
  broken.replace(broken.find("Name=\"Points\""), 13, "Name=\"Pts\"");
  EXPECT_THROW(readVtp(broken), std::invalid_argument);
  EXPECT_THROW(readVtp("<VTKFile/>"), std::invalid_argument);
}

}  // namespace
}  // namespace activefoam
