// Nominal mesh readers (docs/metrology.md section 5): STL (binary, ASCII), OBJ and PLY meshes round trip
// with their groups, and truncated or corrupt files are rejected with the file and the problem named.

#include "acquisition/mesh_io.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <string>

#include "acquisition/format_error.h"

namespace s2m {
namespace {

namespace fs = std::filesystem;

fs::path TempDir() {
  const fs::path dir = fs::temp_directory_path() / ("s2m_mesh_io_" + std::to_string(::getpid()));
  fs::create_directories(dir);
  return dir;
}

void WriteBytes(const fs::path& p, const std::string& bytes) {
  std::ofstream out(p, std::ios::binary);
  out << bytes;
}

std::string ReadBytes(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), {});
}

// A tetrahedron in two groups: "base" (one triangle) and "sides" (three).
TriangleMesh Tetrahedron() {
  TriangleMesh m;
  m.vertices.resize(3, 4);
  m.vertices << 0, 1, 0, 0,  //
      0, 0, 1, 0,            //
      0, 0, 0, 1;
  m.triangles.resize(3, 4);
  m.triangles << 0, 0, 0, 1,  //
      2, 1, 3, 2,             //
      1, 3, 2, 3;
  m.groups = {0, 1, 1, 1};
  m.group_names = {"base", "sides"};
  return m;
}

// The error's message must name the file and the problem's words.
void ExpectRejected(const fs::path& p, const std::string& words) {
  try {
    ReadMesh(p);
    FAIL() << p << " was accepted";
  } catch (const FormatError& e) {
    EXPECT_EQ(e.file(), p.string());
    EXPECT_NE(std::string(e.what()).find(words), std::string::npos) << e.what();
  }
}

TEST(MeshIo, RoundTripsWithGroups) {
  const fs::path dir = TempDir();
  const TriangleMesh t = Tetrahedron();
  WriteStl(dir / "a.stl", t, true);
  WriteStl(dir / "b.stl", t, false);
  WriteObj(dir / "c.obj", t);
  MeshFormat format;
  const TriangleMesh a = ReadMesh(dir / "a.stl", "mm", &format);
  EXPECT_EQ(format, MeshFormat::kStlAscii);
  EXPECT_EQ(a.vertices.cols(), 4);  // merged
  EXPECT_EQ(a.triangle_count(), 4);
  EXPECT_EQ(a.group_names, (std::vector<std::string>{"base", "sides"}));
  EXPECT_EQ(a.units, "mm");
  const TriangleMesh b = ReadMesh(dir / "b.stl", "mm", &format);
  EXPECT_EQ(format, MeshFormat::kStlBinary);
  EXPECT_EQ(b.vertices.cols(), 4);
  EXPECT_EQ(b.group_count(), 1);  // binary STL has no groups
  const TriangleMesh c = ReadMesh(dir / "c.obj", "mm", &format);
  EXPECT_EQ(format, MeshFormat::kObj);
  EXPECT_EQ(c.group_names, (std::vector<std::string>{"base", "sides"}));
  EXPECT_EQ(c.triangles, t.triangles);
  EXPECT_LT((c.vertices - t.vertices).cwiseAbs().maxCoeff(), 1e-15);
  // A PLY mesh with a quad, a face label and units.
  WriteBytes(dir / "d.ply",
             "ply\nformat ascii 1.0\ncomment units mm\nelement vertex 4\nproperty float x\nproperty float y\n"
             "property float z\nelement face 2\nproperty list uchar int vertex_indices\nproperty int label\n"
             "end_header\n0 0 0\n1 0 0\n1 1 0\n0 1 0\n4 0 1 2 3 7\n3 0 2 1 9\n");
  const TriangleMesh d = ReadMesh(dir / "d.ply", "unknown", &format);
  EXPECT_EQ(format, MeshFormat::kPly);
  EXPECT_EQ(d.triangle_count(), 3);  // the quad as two triangles
  EXPECT_EQ(d.group_names, (std::vector<std::string>{"label 7", "label 9"}));
  EXPECT_EQ(d.units, "mm");
  // OBJ with negative indices, v/vt/vn references and comments.
  WriteBytes(dir / "e.obj",
             "# a square\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvt 0 0\ng top\nf -4/1 -3/1 -2/1 -1/1\n");
  EXPECT_EQ(ReadMesh(dir / "e.obj").triangle_count(), 2);
  fs::remove_all(dir);
}

TEST(MeshIo, RejectsTruncatedAndCorruptFiles) {
  const fs::path dir = TempDir();
  const TriangleMesh t = Tetrahedron();
  WriteStl(dir / "good.stl", t, false);
  const std::string binary = ReadBytes(dir / "good.stl");
  // Binary STL cut inside the third triangle, cut inside the header, and with trailing garbage.
  WriteBytes(dir / "cut.stl", binary.substr(0, 84 + 2 * 50 + 20));
  ExpectRejected(dir / "cut.stl", "truncated: the header declares 4 triangles");
  WriteBytes(dir / "header.stl", binary.substr(0, 60));
  ExpectRejected(dir / "header.stl", "truncated: a binary STL file needs an 84-byte header");
  WriteBytes(dir / "long.stl", binary + "xyz");
  ExpectRejected(dir / "long.stl", "corrupt");
  // A NaN coordinate in a binary STL.
  std::string nan_stl = binary;
  const float nan = std::numeric_limits<float>::quiet_NaN();
  std::memcpy(nan_stl.data() + 84 + 12, &nan, 4);
  WriteBytes(dir / "nan.stl", nan_stl);
  ExpectRejected(dir / "nan.stl", "not finite");
  // ASCII STL cut inside a facet, a facet with two vertices, a bad number.
  WriteStl(dir / "good_ascii.stl", t, true);
  const std::string ascii = ReadBytes(dir / "good_ascii.stl");
  // Cut at a line end (a cut inside a line is a malformed line, reported as such).
  WriteBytes(dir / "cut_ascii.stl", ascii.substr(0, ascii.find('\n', ascii.size() / 2) + 1));
  ExpectRejected(dir / "cut_ascii.stl", "truncated: the file ends inside");
  WriteBytes(
      dir / "two.stl",
      "solid s\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\nendloop\nendfacet\nendsolid s\n");
  ExpectRejected(dir / "two.stl", "has 2 vertices, not 3");
  WriteBytes(dir / "word.stl",
             "solid s\nfacet normal 0 0 1\nouter loop\nvertex 0 0 zero\nvertex 1 0 0\nvertex 0 1 0\nendloop\n"
             "endfacet\nendsolid s\n");
  ExpectRejected(dir / "word.stl", "line 4");
  // OBJ: an index out of range, a face of two vertices, an unknown statement, no faces.
  WriteBytes(dir / "range.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 4\n");
  ExpectRejected(dir / "range.obj", "vertex index 4 is out of range");
  WriteBytes(dir / "short.obj", "v 0 0 0\nv 1 0 0\nf 1 2\n");
  ExpectRejected(dir / "short.obj", "at least 3 vertices");
  // A PLY face label no 64-bit integer holds (the fuzzer's finding: undefined behaviour before the check).
  WriteBytes(dir / "label.ply",
             "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
             "element face 1\nproperty list uchar int vertex_indices\nproperty int label\nend_header\n0 0 0\n"
             "1 0 0\n0 1 0\n3 0 1 2 55555555555555555555551\n");
  ExpectRejected(dir / "label.ply", "is not an integer a 64-bit label can hold");
  WriteBytes(dir / "junk.obj", "v 0 0 0\nbogus 1 2\n");
  ExpectRejected(dir / "junk.obj", "unknown OBJ statement");
  WriteBytes(dir / "points.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\n");
  ExpectRejected(dir / "points.obj", "no faces");
  // PLY: faces cut short, an index out of range, a point cloud without faces.
  const std::string header =
      "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
      "element face 2\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n";
  WriteBytes(dir / "cut.ply", header + "3 0 1 2\n");
  ExpectRejected(dir / "cut.ply", "truncated");
  WriteBytes(dir / "range.ply", header + "3 0 1 2\n3 0 1 5\n");
  ExpectRejected(dir / "range.ply", "out of range");
  WriteBytes(dir / "negative.ply", header + "3 0 1 2\n3 0 -1 2\n");
  ExpectRejected(dir / "negative.ply",
                 "line 14: face 1: vertex index -1.000000 is not a non-negative integer");
  WriteBytes(dir / "cloud.ply",
             "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\nproperty float z\n"
             "end_header\n0 0 0\n");
  ExpectRejected(dir / "cloud.ply", "no 'face' element");
  // Unknown extension, missing file, degenerate mesh.
  WriteBytes(dir / "mesh.off", "OFF\n");
  ExpectRejected(dir / "mesh.off", "unknown mesh format");
  ExpectRejected(dir / "absent.stl", "cannot open");
  WriteBytes(dir / "flat.obj", "v 0 0 0\nv 1 0 0\nv 2 0 0\nf 1 2 3\n");
  ExpectRejected(dir / "flat.obj", "zero area");
  fs::remove_all(dir);
}

}  // namespace
}  // namespace s2m
