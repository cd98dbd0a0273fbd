// PLY (Turk, "The PLY polygon file format", 1994): ascii, binary_little_endian and binary_big_endian. The
// vertex element is kept, and for meshes (ParsePlyMesh) the face element's vertex index lists and an optional
// integer face label; every other element (the Stanford range_grid, ...) is parsed to validate the file and
// dropped.

#include <algorithm>
#include <cmath>
#include <optional>
#include <string>
#include <vector>

#include "acquisition/format_error.h"
#include "acquisition/formats/binary_util.h"
#include "acquisition/formats/readers.h"
#include "acquisition/formats/text_util.h"

namespace s2m::formats {
namespace {

struct Property {
  std::string name;
  ScalarType type = ScalarType::kFloat32;
  bool is_list = false;
  ScalarType count_type = ScalarType::kUint8;
};

struct Element {
  std::string name;
  std::size_t count = 0;
  std::vector<Property> properties;
};

enum class Encoding { kAscii, kBinaryLittle, kBinaryBig };

std::optional<ScalarType> ParseType(std::string_view t) {
  if (t == "char" || t == "int8") return ScalarType::kInt8;
  if (t == "uchar" || t == "uint8") return ScalarType::kUint8;
  if (t == "short" || t == "int16") return ScalarType::kInt16;
  if (t == "ushort" || t == "uint16") return ScalarType::kUint16;
  if (t == "int" || t == "int32") return ScalarType::kInt32;
  if (t == "uint" || t == "uint32") return ScalarType::kUint32;
  if (t == "float" || t == "float32") return ScalarType::kFloat32;
  if (t == "double" || t == "float64") return ScalarType::kFloat64;
  return std::nullopt;
}

// Column roles within the vertex element.
struct VertexLayout {
  int x = -1, y = -1, z = -1, nx = -1, ny = -1, nz = -1, weight = -1;
  bool has_normals() const { return nx >= 0 && ny >= 0 && nz >= 0; }
};

VertexLayout LayoutOf(const Element& vertex) {
  VertexLayout l;
  for (int i = 0; i < static_cast<int>(vertex.properties.size()); ++i) {
    const Property& p = vertex.properties[static_cast<std::size_t>(i)];
    if (p.is_list) continue;
    if (p.name == "x")
      l.x = i;
    else if (p.name == "y")
      l.y = i;
    else if (p.name == "z")
      l.z = i;
    else if (p.name == "nx" || p.name == "normal_x")
      l.nx = i;
    else if (p.name == "ny" || p.name == "normal_y")
      l.ny = i;
    else if (p.name == "nz" || p.name == "normal_z")
      l.nz = i;
    else if (p.name == "weight")
      l.weight = i;
  }
  return l;
}

// Declared counts above this are checked against the bytes left before anything is allocated.
constexpr std::size_t kCountCheckedBeforeReading = std::size_t{1} << 20;

class PlyParser {
 public:
  PlyParser(const std::string& bytes, const std::string& file, PlyFaces* faces = nullptr)
      : bytes_(bytes), file_(file), faces_(faces) {}

  Scan Parse() {
    ParseHeader();
    const Element* vertex = nullptr;
    for (const Element& e : elements_) {
      if (e.name == "vertex") vertex = &e;
    }
    if (vertex == nullptr)
      throw FormatError(file_, "header", "no 'vertex' element: the file holds no points");
    layout_ = LayoutOf(*vertex);
    if (layout_.x < 0 || layout_.y < 0 || layout_.z < 0) {
      throw FormatError(file_, "header", "the vertex element lacks one of the properties x, y, z");
    }
    if (vertex->count == 0)
      throw FormatError(file_, "header", "empty point set: the vertex element has 0 entries");
    if (faces_ != nullptr) FindFaceLayout();
    for (const Element& e : elements_) {
      if (encoding_ == Encoding::kAscii)
        ReadAsciiElement(e, &e == vertex);
      else
        ReadBinaryElement(e, &e == vertex);
    }
    scan_.metadata.device = "file";
    scan_.metadata.source = file_;
    return std::move(scan_);
  }

 private:
  [[noreturn]] void Fail(const std::string& location, const std::string& problem) const {
    throw FormatError(file_, location, problem);
  }

  void ParseHeader() {
    Line line;
    if (!lines_.Next(line) || line.text != "ply")
      Fail(AtLine(1), "not a PLY file (the first line must be 'ply')");
    std::vector<std::string_view> tok;
    bool have_format = false;
    while (true) {
      if (!lines_.Next(line)) Fail(AtLine(lines_.line_number()), "truncated header: no 'end_header' line");
      Tokenize(line.text, tok);
      if (tok.empty()) continue;
      const std::string where = AtLine(line.number);
      if (tok[0] == "end_header") break;
      if (tok[0] == "comment") {
        if (tok.size() >= 3 && tok[1] == "units") scan_.units = std::string(tok[2]);
        if (tok.size() == 14 && tok[1] == "world_T_scan") ReadPoseComment(tok, where);
        continue;
      }
      if (tok[0] == "obj_info") continue;
      if (tok[0] == "format") {
        if (tok.size() != 3) Fail(where, "malformed format line " + Quoted(line.text));
        if (tok[1] == "ascii")
          encoding_ = Encoding::kAscii;
        else if (tok[1] == "binary_little_endian")
          encoding_ = Encoding::kBinaryLittle;
        else if (tok[1] == "binary_big_endian")
          encoding_ = Encoding::kBinaryBig;
        else
          Fail(where, "unknown PLY encoding " + Quoted(tok[1]));
        have_format = true;
      } else if (tok[0] == "element") {
        std::size_t count = 0;
        if (tok.size() != 3 || !ParseInteger(tok[2], count))
          Fail(where, "malformed element line " + Quoted(line.text));
        elements_.push_back({std::string(tok[1]), count, {}});
      } else if (tok[0] == "property") {
        if (elements_.empty()) Fail(where, "property before any element");
        Property p;
        if (tok.size() == 5 && tok[1] == "list") {
          auto count_type = ParseType(tok[2]);
          auto item_type = ParseType(tok[3]);
          if (!count_type || !item_type || *count_type == ScalarType::kFloat32 ||
              *count_type == ScalarType::kFloat64) {
            Fail(where, "bad list property types in " + Quoted(line.text));
          }
          p = {std::string(tok[4]), *item_type, true, *count_type};
        } else if (tok.size() == 3) {
          auto type = ParseType(tok[1]);
          if (!type) Fail(where, "unknown property type " + Quoted(tok[1]));
          p = {std::string(tok[2]), *type, false, ScalarType::kUint8};
        } else {
          Fail(where, "malformed property line " + Quoted(line.text));
        }
        elements_.back().properties.push_back(p);
      } else {
        Fail(where, "unknown header keyword " + Quoted(tok[0]));
      }
    }
    if (!have_format) Fail("header", "no 'format' line");
  }

  // The face element's index list ("vertex_indices" or "vertex_index") and label ("label", "group" or
  // "region", a scalar) when faces are wanted.
  void FindFaceLayout() {
    for (const Element& e : elements_) {
      if (e.name != "face") continue;
      face_element_ = &e;
      for (int i = 0; i < static_cast<int>(e.properties.size()); ++i) {
        const Property& p = e.properties[static_cast<std::size_t>(i)];
        if (p.is_list && (p.name == "vertex_indices" || p.name == "vertex_index")) face_list_ = i;
        if (!p.is_list && (p.name == "label" || p.name == "group" || p.name == "region")) face_label_ = i;
      }
      if (face_list_ < 0)
        Fail("header", "the face element has no list property 'vertex_indices' (or 'vertex_index')");
    }
    if (face_element_ == nullptr) Fail("header", "no 'face' element: the file holds points, not a mesh");
    faces_->has_labels = face_label_ >= 0;
  }

  // Stores one face's index list item (checked to be a whole number) while it is read.
  void StoreFaceIndex(double value, const std::string& where) {
    if (!(value >= 0) || value != std::floor(value) || value > 2147483647.0)
      Fail(where, "face " + std::to_string(faces_->offsets.size() - 1) + ": vertex index " +
                      std::to_string(value) + " is not a non-negative integer");
    faces_->indices.push_back(static_cast<std::int64_t>(value));
  }

  void ReadPoseComment(const std::vector<std::string_view>& tok, const std::string& where) {
    Eigen::Matrix<double, 3, 4> m;
    for (int i = 0; i < 12; ++i) {
      if (!ParseDouble(tok[static_cast<std::size_t>(2 + i)], m(i / 4, i % 4)) ||
          !std::isfinite(m(i / 4, i % 4))) {
        Fail(where, "malformed world_T_scan comment");
      }
    }
    scan_.world_T_scan = RigidMotion(m.leftCols<3>(), m.col(3));
  }

  void Allocate(std::size_t count) {
    const auto n = static_cast<Eigen::Index>(count);
    scan_.points.resize(3, n);
    if (layout_.has_normals()) scan_.normals.resize(3, n);
    if (layout_.weight >= 0) scan_.weights.resize(n);
  }

  // Stores one vertex record's scalar values (indexed by property) after checking they are finite.
  void StoreVertex(std::size_t i, const std::vector<double>& v, const std::string& where) {
    const auto c = static_cast<Eigen::Index>(i);
    auto finite = [&](int idx, const char* what) {
      const double x = v[static_cast<std::size_t>(idx)];
      if (!std::isfinite(x))
        Fail(where,
             "vertex " + std::to_string(i) + ": " + what + " is not finite (" + std::to_string(x) + ")");
      return x;
    };
    // Every value read before the column is written (left to right), not by a comma initializer a format
    // error would leave half-filled (Eigen's assertions abort on that).
    scan_.points.col(c) =
        Eigen::Vector3d{finite(layout_.x, "x"), finite(layout_.y, "y"), finite(layout_.z, "z")};
    if (layout_.has_normals())
      scan_.normals.col(c) =
          Eigen::Vector3d{finite(layout_.nx, "nx"), finite(layout_.ny, "ny"), finite(layout_.nz, "nz")};
    if (layout_.weight >= 0) scan_.weights[c] = finite(layout_.weight, "weight");
  }

  void ReadAsciiElement(const Element& e, bool is_vertex) {
    // Refuse a large count the rest of the file cannot hold before allocating (docs/reliability.md): every
    // value of an ASCII record takes at least two bytes, a digit and a separator. Smaller counts are read and
    // fail at the line where the data end, which names the place more precisely.
    const std::size_t min_record = 2 * std::max<std::size_t>(1, e.properties.size());
    const std::size_t left = bytes_.size() - lines_.position();
    if (e.count > kCountCheckedBeforeReading && e.count > left / min_record) {
      Fail(AtLine(lines_.line_number() + 1), "truncated: element '" + e.name + "' declares " +
                                                 std::to_string(e.count) + " entries (at least " +
                                                 std::to_string(min_record) + " bytes each) but only " +
                                                 std::to_string(left) + " bytes follow");
    }
    if (is_vertex) Allocate(e.count);
    const bool is_face = faces_ != nullptr && &e == face_element_;
    std::vector<std::string_view> tok;
    std::vector<double> values(e.properties.size());
    Line line;
    for (std::size_t i = 0; i < e.count; ++i) {
      do {
        if (!lines_.Next(line)) {
          Fail(AtLine(lines_.line_number() + 1), "truncated: element '" + e.name + "' declares " +
                                                     std::to_string(e.count) +
                                                     " entries, the file ends after " + std::to_string(i));
        }
        Tokenize(line.text, tok);
      } while (tok.empty());
      const std::string where = AtLine(line.number);
      std::size_t t = 0;
      for (std::size_t p = 0; p < e.properties.size(); ++p) {
        const Property& prop = e.properties[p];
        if (t >= tok.size())
          Fail(where, "too few values for element '" + e.name + "' entry " + std::to_string(i));
        if (prop.is_list) {
          std::size_t n = 0;
          if (!ParseInteger(tok[t], n)) Fail(where, "bad list length " + Quoted(tok[t]));
          if (n > tok.size() - t - 1)  // (t + 1 + n could wrap round for a huge n)
            Fail(where,
                 "list '" + prop.name + "' declares " + std::to_string(n) + " items, the line has fewer");
          const bool keep = is_face && static_cast<int>(p) == face_list_;
          if (keep) faces_->offsets.push_back(faces_->indices.size());
          for (std::size_t k = 0; k < n; ++k) {
            double item;
            if (!ParseDouble(tok[t + 1 + k], item)) Fail(where, "not a number: " + Quoted(tok[t + 1 + k]));
            if (keep) StoreFaceIndex(item, where);
          }
          t += 1 + n;
        } else {
          if (!ParseDouble(tok[t], values[p])) Fail(where, "not a number: " + Quoted(tok[t]));
          ++t;
        }
      }
      if (t != tok.size())
        Fail(where, "expected " + std::to_string(t) + " values for element '" + e.name + "', found " +
                        std::to_string(tok.size()));
      if (is_vertex) StoreVertex(i, values, where);
      if (is_face && face_label_ >= 0) StoreFaceLabel(values, where);
    }
  }

  void StoreFaceLabel(const std::vector<double>& values, const std::string& where) {
    const double label = values[static_cast<std::size_t>(face_label_)];
    if (!IsWholeInt64(label))
      Fail(where, "face " + std::to_string(faces_->labels.size()) + ": label " + std::to_string(label) +
                      " is not an integer a 64-bit label can hold");
    faces_->labels.push_back(static_cast<std::int64_t>(label));
  }

  void ReadBinaryElement(const Element& e, bool is_vertex) {
    const bool little = encoding_ == Encoding::kBinaryLittle;
    if (offset_ == 0) offset_ = lines_.position();
    // The declared count against the bytes left, before allocating anything (docs/reliability.md): a record
    // takes its scalars' bytes and, for each list, at least the list's count (an empty list); fixed-size
    // records exactly that.
    bool fixed = true;
    std::size_t record = 0;
    for (const Property& p : e.properties) {
      if (p.is_list) {
        fixed = false;
        record += SizeOf(p.count_type);
      } else {
        record += SizeOf(p.type);
      }
    }
    const std::size_t left = bytes_.size() - offset_;
    if (record > 0 && e.count > left / record) {
      Fail(AtByte(offset_), "truncated: element '" + e.name + "' declares " + std::to_string(e.count) +
                                " entries (" + std::to_string(e.count) + " x " + (fixed ? "" : "at least ") +
                                std::to_string(record) + " bytes) but only " + std::to_string(left) +
                                " bytes follow");
    }
    // An element without properties has records of no bytes: nothing to read, however many it declares (a
    // loop over a claimed 2^34 of them would only spin).
    if (record == 0) return;
    if (is_vertex) Allocate(e.count);
    const bool is_face = faces_ != nullptr && &e == face_element_;
    std::vector<double> values(e.properties.size());
    for (std::size_t i = 0; i < e.count; ++i) {
      const std::size_t record_start = offset_;
      for (std::size_t p = 0; p < e.properties.size(); ++p) {
        const Property& prop = e.properties[p];
        if (prop.is_list) {
          // The count's type may be signed: only a whole number from 0 is a count, and converting a negative
          // one to an unsigned size is undefined behaviour.
          const double count = Take(prop.count_type, little, e, i);
          if (!(count >= 0.0) || count != std::floor(count))
            Fail(AtByte(record_start), "element '" + e.name + "' entry " + std::to_string(i) + ": list '" +
                                           prop.name + "' has the count " + std::to_string(count) +
                                           ", not a non-negative integer");
          const auto n = static_cast<std::size_t>(count);
          const std::size_t need = n * SizeOf(prop.type);
          if (need / std::max<std::size_t>(1, SizeOf(prop.type)) != n || need > bytes_.size() - offset_)
            TruncatedAt(e, i);
          if (is_face && static_cast<int>(p) == face_list_) {
            faces_->offsets.push_back(faces_->indices.size());
            for (std::size_t k = 0; k < n; ++k)
              StoreFaceIndex(LoadAsDouble(bytes_.data() + offset_ + k * SizeOf(prop.type), prop.type, little),
                             AtByte(record_start));
          }
          offset_ += need;
        } else {
          values[p] = Take(prop.type, little, e, i);
        }
      }
      if (is_vertex) StoreVertex(i, values, AtByte(record_start));
      if (is_face && face_label_ >= 0) StoreFaceLabel(values, AtByte(record_start));
    }
  }

  double Take(ScalarType t, bool little, const Element& e, std::size_t i) {
    if (SizeOf(t) > bytes_.size() - offset_) TruncatedAt(e, i);
    const double v = LoadAsDouble(bytes_.data() + offset_, t, little);
    offset_ += SizeOf(t);
    return v;
  }

  [[noreturn]] void TruncatedAt(const Element& e, std::size_t i) const {
    Fail(AtByte(offset_), "truncated: the file ends inside element '" + e.name + "' entry " +
                              std::to_string(i) + " of " + std::to_string(e.count));
  }

  const std::string& bytes_;
  const std::string& file_;
  LineReader lines_{bytes_};
  Encoding encoding_ = Encoding::kAscii;
  std::vector<Element> elements_;
  VertexLayout layout_;
  std::size_t offset_ = 0;
  Scan scan_;
  PlyFaces* faces_ = nullptr;
  const Element* face_element_ = nullptr;
  int face_list_ = -1, face_label_ = -1;
};

}  // namespace

Scan ParsePly(const std::string& bytes, const std::string& file) {
  return PlyParser(bytes, file).Parse();
}

Scan ParsePlyMesh(const std::string& bytes, const std::string& file, PlyFaces& faces) {
  faces = PlyFaces();
  Scan vertices = PlyParser(bytes, file, &faces).Parse();
  faces.offsets.push_back(faces.indices.size());  // the end of the last face
  return vertices;
}

}  // namespace s2m::formats
