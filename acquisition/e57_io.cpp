// E57 reading and writing (docs/e57.md). The paged file layer is acquisition/formats/e57_pages.h, the
// bit-pack codec e57_bitpack.h, the compressed-vector sections and packets e57_section.h; this file reads and
// writes the file header and the XML section (pugixml) and turns data3D records into scans.

#include "acquisition/e57_io.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <array>
#include <cctype>
#include <charconv>
#include <chrono>
#include <cmath>
#include <cstring>
#include <fstream>
#include <limits>
#include <map>
#include <optional>
#include <pugixml.hpp>
#include <sstream>

#include "acquisition/format_error.h"
#include "acquisition/formats/binary_util.h"
#include "acquisition/formats/e57_bitpack.h"
#include "acquisition/formats/e57_pages.h"
#include "acquisition/formats/e57_section.h"

namespace s2m {
namespace {

namespace fs = std::filesystem;
namespace e57 = formats::e57;

constexpr std::size_t kHeaderSize = 48;
constexpr char kSignature[] = "ASTM-E57";
constexpr const char* kNamespace = "http://www.astm.org/COMMIT/E57/2010-e57-v1.0";

// ------------------------------------------------------------------------------------------------ reading

// The XML section with what is needed to turn a node into a byte offset of the file.
struct XmlContext {
  const std::string& file;
  std::uint64_t xml_logical = 0;

  std::string Where(const pugi::xml_node& node, const std::string& path) const {
    const std::ptrdiff_t offset = node.offset_debug();
    std::string where = offset >= 0
                            ? AtByte(e57::LogicalToPhysical(xml_logical + static_cast<std::uint64_t>(offset)))
                            : std::string("XML");
    return where + " (XML " + path + ")";
  }
  [[noreturn]] void Fail(const pugi::xml_node& node, const std::string& path,
                         const std::string& problem) const {
    throw FormatError(file, Where(node, path), problem);
  }
};

std::string_view Trimmed(const char* text) {
  std::string_view s(text);
  while (!s.empty() && std::isspace(static_cast<unsigned char>(s.front()))) s.remove_prefix(1);
  while (!s.empty() && std::isspace(static_cast<unsigned char>(s.back()))) s.remove_suffix(1);
  return s;
}

bool ParseInt64(std::string_view s, std::int64_t& v) {
  if (!s.empty() && s.front() == '+') s.remove_prefix(1);
  const auto [end, ec] = std::from_chars(s.data(), s.data() + s.size(), v);
  return ec == std::errc() && end == s.data() + s.size() && !s.empty();
}
bool ParseUint64(std::string_view s, std::uint64_t& v) {
  if (!s.empty() && s.front() == '+') s.remove_prefix(1);
  const auto [end, ec] = std::from_chars(s.data(), s.data() + s.size(), v);
  return ec == std::errc() && end == s.data() + s.size() && !s.empty();
}
bool ParseDouble(std::string_view s, double& v) {
  if (!s.empty() && s.front() == '+') s.remove_prefix(1);
  const auto [end, ec] = std::from_chars(s.data(), s.data() + s.size(), v);
  return ec == std::errc() && end == s.data() + s.size() && !s.empty();
}

std::string TypeOf(const pugi::xml_node& node) {
  return node.attribute("type").value();
}

// A Float or Integer element's value (an empty element is 0, the standard's default).
double NumberOf(const XmlContext& x, const pugi::xml_node& node, const std::string& path) {
  const std::string type = TypeOf(node);
  if (type != "Float" && type != "Integer" && type != "ScaledInteger")
    x.Fail(node, path, "expected a number element, found type '" + type + "'");
  const std::string_view text = Trimmed(node.text().get());
  if (text.empty()) return 0.0;
  double v = 0.0;
  if (type == "Integer" || type == "ScaledInteger") {
    std::int64_t i = 0;
    if (!ParseInt64(text, i)) x.Fail(node, path, "not an integer: '" + std::string(text) + "'");
    v = static_cast<double>(i);
    if (type == "ScaledInteger") {
      double scale = 1.0, offset = 0.0;
      if (node.attribute("scale")) ParseDouble(Trimmed(node.attribute("scale").value()), scale);
      if (node.attribute("offset")) ParseDouble(Trimmed(node.attribute("offset").value()), offset);
      v = v * scale + offset;
    }
  } else if (!ParseDouble(text, v)) {
    x.Fail(node, path, "not a number: '" + std::string(text) + "'");
  }
  if (!std::isfinite(v)) x.Fail(node, path, "not finite: '" + std::string(text) + "'");
  return v;
}

std::string StringOf(const pugi::xml_node& node) {
  return node ? std::string(node.text().get()) : std::string();
}

// pose: rotation (unit quaternion w, x, y, z) and translation, mapping the scan's coordinates into the file's
// world: p_world = R(q) p_scan + t, i.e. world_T_scan (the standard's "transforms from the local coordinate
// system to the file-level coordinate system").
RigidMotion PoseOf(const XmlContext& x, const pugi::xml_node& pose, const std::string& path,
                   std::vector<std::string>& notes) {
  if (!pose) return RigidMotion::Identity();
  Eigen::Quaterniond q = Eigen::Quaterniond::Identity();
  if (const pugi::xml_node r = pose.child("rotation")) {
    const auto c = [&](const char* name) {
      const pugi::xml_node n = r.child(name);
      return n ? NumberOf(x, n, path + "/rotation/" + name) : 0.0;
    };
    q = Eigen::Quaterniond(c("w"), c("x"), c("y"), c("z"));
    const double norm = q.norm();
    if (!(norm > 1e-12)) x.Fail(r, path + "/rotation", "the rotation quaternion is zero");
    if (std::abs(norm - 1.0) > 1e-6) {
      notes.push_back("the pose's rotation quaternion had norm " + std::to_string(norm) + "; normalized");
    }
  }
  Eigen::Vector3d t = Eigen::Vector3d::Zero();
  if (const pugi::xml_node tr = pose.child("translation")) {
    const char* names[] = {"x", "y", "z"};
    for (int i = 0; i < 3; ++i) {
      const pugi::xml_node n = tr.child(names[i]);
      t[i] = n ? NumberOf(x, n, path + "/translation/" + names[i]) : 0.0;
    }
  }
  return RigidMotion::FromQuaternion(q, t);
}

// The prototype's terminal elements in document order (the order of the bytestreams), nested structures as
// paths.
void CollectFields(const XmlContext& x, const pugi::xml_node& node, const std::string& prefix,
                   const std::string& path, std::vector<e57::PrototypeField>& fields, int depth = 0) {
  // Nesting is bounded so that a hostile file cannot exhaust the stack.
  if (depth > 16) x.Fail(node, path, "the prototype nests structures deeper than 16 levels");
  for (const pugi::xml_node child : node.children()) {
    if (child.type() != pugi::node_element) continue;
    const std::string name = prefix + child.name();
    const std::string where = path + "/" + child.name();
    const std::string type = TypeOf(child);
    e57::PrototypeField field;
    field.name = name;
    if (type == "Structure") {
      CollectFields(x, child, name + "/", where, fields, depth + 1);
      continue;
    }
    const auto integer_attribute = [&](const char* attribute, std::int64_t fallback) {
      const pugi::xml_attribute a = child.attribute(attribute);
      if (!a) return fallback;
      std::int64_t v = 0;
      if (!ParseInt64(Trimmed(a.value()), v))
        x.Fail(child, where, std::string(attribute) + " is not an integer: '" + a.value() + "'");
      return v;
    };
    const auto double_attribute = [&](const char* attribute, double fallback) {
      const pugi::xml_attribute a = child.attribute(attribute);
      if (!a) return fallback;
      double v = 0.0;
      if (!ParseDouble(Trimmed(a.value()), v) || !std::isfinite(v))
        x.Fail(child, where, std::string(attribute) + " is not a finite number: '" + a.value() + "'");
      return v;
    };
    if (type == "Float") {
      const std::string precision = child.attribute("precision").as_string("double");
      if (precision == "single") {
        field.codec.type = e57::FieldType::kFloat32;
      } else if (precision == "double") {
        field.codec.type = e57::FieldType::kFloat64;
      } else {
        x.Fail(child, where, "unknown Float precision '" + precision + "' (single or double)");
      }
    } else if (type == "Integer" || type == "ScaledInteger") {
      field.codec.type = type == "Integer" ? e57::FieldType::kInteger : e57::FieldType::kScaledInteger;
      field.codec.minimum = integer_attribute("minimum", std::numeric_limits<std::int64_t>::min());
      field.codec.maximum = integer_attribute("maximum", std::numeric_limits<std::int64_t>::max());
      if (field.codec.minimum > field.codec.maximum) {
        x.Fail(child, where,
               "minimum " + std::to_string(field.codec.minimum) + " exceeds maximum " +
                   std::to_string(field.codec.maximum));
      }
      if (type == "ScaledInteger") {
        field.codec.scale = double_attribute("scale", 1.0);
        field.codec.offset = double_attribute("offset", 0.0);
        if (field.codec.scale == 0.0) x.Fail(child, where, "scale is 0");
      }
    } else if (type == "String") {
      x.Fail(child, where, "String fields in point records are not supported");
    } else {
      x.Fail(child, where, "element type '" + type + "' cannot be part of a point record");
    }
    fields.push_back(std::move(field));
  }
}

std::string Describe(const e57::PrototypeField& f) {
  std::string s = f.name + ": " + e57::ToString(f.codec.type);
  if (f.codec.type == e57::FieldType::kInteger || f.codec.type == e57::FieldType::kScaledInteger) {
    s += ", " + std::to_string(f.codec.BitWidth()) + " bits [" + std::to_string(f.codec.minimum) + ", " +
         std::to_string(f.codec.maximum) + "]";
    if (f.codec.type == e57::FieldType::kScaledInteger) {
      std::ostringstream o;
      o.precision(17);
      o << ", scale " << f.codec.scale;
      if (f.codec.offset != 0.0) o << ", offset " << f.codec.offset;
      s += o.str();
    }
  }
  return s;
}

// The codecs vector: empty means bit-pack for every field; an entry naming bitPackCodec says so explicitly.
void CheckCodecs(const XmlContext& x, const pugi::xml_node& codecs, const std::string& path) {
  for (const pugi::xml_node codec : codecs.children()) {
    if (codec.type() != pugi::node_element) continue;
    bool bitpack = false;
    std::string names;
    for (const pugi::xml_node c : codec.children()) {
      if (c.type() != pugi::node_element || std::string(c.name()) == "inputs") continue;
      if (std::string(c.name()) == "bitPackCodec") bitpack = true;
      names += (names.empty() ? "" : ", ") + std::string(c.name());
    }
    if (!bitpack) {
      x.Fail(codec, path + "/codecs",
             "unknown codec '" + (names.empty() ? std::string("?") : names) +
                 "' (only the bit-pack codec is defined by the standard)");
    }
  }
}

E57Scan ReadScan(e57::PagedReader& reader, const XmlContext& x, const pugi::xml_node& node, std::size_t k,
                 std::vector<std::pair<std::uint64_t, std::uint64_t>>& claimed) {
  const std::string path = "data3D/" + std::to_string(k);
  if (TypeOf(node) != "Structure") x.Fail(node, path, "a data3D entry must be a Structure");
  E57Scan out;
  out.guid = StringOf(node.child("guid"));
  out.name = StringOf(node.child("name"));
  out.description = StringOf(node.child("description"));
  std::vector<std::string> notes;
  out.scan.world_T_scan = PoseOf(x, node.child("pose"), path + "/pose", notes);

  const pugi::xml_node points = node.child("points");
  if (!points) x.Fail(node, path, "no 'points' element");
  if (TypeOf(points) != "CompressedVector")
    x.Fail(points, path + "/points", "'points' is not a CompressedVector");
  std::uint64_t file_offset = 0, record_count = 0;
  if (!ParseUint64(Trimmed(points.attribute("fileOffset").value()), file_offset))
    x.Fail(points, path + "/points", "missing or bad fileOffset attribute");
  if (!ParseUint64(Trimmed(points.attribute("recordCount").value()), record_count))
    x.Fail(points, path + "/points", "missing or bad recordCount attribute");
  const pugi::xml_node prototype = points.child("prototype");
  if (!prototype || TypeOf(prototype) != "Structure")
    x.Fail(points, path + "/points", "no prototype Structure");
  CheckCodecs(x, points.child("codecs"), path + "/points");
  std::vector<e57::PrototypeField> fields;
  CollectFields(x, prototype, "", path + "/points/prototype", fields);
  if (fields.empty()) x.Fail(prototype, path + "/points/prototype", "the prototype has no fields");
  std::map<std::string, std::size_t> index;
  for (std::size_t f = 0; f < fields.size(); ++f) {
    index.emplace(fields[f].name, f);
    out.fields.push_back(Describe(fields[f]));
  }
  const auto find = [&](const char* name) -> std::optional<std::size_t> {
    const auto it = index.find(name);
    return it == index.end() ? std::nullopt : std::optional<std::size_t>(it->second);
  };
  const auto cx = find("cartesianX"), cy = find("cartesianY"), cz = find("cartesianZ");
  const auto sr = find("sphericalRange"), sa = find("sphericalAzimuth"), se = find("sphericalElevation");
  const bool cartesian = cx && cy && cz;
  if (!cartesian && !(sr && sa && se)) {
    x.Fail(prototype, path + "/points/prototype",
           "no coordinates: neither cartesianX/Y/Z nor sphericalRange/Azimuth/Elevation");
  }
  out.coordinates = cartesian ? "cartesian" : "spherical";
  const auto state = cartesian ? find("cartesianInvalidState") : find("sphericalInvalidState");
  const auto intensity = find("intensity"), intensity_invalid = find("isIntensityInvalid");
  const auto red = find("colorRed"), green = find("colorGreen"), blue = find("colorBlue");
  const auto colour_invalid = find("isColorInvalid");
  const auto row = find("rowIndex"), column = find("columnIndex");
  const bool colour = red && green && blue;

  // Only the columns used here are kept (the others are decoded and dropped): at most 12 numbers per record.
  std::vector<bool> keep(fields.size(), false);
  for (const auto& f : {cx, cy, cz, sr, sa, se, state, intensity, intensity_invalid, red, green, blue,
                        colour_invalid, row, column}) {
    if (f) keep[*f] = true;
  }
  const std::vector<std::vector<double>> c =
      e57::ReadCompressedVector(reader, file_offset, record_count, fields, keep, path + "/points", claimed);
  out.records = record_count;
  const auto n = static_cast<std::size_t>(record_count);
  std::size_t valid = 0;
  for (std::size_t r = 0; r < n; ++r) valid += !(state && c[*state][r] != 0.0);
  out.invalid = n - valid;
  out.scan.points.resize(3, static_cast<Eigen::Index>(valid));
  if (intensity) out.intensity.resize(static_cast<Eigen::Index>(valid));
  if (colour) out.colour.resize(3, static_cast<Eigen::Index>(valid));
  const bool grid = row && column;
  if (grid) {
    out.row_index.reserve(valid);
    out.column_index.reserve(valid);
  }
  const std::string where = x.Where(points, path + "/points");
  Eigen::Index j = 0;
  for (std::size_t r = 0; r < n; ++r) {
    if (state && c[*state][r] != 0.0) continue;  // no usable position (invalid, or a direction only)
    Eigen::Vector3d p;
    if (cartesian) {
      p = Eigen::Vector3d(c[*cx][r], c[*cy][r], c[*cz][r]);
    } else {
      // ASTM E2807 spherical coordinates: azimuth from +x towards +y, elevation from the xy plane towards +z.
      const double range = c[*sr][r], azimuth = c[*sa][r], elevation = c[*se][r];
      if (range < 0.0)
        throw FormatError(x.file, where, "record " + std::to_string(r) + ": negative sphericalRange");
      p = range * Eigen::Vector3d(std::cos(elevation) * std::cos(azimuth),
                                  std::cos(elevation) * std::sin(azimuth), std::sin(elevation));
    }
    if (!p.allFinite()) {
      throw FormatError(x.file, where,
                        "record " + std::to_string(r) +
                            ": coordinates are not finite and its invalid state does not say so");
    }
    out.scan.points.col(j) = p;
    if (intensity) {
      out.intensity[j] = intensity_invalid && c[*intensity_invalid][r] != 0.0
                             ? std::numeric_limits<double>::quiet_NaN()
                             : c[*intensity][r];
    }
    if (colour) {
      out.colour.col(j) = colour_invalid && c[*colour_invalid][r] != 0.0
                              ? Eigen::Vector3d::Constant(std::numeric_limits<double>::quiet_NaN())
                              : Eigen::Vector3d(c[*red][r], c[*green][r], c[*blue][r]);
    }
    if (grid) {
      // Integer fields in valid files; a Float field could hold anything, so the conversion is checked.
      for (const std::size_t f : {*row, *column}) {
        const double v = c[f][r];
        if (!(std::abs(v) < 9.2e18) || v != std::floor(v)) {
          throw FormatError(
              x.file, where,
              "record " + std::to_string(r) + ": " + fields[f].name + " is not an integer index");
        }
      }
      out.row_index.push_back(static_cast<std::int64_t>(c[*row][r]));
      out.column_index.push_back(static_cast<std::int64_t>(c[*column][r]));
    }
    ++j;
  }
  out.scan.units = "m";  // the standard's unit of length
  out.scan.metadata.device = grid ? "file:organized" : "file";
  out.scan.metadata.source = x.file + " " + path + (out.name.empty() ? "" : " '" + out.name + "'");
  if (out.invalid > 0) {
    notes.push_back("dropped " + std::to_string(out.invalid) + " of " + std::to_string(n) + " records of " +
                    path + " whose " + (cartesian ? "cartesianInvalidState" : "sphericalInvalidState") +
                    " is not 0 (no usable position)");
  }
  if (!cartesian) notes.push_back(path + ": spherical coordinates converted to cartesian");
  out.scan.metadata.notes = std::move(notes);
  return out;
}

// -------------------------------------------------------------------------------------------------- writing

double MetresPerUnit(const std::string& units, const std::string& file) {
  static const std::map<std::string, double> kUnits = {{"m", 1.0},   {"metre", 1.0}, {"meter", 1.0},
                                                       {"cm", 1e-2}, {"mm", 1e-3},   {"um", 1e-6}};
  const auto it = kUnits.find(units);
  if (it == kUnits.end()) {
    throw FormatError(file, "",
                      "cannot write units '" + units +
                          "' to E57, which stores metres: give the data's units (m, cm, mm or um)");
  }
  return it->second;
}

std::string NumberText(double v) {
  char text[32];
  const auto [end, ec] = std::to_chars(text, text + sizeof text, v);  // shortest text that reads back exactly
  return ec == std::errc() ? std::string(text, end) : std::string("0");
}

pugi::xml_node Element(pugi::xml_node parent, const char* name, const char* type) {
  pugi::xml_node n = parent.append_child(name);
  n.append_attribute("type") = type;
  return n;
}
void StringElement(pugi::xml_node parent, const char* name, const std::string& value) {
  Element(parent, name, "String").text().set(value.c_str());
}
void FloatElement(pugi::xml_node parent, const char* name, double value) {
  Element(parent, name, "Float").text().set(NumberText(value).c_str());
}
void IntegerElement(pugi::xml_node parent, const char* name, std::int64_t value) {
  Element(parent, name, "Integer").text().set(std::to_string(value).c_str());
}

// A GUID derived from the content (FNV-1a over the bytes with two seeds), so the same data give the same
// file.
std::string ContentGuid(const void* data, std::size_t size, std::uint64_t salt) {
  const auto fnv = [&](std::uint64_t h) {
    h ^= salt;
    const auto* p = static_cast<const unsigned char*>(data);
    for (std::size_t i = 0; i < size; ++i) h = (h ^ p[i]) * 0x100000001b3ull;
    return h;
  };
  const std::uint64_t a = fnv(0xcbf29ce484222325ull), b = fnv(0x84222325cbf29ce4ull);
  char text[40];
  std::snprintf(text, sizeof text, "{%08x-%04x-4%03x-8%03x-%012llx}", static_cast<unsigned>(a >> 32),
                static_cast<unsigned>((a >> 16) & 0xFFFFu), static_cast<unsigned>(a & 0xFFFu),
                static_cast<unsigned>((b >> 48) & 0xFFFu),
                static_cast<unsigned long long>(b & 0xFFFFFFFFFFFFull));
  return text;
}

struct FieldColumn {
  const char* name;
  e57::FieldCodec codec;
  e57::BitWriter bits;
};

void AddPrototypeElement(pugi::xml_node prototype, const FieldColumn& f) {
  switch (f.codec.type) {
    case e57::FieldType::kFloat32:
      Element(prototype, f.name, "Float").append_attribute("precision") = "single";
      break;
    case e57::FieldType::kFloat64:
      Element(prototype, f.name, "Float").append_attribute("precision") = "double";
      break;
    case e57::FieldType::kInteger:
    case e57::FieldType::kScaledInteger: {
      pugi::xml_node n =
          Element(prototype, f.name, f.codec.type == e57::FieldType::kInteger ? "Integer" : "ScaledInteger");
      n.append_attribute("minimum") = std::to_string(f.codec.minimum).c_str();
      n.append_attribute("maximum") = std::to_string(f.codec.maximum).c_str();
      if (f.codec.type == e57::FieldType::kScaledInteger) {
        n.append_attribute("scale") = NumberText(f.codec.scale).c_str();
        n.append_attribute("offset") = NumberText(f.codec.offset).c_str();
      }
      break;
    }
  }
}

// Round(v / scale) as an integer, refusing values the int64 range (kept within 2^62) cannot hold.
std::int64_t ScaledRaw(double v, double scale, const std::string& file, const std::string& what) {
  const double q = std::round(v / scale);
  if (!(std::abs(q) < 4.611686018427387904e18))
    throw FormatError(
        file, "",
        what + " " + NumberText(v) + " is beyond the scaled-integer range (scale " + NumberText(scale) + ")");
  return static_cast<std::int64_t>(q);
}

// A column of values as a field: floats as they are, or scaled integers over the tight range of the values
// (`fill` for the records whose value is not written, e.g. invalid points, is kept in the range).
FieldColumn MakeColumn(const char* name, const std::vector<double>& values, const std::vector<bool>& written,
                       bool scaled_integer, bool single, double scale, const std::string& file) {
  FieldColumn f{name, {}, {}};
  if (!scaled_integer) {
    f.codec.type = single ? e57::FieldType::kFloat32 : e57::FieldType::kFloat64;
    for (std::size_t i = 0; i < values.size(); ++i) {
      const double v = written[i] ? values[i] : 0.0;
      if (single && !(std::abs(v) <= std::numeric_limits<float>::max()))
        throw FormatError(file, "", std::string(name) + " " + NumberText(v) + " is beyond single precision");
      f.bits.Put(e57::EncodeFloat(f.codec, v), f.codec.BitWidth());
    }
    return f;
  }
  f.codec.type = e57::FieldType::kScaledInteger;
  f.codec.scale = scale;
  std::vector<std::int64_t> raw(values.size(), 0);
  bool first = true;
  for (std::size_t i = 0; i < values.size(); ++i) {
    if (written[i]) raw[i] = ScaledRaw(values[i], scale, file, name);
    if (first || raw[i] < f.codec.minimum) f.codec.minimum = raw[i];
    if (first || raw[i] > f.codec.maximum) f.codec.maximum = raw[i];
    first = false;
  }
  for (const std::int64_t r : raw) f.bits.Put(e57::EncodeInteger(f.codec, r), f.codec.BitWidth());
  return f;
}

FieldColumn FlagColumn(const char* name, const std::vector<std::int64_t>& values, std::int64_t maximum) {
  FieldColumn f{name, {}, {}};
  f.codec.type = e57::FieldType::kInteger;
  f.codec.minimum = 0;
  f.codec.maximum = maximum;
  for (const std::int64_t v : values) f.bits.Put(e57::EncodeInteger(f.codec, v), f.codec.BitWidth());
  return f;
}

}  // namespace

E57Data ReadE57(const fs::path& path) {
  const std::string file = path.string();
  std::error_code ec;
  if (fs::is_directory(path, ec)) throw FormatError(file, "", "is a directory, not an E57 file");
  e57::PagedReader reader(file);
  if (reader.physical_size() == 0) throw FormatError(file, "", "empty file");
  // The signature first, straight from the bytes: a file of another kind gets that answer, not a checksum
  // error.
  {
    std::ifstream in(path, std::ios::binary);
    char signature[8] = {};
    in.read(signature, sizeof signature);
    if (in.gcount() < 8 || std::memcmp(signature, kSignature, 8) != 0)
      throw FormatError(file, AtByte(0), "not an E57 file (the first 8 bytes are not \"ASTM-E57\")");
  }
  const std::string header = reader.Read(0, kHeaderSize, "file header");
  const auto u32 = [&](std::size_t at) {
    return formats::LoadScalar<std::uint32_t>(header.data() + at, true);
  };
  const auto u64 = [&](std::size_t at) {
    return formats::LoadScalar<std::uint64_t>(header.data() + at, true);
  };
  const std::uint32_t major = u32(8), minor = u32(12);
  const std::uint64_t physical_length = u64(16), xml_physical = u64(24), xml_length = u64(32),
                      page_size = u64(40);
  if (major != 1) {
    throw FormatError(file, AtByte(8),
                      "unsupported E57 version " + std::to_string(major) + "." + std::to_string(minor) +
                          " (this reader reads version 1)");
  }
  if (page_size != e57::kPageSize)
    throw FormatError(file, AtByte(40),
                      "page size " + std::to_string(page_size) + " (the standard's is 1024)");
  if (physical_length != reader.physical_size()) {
    throw FormatError(file, AtByte(16),
                      (physical_length > reader.physical_size() ? "truncated: " : "") +
                          std::string("the header declares ") + std::to_string(physical_length) +
                          " bytes, the file has " + std::to_string(reader.physical_size()));
  }
  if (physical_length % e57::kPageSize != 0) {
    throw FormatError(
        file, AtByte(16),
        "the file length " + std::to_string(physical_length) + " is not a whole number of 1024-byte pages");
  }
  const std::optional<std::uint64_t> xml_logical = e57::PhysicalToLogical(xml_physical);
  if (!xml_logical || *xml_logical < kHeaderSize || *xml_logical > reader.logical_size() ||
      xml_length > reader.logical_size() - *xml_logical) {
    throw FormatError(file, AtByte(24),
                      "the XML section (physical offset " + std::to_string(xml_physical) + ", " +
                          std::to_string(xml_length) + " bytes) does not lie in the file");
  }
  if (xml_length == 0) throw FormatError(file, AtByte(32), "the XML section is empty");
  const std::string xml = reader.Read(*xml_logical, static_cast<std::size_t>(xml_length), "XML section");

  pugi::xml_document doc;
  const pugi::xml_parse_result parsed =
      doc.load_buffer(xml.data(), xml.size(), pugi::parse_default, pugi::encoding_utf8);
  if (!parsed) {
    throw FormatError(
        file, AtByte(e57::LogicalToPhysical(*xml_logical + static_cast<std::uint64_t>(parsed.offset))),
        std::string("bad XML: ") + parsed.description());
  }
  const XmlContext x{file, *xml_logical};
  const pugi::xml_node root = doc.child("e57Root");
  if (!root) throw FormatError(file, AtByte(xml_physical), "bad XML: no e57Root element");
  E57Data data;
  data.guid = StringOf(root.child("guid"));
  data.library_version = StringOf(root.child("e57LibraryVersion"));
  if (const pugi::xml_node images = root.child("images2D")) {
    for (const pugi::xml_node i : images.children())
      if (i.type() == pugi::node_element) ++data.images;
  }
  const pugi::xml_node data3d = root.child("data3D");
  if (!data3d) return data;
  std::size_t k = 0;
  std::vector<std::pair<std::uint64_t, std::uint64_t>> claimed;  // sections read so far: none may overlap
  for (const pugi::xml_node child : data3d.children()) {
    if (child.type() != pugi::node_element) continue;
    data.scans.push_back(ReadScan(reader, x, child, k++, claimed));
  }
  return data;
}

bool IsE57File(const fs::path& path) {
  std::string ext = path.extension().string();
  for (char& c : ext) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return ext == kE57Extension;
}

ScanSet ToScanSet(const E57Data& data, const fs::path& path) {
  ScanSet set;
  set.name = path.stem().string();
  std::vector<std::string> left_out;
  for (const E57Scan& s : data.scans) {
    if (s.scan.empty()) {
      left_out.push_back(s.scan.metadata.source + " has no valid point: left out");
      continue;
    }
    set.scans.push_back(s.scan);
  }
  if (set.scans.empty()) {
    throw FormatError(path.string(), "",
                      data.scans.empty() ? "the E57 file has no data3D scan"
                                         : "no data3D scan of the E57 file has a valid point");
  }
  for (const std::string& note : left_out) set.scans.front().metadata.notes.push_back(note);
  return set;
}

ScanSet ReadE57ScanSet(const fs::path& path) {
  return ToScanSet(ReadE57(path), path);
}

Scan ToOneCloud(const E57Data& data, const fs::path& path) {
  const ScanSet set = ToScanSet(data, path);
  Scan scan;
  scan.points = set.MergedWorldPoints();
  scan.units = set.scans.front().units;
  scan.metadata = set.scans.front().metadata;
  scan.metadata.source = path.string();
  bool posed = false;
  for (std::size_t k = 0; k < set.scans.size(); ++k) {
    posed = posed || !set.scans[k].world_T_scan.matrix().isIdentity(0.0);
    if (k == 0) continue;
    for (const std::string& note : set.scans[k].metadata.notes) scan.metadata.notes.push_back(note);
    if (set.scans[k].metadata.device != scan.metadata.device) scan.metadata.device = "file";
  }
  if (set.scans.size() > 1 || posed) {
    scan.metadata.notes.push_back(
        std::to_string(set.scans.size()) + " E57 scan" + (set.scans.size() > 1 ? "s" : "") +
        " placed in the file's world frame by " + (set.scans.size() > 1 ? "their poses" : "its pose"));
  }
  return scan;
}

bool E57WriteOptions::IsValid() const {
  const auto ok = [](double s) { return std::isfinite(s) && s > 0.0; };
  return ok(coordinate_scale) && ok(intensity_scale);
}

void WriteE57(const fs::path& path, const std::vector<E57Scan>& scans, const E57WriteOptions& options) {
  const std::string file = path.string();
  if (!options.IsValid()) throw std::invalid_argument("E57WriteOptions: scales must be positive and finite");
  if (scans.empty()) throw FormatError(file, "", "refusing to write an E57 file without scans");
  std::string logical(kHeaderSize, '\0');

  pugi::xml_document doc;
  pugi::xml_node declaration = doc.append_child(pugi::node_declaration);
  declaration.append_attribute("version") = "1.0";
  declaration.append_attribute("encoding") = "UTF-8";
  pugi::xml_node root = doc.append_child("e57Root");
  root.append_attribute("type") = "Structure";
  root.append_attribute("xmlns") = kNamespace;
  StringElement(root, "formatName", "ASTM E57 3D Imaging Data File");
  pugi::xml_node file_guid = Element(root, "guid", "String");
  IntegerElement(root, "versionMajor", 1);
  IntegerElement(root, "versionMinor", 0);
  StringElement(root, "e57LibraryVersion", "scan2model");
  StringElement(root, "coordinateMetadata", "");
  pugi::xml_node created = Element(root, "creationDateTime", "Structure");
  // GPS time: seconds since 1980-01-06 00:00:00 UTC, ahead of UTC by the 18 leap seconds since then.
  const double unix_now =
      std::chrono::duration<double>(std::chrono::system_clock::now().time_since_epoch()).count();
  FloatElement(created, "dateTimeValue", unix_now - 315964800.0 + 18.0);
  IntegerElement(created, "isAtomicClockReferenced", 0);
  pugi::xml_node data3d = Element(root, "data3D", "Vector");
  data3d.append_attribute("allowHeterogeneousChildren") = "1";

  std::string all_guids;
  for (std::size_t k = 0; k < scans.size(); ++k) {
    const E57Scan& s = scans[k];
    const std::string what = "data3D/" + std::to_string(k);
    if (s.scan.empty()) throw FormatError(file, "", what + ": refusing to write an empty scan");
    const double metres = MetresPerUnit(s.scan.units, file);
    const auto n = static_cast<std::size_t>(s.scan.size());
    const bool has_intensity = s.intensity.size() > 0;
    if (has_intensity && static_cast<std::size_t>(s.intensity.size()) != n)
      throw FormatError(file, "",
                        what + ": " + std::to_string(s.intensity.size()) + " intensities for " +
                            std::to_string(n) + " points");
    std::vector<bool> valid(n);
    std::array<std::vector<double>, 3> xyz;
    for (auto& a : xyz) a.resize(n);
    Eigen::Vector3d lo = Eigen::Vector3d::Constant(std::numeric_limits<double>::infinity()), hi = -lo;
    std::size_t invalid = 0;
    for (std::size_t i = 0; i < n; ++i) {
      const Eigen::Vector3d p = s.scan.points.col(static_cast<Eigen::Index>(i)) * metres;
      valid[i] = p.allFinite();
      invalid += !valid[i];
      for (int a = 0; a < 3; ++a) xyz[static_cast<std::size_t>(a)][i] = p[a];
      if (valid[i]) lo = lo.cwiseMin(p), hi = hi.cwiseMax(p);
    }
    if (invalid == n) throw FormatError(file, "", what + ": no point has finite coordinates");
    std::vector<FieldColumn> columns;
    const bool scaled = options.coordinates == E57CoordinateEncoding::kScaledInteger;
    const bool single = options.coordinates == E57CoordinateEncoding::kFloat32;
    const char* axes[] = {"cartesianX", "cartesianY", "cartesianZ"};
    for (int a = 0; a < 3; ++a)
      columns.push_back(MakeColumn(axes[a], xyz[static_cast<std::size_t>(a)], valid, scaled, single,
                                   options.coordinate_scale, file));
    if (invalid > 0) {
      std::vector<std::int64_t> state(n);
      for (std::size_t i = 0; i < n; ++i) state[i] = valid[i] ? 0 : 2;  // 2: no position at all
      columns.push_back(FlagColumn("cartesianInvalidState", state, 2));
    }
    double intensity_lo = std::numeric_limits<double>::infinity(), intensity_hi = -intensity_lo;
    if (has_intensity) {
      std::vector<double> values(n);
      std::vector<bool> known(n);
      std::vector<std::int64_t> flag(n);
      for (std::size_t i = 0; i < n; ++i) {
        values[i] = s.intensity[static_cast<Eigen::Index>(i)];
        known[i] = std::isfinite(values[i]);
        flag[i] = known[i] ? 0 : 1;
        if (known[i])
          intensity_lo = std::min(intensity_lo, values[i]), intensity_hi = std::max(intensity_hi, values[i]);
      }
      columns.push_back(
          MakeColumn("intensity", values, known, options.intensity == E57IntensityEncoding::kScaledInteger,
                     options.intensity == E57IntensityEncoding::kFloat32, options.intensity_scale, file));
      if (intensity_lo > intensity_hi) intensity_lo = intensity_hi = 0.0;
      if (std::find(flag.begin(), flag.end(), 1) != flag.end())
        columns.push_back(FlagColumn("isIntensityInvalid", flag, 1));
    }
    std::vector<e57::FieldCodec> codecs;
    std::vector<e57::BitWriter> streams;
    for (const FieldColumn& c : columns) codecs.push_back(c.codec), streams.push_back(c.bits);
    const std::uint64_t offset =
        e57::AppendCompressedVector(logical, codecs, streams, n, options.max_records_per_packet);

    pugi::xml_node entry = Element(data3d, "vectorChild", "Structure");
    const std::string guid = ContentGuid(s.scan.points.data(), n * 3 * sizeof(double), k);
    all_guids += guid;
    StringElement(entry, "guid", s.guid.empty() ? guid : s.guid);
    StringElement(entry, "name", s.name.empty() ? "scan " + std::to_string(k) : s.name);
    if (!s.description.empty()) StringElement(entry, "description", s.description);
    pugi::xml_node pose = Element(entry, "pose", "Structure");
    pugi::xml_node rotation = Element(pose, "rotation", "Structure");
    Eigen::Quaterniond q(s.scan.world_T_scan.rotation());
    q.normalize();
    FloatElement(rotation, "w", q.w());
    FloatElement(rotation, "x", q.x());
    FloatElement(rotation, "y", q.y());
    FloatElement(rotation, "z", q.z());
    pugi::xml_node translation = Element(pose, "translation", "Structure");
    const Eigen::Vector3d t = s.scan.world_T_scan.translation() * metres;
    FloatElement(translation, "x", t.x());
    FloatElement(translation, "y", t.y());
    FloatElement(translation, "z", t.z());
    pugi::xml_node bounds = Element(entry, "cartesianBounds", "Structure");
    FloatElement(bounds, "xMinimum", lo.x());
    FloatElement(bounds, "xMaximum", hi.x());
    FloatElement(bounds, "yMinimum", lo.y());
    FloatElement(bounds, "yMaximum", hi.y());
    FloatElement(bounds, "zMinimum", lo.z());
    FloatElement(bounds, "zMaximum", hi.z());
    if (has_intensity) {
      pugi::xml_node limits = Element(entry, "intensityLimits", "Structure");
      FloatElement(limits, "intensityMinimum", intensity_lo);
      FloatElement(limits, "intensityMaximum", intensity_hi);
    }
    pugi::xml_node points = Element(entry, "points", "CompressedVector");
    points.append_attribute("fileOffset") = std::to_string(offset).c_str();
    points.append_attribute("recordCount") = std::to_string(n).c_str();
    pugi::xml_node prototype = Element(points, "prototype", "Structure");
    for (const FieldColumn& c : columns) AddPrototypeElement(prototype, c);
    Element(points, "codecs", "Vector").append_attribute("allowHeterogeneousChildren") = "1";
  }
  file_guid.text().set(ContentGuid(all_guids.data(), all_guids.size(), scans.size()).c_str());
  Element(root, "images2D", "Vector").append_attribute("allowHeterogeneousChildren") = "1";

  std::ostringstream xml;
  doc.save(xml, "  ", pugi::format_default, pugi::encoding_utf8);
  const std::string xml_text = xml.str();
  while (logical.size() % 4 != 0) logical.push_back('\0');
  const std::uint64_t xml_logical = logical.size();
  logical += xml_text;
  const std::uint64_t pages = (logical.size() + e57::kPagePayload - 1) / e57::kPagePayload;
  // The header: signature, version 1.0, physical length, XML physical offset and logical length, page size.
  std::memcpy(logical.data(), kSignature, 8);
  const auto put = [&](std::size_t at, std::uint64_t v, int bytes) {
    for (int i = 0; i < bytes; ++i)
      logical[at + static_cast<std::size_t>(i)] = static_cast<char>((v >> (8 * i)) & 0xFFu);
  };
  put(8, 1, 4);
  put(12, 0, 4);
  put(16, pages * e57::kPageSize, 8);
  put(24, e57::LogicalToPhysical(xml_logical), 8);
  put(32, xml_text.size(), 8);
  put(40, e57::kPageSize, 8);
  const std::string physical = e57::PageLogicalStream(logical);

  const fs::path tmp = file + ".partial";
  {
    std::ofstream out(tmp, std::ios::binary | std::ios::trunc);
    if (!out) throw FormatError(file, "", "cannot create " + tmp.string());
    out.write(physical.data(), static_cast<std::streamsize>(physical.size()));
    out.flush();
    if (!out) {
      out.close();
      std::error_code ignored;
      fs::remove(tmp, ignored);
      throw FormatError(file, "", "write failed (disk full?)");
    }
  }
  std::error_code ec;
  fs::rename(tmp, path, ec);
  if (ec) throw FormatError(file, "", "cannot move the finished file into place: " + ec.message());
}

void WriteE57(const fs::path& path, const ScanSet& set, const E57WriteOptions& options) {
  std::vector<E57Scan> scans(set.scans.size());
  for (std::size_t k = 0; k < set.scans.size(); ++k) {
    scans[k].scan = set.scans[k];
    scans[k].name = set.name.empty() ? "view " + std::to_string(k) : set.name + " view " + std::to_string(k);
  }
  WriteE57(path, scans, options);
}

}  // namespace s2m
