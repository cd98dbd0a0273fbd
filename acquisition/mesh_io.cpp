#include "acquisition/mesh_io.h"

#include <array>
#include <cctype>
#include <cerrno>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <fstream>
#include <map>
#include <sstream>
#include <stdexcept>

#include "acquisition/format_error.h"
#include "acquisition/formats/binary_util.h"
#include "acquisition/formats/readers.h"
#include "acquisition/formats/text_util.h"

namespace s2m {

const char* ToString(MeshFormat format) {
  switch (format) {
    case MeshFormat::kStlBinary:
      return "stl-binary";
    case MeshFormat::kStlAscii:
      return "stl-ascii";
    case MeshFormat::kObj:
      return "obj";
    case MeshFormat::kPly:
      return "ply";
  }
  return "unknown";
}

namespace {

bool EndsWithLower(std::string name, const std::string& suffix) {
  for (char& c : name) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return name.size() >= suffix.size() &&
         name.compare(name.size() - suffix.size(), suffix.size(), suffix) == 0;
}

// Builds an indexed mesh from triangles given by coordinates, merging bit-identical vertices.
class VertexMerger {
 public:
  int Add(const Eigen::Vector3d& p) {
    const std::array<double, 3> key{p.x(), p.y(), p.z()};
    auto [it, inserted] = index_.try_emplace(key, static_cast<int>(points_.size()));
    if (inserted) points_.push_back(p);
    return it->second;
  }
  Eigen::Matrix3Xd Vertices() const {
    Eigen::Matrix3Xd v(3, static_cast<Eigen::Index>(points_.size()));
    for (std::size_t i = 0; i < points_.size(); ++i) v.col(static_cast<Eigen::Index>(i)) = points_[i];
    return v;
  }

 private:
  std::map<std::array<double, 3>, int> index_;
  std::vector<Eigen::Vector3d> points_;
};

Eigen::Matrix<int, 3, Eigen::Dynamic> ToMatrix(const std::vector<std::array<int, 3>>& t) {
  Eigen::Matrix<int, 3, Eigen::Dynamic> m(3, static_cast<Eigen::Index>(t.size()));
  for (std::size_t i = 0; i < t.size(); ++i) m.col(static_cast<Eigen::Index>(i)) << t[i][0], t[i][1], t[i][2];
  return m;
}

// The last check every reader makes: a mesh the model can use.
void Validate(TriangleMesh& mesh, const std::string& file) {
  std::string why;
  if (!mesh.IsValid(&why)) throw FormatError(file, "", why);
  // A single group stays unnamed ("all").
  if (mesh.group_names.size() == 1) {
    mesh.group_names.clear();
    mesh.groups.clear();
  }
}

TriangleMesh ParseBinaryStl(const std::string& bytes, const std::string& file) {
  if (bytes.size() < 84)
    throw FormatError(file, AtByte(bytes.size()),
                      "truncated: a binary STL file needs an 84-byte header, the file has " +
                          std::to_string(bytes.size()) + " bytes");
  const auto count = formats::LoadScalar<std::uint32_t>(bytes.data() + 80, true);
  const std::size_t need = 84 + 50 * static_cast<std::size_t>(count);
  if (bytes.size() < need)
    throw FormatError(file, AtByte(bytes.size()),
                      "truncated: the header declares " + std::to_string(count) + " triangles (" +
                          std::to_string(need) + " bytes), the file has " + std::to_string(bytes.size()) +
                          " bytes (it ends inside triangle " + std::to_string((bytes.size() - 84) / 50) +
                          ")");
  if (bytes.size() > need)
    throw FormatError(file, AtByte(need),
                      "corrupt: the header declares " + std::to_string(count) + " triangles (" +
                          std::to_string(need) + " bytes) but the file has " + std::to_string(bytes.size()) +
                          " bytes");
  if (count == 0) throw FormatError(file, AtByte(80), "the header declares 0 triangles: an empty mesh");
  VertexMerger merger;
  std::vector<std::array<int, 3>> triangles;
  triangles.reserve(count);
  for (std::uint32_t t = 0; t < count; ++t) {
    const std::size_t at = 84 + 50 * static_cast<std::size_t>(t);
    std::array<int, 3> tri{};
    for (int k = 0; k < 3; ++k) {
      Eigen::Vector3d p;
      for (int c = 0; c < 3; ++c) {
        const std::size_t offset =
            at + 12 + 12 * static_cast<std::size_t>(k) + 4 * static_cast<std::size_t>(c);
        p[c] = formats::LoadScalar<float>(bytes.data() + offset, true);
        if (!std::isfinite(p[c]))
          throw FormatError(file, AtByte(offset),
                            "triangle " + std::to_string(t) + ": a vertex coordinate is not finite");
      }
      tri[static_cast<std::size_t>(k)] = merger.Add(p);
    }
    triangles.push_back(tri);
  }
  TriangleMesh mesh;
  mesh.vertices = merger.Vertices();
  mesh.triangles = ToMatrix(triangles);
  Validate(mesh, file);
  return mesh;
}

TriangleMesh ParseAsciiStl(const std::string& bytes, const std::string& file) {
  formats::LineReader lines(bytes);
  formats::Line line;
  std::vector<std::string_view> tok;
  VertexMerger merger;
  std::vector<std::array<int, 3>> triangles;
  std::vector<int> groups;
  std::vector<std::string> names;
  // States: outside a solid, in a solid, in a facet (after "facet normal"), in its loop (vertices).
  enum class State { kOutside, kSolid, kFacet, kLoop, kLoopDone } state = State::kOutside;
  std::array<int, 3> tri{};
  int vertices_in_loop = 0;
  std::size_t facet_line = 0;
  while (lines.Next(line)) {
    formats::Tokenize(line.text, tok);
    if (tok.empty()) continue;
    const std::string where = AtLine(line.number);
    auto fail = [&](const std::string& problem) { throw FormatError(file, where, problem); };
    const std::string_view key = tok[0];
    switch (state) {
      case State::kOutside:
        if (key != "solid") fail("expected 'solid', found " + formats::Quoted(line.text));
        names.push_back(tok.size() > 1 ? std::string(line.text.substr(line.text.find(tok[1])))
                                       : "solid " + std::to_string(names.size()));
        state = State::kSolid;
        break;
      case State::kSolid:
        if (key == "endsolid") {
          state = State::kOutside;
        } else if (key == "facet") {
          if (tok.size() != 5 || tok[1] != "normal")
            fail("malformed facet line " + formats::Quoted(line.text));
          state = State::kFacet;
          facet_line = line.number;
        } else {
          fail("expected 'facet normal' or 'endsolid', found " + formats::Quoted(line.text));
        }
        break;
      case State::kFacet:
        if (tok.size() != 2 || key != "outer" || tok[1] != "loop")
          fail("expected 'outer loop', found " + formats::Quoted(line.text));
        state = State::kLoop;
        vertices_in_loop = 0;
        break;
      case State::kLoop:
        if (key == "endloop") {
          if (vertices_in_loop != 3)
            fail("the facet at line " + std::to_string(facet_line) + " has " +
                 std::to_string(vertices_in_loop) + " vertices, not 3");
          state = State::kLoopDone;
        } else if (key == "vertex") {
          if (tok.size() != 4) fail("a vertex needs 3 coordinates: " + formats::Quoted(line.text));
          if (vertices_in_loop >= 3)
            fail("the facet at line " + std::to_string(facet_line) + " has more than 3 vertices");
          Eigen::Vector3d p;
          for (int c = 0; c < 3; ++c) {
            if (!formats::ParseDouble(tok[static_cast<std::size_t>(1 + c)], p[c]))
              fail("not a number: " + formats::Quoted(tok[static_cast<std::size_t>(1 + c)]));
            if (!std::isfinite(p[c])) fail("a vertex coordinate is not finite");
          }
          tri[static_cast<std::size_t>(vertices_in_loop++)] = merger.Add(p);
        } else {
          fail("expected 'vertex' or 'endloop', found " + formats::Quoted(line.text));
        }
        break;
      case State::kLoopDone:
        if (key != "endfacet") fail("expected 'endfacet', found " + formats::Quoted(line.text));
        triangles.push_back(tri);
        groups.push_back(static_cast<int>(names.size()) - 1);
        state = State::kSolid;
        break;
    }
  }
  if (state != State::kOutside) {
    const char* inside = state == State::kSolid ? "a solid (no 'endsolid')" : "a facet";
    throw FormatError(file, AtLine(lines.line_number() + 1),
                      std::string("truncated: the file ends inside ") + inside);
  }
  if (triangles.empty()) throw FormatError(file, "", "no facets: an empty mesh");
  TriangleMesh mesh;
  mesh.vertices = merger.Vertices();
  mesh.triangles = ToMatrix(triangles);
  mesh.groups = std::move(groups);
  mesh.group_names = std::move(names);
  // Solids of the same name are one group.
  std::map<std::string, int> first;
  std::vector<int> remap(mesh.group_names.size());
  std::vector<std::string> unique;
  for (std::size_t g = 0; g < mesh.group_names.size(); ++g) {
    auto [it, inserted] = first.try_emplace(mesh.group_names[g], static_cast<int>(unique.size()));
    if (inserted) unique.push_back(mesh.group_names[g]);
    remap[g] = it->second;
  }
  for (int& g : mesh.groups) g = remap[static_cast<std::size_t>(g)];
  mesh.group_names = std::move(unique);
  Validate(mesh, file);
  return mesh;
}

TriangleMesh ParseObj(const std::string& bytes, const std::string& file) {
  formats::LineReader lines(bytes);
  formats::Line line;
  std::vector<std::string_view> tok;
  std::vector<Eigen::Vector3d> vertices;
  std::vector<std::array<int, 3>> triangles;
  std::vector<int> groups;
  std::vector<std::string> names;
  std::map<std::string, int> group_index;
  int current = -1;
  bool seen_g = false;
  std::vector<long long> face;
  while (lines.Next(line)) {
    std::string_view text = line.text;
    if (const std::size_t hash = text.find('#'); hash != std::string_view::npos) text = text.substr(0, hash);
    formats::Tokenize(text, tok);
    if (tok.empty()) continue;
    const std::string where = AtLine(line.number);
    auto fail = [&](const std::string& problem) { throw FormatError(file, where, problem); };
    const std::string_view key = tok[0];
    if (key == "v") {
      if (tok.size() != 4 && tok.size() != 5) fail("a vertex needs 3 coordinates (and an optional w)");
      Eigen::Vector3d p;
      for (int c = 0; c < 3; ++c) {
        if (!formats::ParseDouble(tok[static_cast<std::size_t>(1 + c)], p[c]))
          fail("not a number: " + formats::Quoted(tok[static_cast<std::size_t>(1 + c)]));
        if (!std::isfinite(p[c]))
          fail("vertex " + std::to_string(vertices.size() + 1) + ": a coordinate is not finite");
      }
      if (tok.size() == 5) {
        double w = 1;
        if (!formats::ParseDouble(tok[4], w) || !std::isfinite(w) || w == 0) fail("bad vertex weight w");
        p /= w;
      }
      vertices.push_back(p);
    } else if (key == "f") {
      if (tok.size() < 4) fail("a face needs at least 3 vertices, found " + std::to_string(tok.size() - 1));
      face.clear();
      for (std::size_t i = 1; i < tok.size(); ++i) {
        // v, v/vt, v//vn or v/vt/vn: the vertex index is the first field.
        std::string_view field = tok[i].substr(0, tok[i].find('/'));
        long long index = 0;
        if (!formats::ParseInteger(field, index) || index == 0)
          fail("bad vertex index " + formats::Quoted(tok[i]));
        const auto n = static_cast<long long>(vertices.size());
        const long long resolved = index > 0 ? index - 1 : n + index;  // negative: relative to the end
        if (resolved < 0 || resolved >= n)
          fail("vertex index " + std::to_string(index) + " is out of range (" + std::to_string(n) +
               " vertices so far)");
        face.push_back(resolved);
      }
      if (current < 0) {
        current = 0;
        names.push_back("default");
        group_index["default"] = 0;
      }
      for (std::size_t k = 1; k + 1 < face.size(); ++k) {
        triangles.push_back(
            {static_cast<int>(face[0]), static_cast<int>(face[k]), static_cast<int>(face[k + 1])});
        groups.push_back(current);
      }
    } else if (key == "g" || key == "o") {
      // Groups name the regions; objects only when the file has no groups.
      if (key == "g") seen_g = true;
      if (key == "o" && seen_g) continue;
      const std::string name = tok.size() > 1 ? std::string(text.substr(text.find(tok[1]))) : "default";
      std::string trimmed = name;
      while (!trimmed.empty() && std::isspace(static_cast<unsigned char>(trimmed.back()))) trimmed.pop_back();
      auto [it, inserted] = group_index.try_emplace(trimmed, static_cast<int>(names.size()));
      if (inserted) names.push_back(trimmed);
      current = it->second;
    } else if (key == "vt" || key == "vn" || key == "vp" || key == "l" || key == "p" || key == "s" ||
               key == "mtllib" || key == "usemtl" || key == "cstype" || key == "deg" || key == "curv" ||
               key == "surf" || key == "parm" || key == "end" || key == "mg" || key == "lod" ||
               key == "usemap" || key == "maplib" || key == "shadow_obj" || key == "trace_obj") {
      continue;  // texture, normals, lines, materials, free-form geometry: not part of the nominal's
                 // triangles
    } else {
      fail("unknown OBJ statement " + formats::Quoted(key));
    }
  }
  if (vertices.empty()) throw FormatError(file, "", "no vertices ('v' lines)");
  if (triangles.empty()) throw FormatError(file, "", "no faces ('f' lines): not a mesh");
  TriangleMesh mesh;
  mesh.vertices.resize(3, static_cast<Eigen::Index>(vertices.size()));
  for (std::size_t i = 0; i < vertices.size(); ++i)
    mesh.vertices.col(static_cast<Eigen::Index>(i)) = vertices[i];
  mesh.triangles = ToMatrix(triangles);
  // Drop names of groups without faces (a `g` before the first face, then another).
  std::vector<int> used(names.size(), 0);
  for (int g : groups) used[static_cast<std::size_t>(g)] = 1;
  std::vector<int> remap(names.size(), -1);
  for (std::size_t g = 0; g < names.size(); ++g)
    if (used[g]) {
      remap[g] = static_cast<int>(mesh.group_names.size());
      mesh.group_names.push_back(names[g]);
    }
  for (int g : groups) mesh.groups.push_back(remap[static_cast<std::size_t>(g)]);
  Validate(mesh, file);
  return mesh;
}

TriangleMesh ParsePlyMeshFile(const std::string& bytes, const std::string& file, std::string& units) {
  formats::PlyFaces faces;
  const Scan vertices = formats::ParsePlyMesh(bytes, file, faces);
  if (vertices.units != "unknown") units = vertices.units;
  std::vector<std::array<int, 3>> triangles;
  std::vector<std::int64_t> labels;
  const std::size_t count = faces.offsets.size() - 1;
  for (std::size_t f = 0; f < count; ++f) {
    const std::size_t begin = faces.offsets[f], end = faces.offsets[f + 1];
    if (end - begin < 3)
      throw FormatError(file, "face " + std::to_string(f),
                        "a face needs at least 3 vertices, it has " + std::to_string(end - begin));
    for (std::size_t k = begin; k < end; ++k)
      if (faces.indices[k] >= vertices.points.cols())
        throw FormatError(file, "face " + std::to_string(f),
                          "vertex index " + std::to_string(faces.indices[k]) + " is out of range (" +
                              std::to_string(vertices.points.cols()) + " vertices)");
    for (std::size_t k = begin + 1; k + 1 < end; ++k) {
      triangles.push_back({static_cast<int>(faces.indices[begin]), static_cast<int>(faces.indices[k]),
                           static_cast<int>(faces.indices[k + 1])});
      if (faces.has_labels) labels.push_back(faces.labels[f]);
    }
  }
  if (triangles.empty()) throw FormatError(file, "", "no faces: not a mesh");
  TriangleMesh mesh;
  mesh.vertices = vertices.points;
  mesh.triangles = ToMatrix(triangles);
  if (faces.has_labels) {
    std::map<std::int64_t, int> index;
    for (std::int64_t l : labels) index.try_emplace(l, 0);
    int next = 0;
    for (auto& [label, g] : index) {
      g = next++;
      mesh.group_names.push_back("label " + std::to_string(label));
    }
    for (std::int64_t l : labels) mesh.groups.push_back(index.at(l));
  }
  Validate(mesh, file);
  return mesh;
}

}  // namespace

TriangleMesh ParseMesh(const std::string& bytes, const std::string& file, const std::string& units,
                       MeshFormat* format) {
  MeshFormat found;
  TriangleMesh mesh;
  std::string mesh_units = units;
  if (EndsWithLower(file, ".stl")) {
    bool binary = false;
    if (bytes.size() >= 84) {
      const auto count = formats::LoadScalar<std::uint32_t>(bytes.data() + 80, true);
      binary = bytes.size() == 84 + 50 * static_cast<std::size_t>(count);
    }
    if (!binary && bytes.compare(0, 5, "solid") != 0) binary = true;  // binary, and its size will be wrong
    found = binary ? MeshFormat::kStlBinary : MeshFormat::kStlAscii;
    mesh = binary ? ParseBinaryStl(bytes, file) : ParseAsciiStl(bytes, file);
  } else if (EndsWithLower(file, ".obj")) {
    found = MeshFormat::kObj;
    mesh = ParseObj(bytes, file);
  } else if (EndsWithLower(file, ".ply") || EndsWithLower(file, ".ply.gz")) {
    found = MeshFormat::kPly;
    mesh = ParsePlyMeshFile(bytes, file, mesh_units);
  } else {
    throw FormatError(file, "", "unknown mesh format (expected .stl, .obj, .ply or .ply.gz)");
  }
  mesh.units = mesh_units;
  if (format != nullptr) *format = found;
  return mesh;
}

TriangleMesh ReadMesh(const std::filesystem::path& path, const std::string& units, MeshFormat* format) {
  const std::string file = path.string();
  if (!EndsWithLower(file, ".stl") && !EndsWithLower(file, ".obj") && !EndsWithLower(file, ".ply") &&
      !EndsWithLower(file, ".ply.gz"))
    throw FormatError(file, "", "unknown mesh format (expected .stl, .obj, .ply or .ply.gz)");
  return ParseMesh(formats::ReadFileBytes(file), file, units, format);
}

namespace {

void WriteAtomically(const std::filesystem::path& path, const std::string& bytes) {
  const std::filesystem::path tmp = path.string() + ".partial";
  {
    std::ofstream out(tmp, std::ios::binary | std::ios::trunc);
    if (!out) throw std::runtime_error("cannot create " + tmp.string() + ": " + std::strerror(errno));
    out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
    out.flush();
    if (!out) {
      std::error_code ignored;
      std::filesystem::remove(tmp, ignored);
      throw std::runtime_error("cannot write " + path.string() + ": " + std::strerror(errno));
    }
  }
  std::error_code ec;
  std::filesystem::rename(tmp, path, ec);
  if (ec)
    throw std::runtime_error("cannot rename " + tmp.string() + " to " + path.string() + ": " + ec.message());
}

}  // namespace

void WriteStl(const std::filesystem::path& path, const TriangleMesh& mesh, bool ascii) {
  std::ostringstream out;
  auto normal = [&](Eigen::Index f) {
    const Eigen::Vector3d a = mesh.vertices.col(mesh.triangles(0, f)),
                          b = mesh.vertices.col(mesh.triangles(1, f)),
                          c = mesh.vertices.col(mesh.triangles(2, f));
    const Eigen::Vector3d n = (b - a).cross(c - a);
    return n.norm() > 0 ? Eigen::Vector3d(n.normalized()) : Eigen::Vector3d::Zero();
  };
  if (ascii) {
    out.precision(17);
    for (int g = 0; g < mesh.group_count(); ++g) {
      out << "solid " << mesh.GroupName(g) << "\n";
      for (Eigen::Index f = 0; f < mesh.triangle_count(); ++f) {
        if (mesh.GroupOf(f) != g) continue;
        const Eigen::Vector3d n = normal(f);
        out << "  facet normal " << n.x() << " " << n.y() << " " << n.z() << "\n    outer loop\n";
        for (int k = 0; k < 3; ++k) {
          const Eigen::Vector3d p = mesh.vertices.col(mesh.triangles(k, f));
          out << "      vertex " << p.x() << " " << p.y() << " " << p.z() << "\n";
        }
        out << "    endloop\n  endfacet\n";
      }
      out << "endsolid " << mesh.GroupName(g) << "\n";
    }
  } else {
    std::string header(80, ' ');
    const std::string title = "scan2model binary STL";
    header.replace(0, title.size(), title);
    out.write(header.data(), 80);
    auto put_u32 = [&](std::uint32_t v) {
      unsigned char b[4] = {static_cast<unsigned char>(v), static_cast<unsigned char>(v >> 8),
                            static_cast<unsigned char>(v >> 16), static_cast<unsigned char>(v >> 24)};
      out.write(reinterpret_cast<const char*>(b), 4);
    };
    auto put_f32 = [&](double v) {
      const float f = static_cast<float>(v);
      std::uint32_t bits;
      std::memcpy(&bits, &f, 4);
      put_u32(bits);
    };
    put_u32(static_cast<std::uint32_t>(mesh.triangle_count()));
    for (Eigen::Index f = 0; f < mesh.triangle_count(); ++f) {
      const Eigen::Vector3d n = normal(f);
      for (int c = 0; c < 3; ++c) put_f32(n[c]);
      for (int k = 0; k < 3; ++k)
        for (int c = 0; c < 3; ++c) put_f32(mesh.vertices(c, mesh.triangles(k, f)));
      out.write("\0\0", 2);
    }
  }
  WriteAtomically(path, out.str());
}

void WriteObj(const std::filesystem::path& path, const TriangleMesh& mesh) {
  std::ostringstream out;
  out.precision(17);
  out << "# scan2model nominal mesh\n";
  for (Eigen::Index i = 0; i < mesh.vertices.cols(); ++i)
    out << "v " << mesh.vertices(0, i) << " " << mesh.vertices(1, i) << " " << mesh.vertices(2, i) << "\n";
  for (int g = 0; g < mesh.group_count(); ++g) {
    out << "g " << mesh.GroupName(g) << "\n";
    for (Eigen::Index f = 0; f < mesh.triangle_count(); ++f)
      if (mesh.GroupOf(f) == g)
        out << "f " << mesh.triangles(0, f) + 1 << " " << mesh.triangles(1, f) + 1 << " "
            << mesh.triangles(2, f) + 1 << "\n";
  }
  WriteAtomically(path, out.str());
}

}  // namespace s2m
