// PCD, the Point Cloud Library's format (v0.5 to v0.7): DATA ascii, binary and binary_compressed (LZF, fields
// stored one after the other). NaN coordinates are PCD's own marker for "no measurement" (organized clouds,
// is_dense false): such points are dropped and counted in the scan's notes; a file with no valid point at all
// is an error. An integer `label` field (a per-point segmentation, e.g. the mOSD scenes' ground truth) is
// kept in Scan::labels.

#include <Eigen/Geometry>
#include <cmath>
#include <cstdint>
#include <string>
#include <vector>

#include "acquisition/format_error.h"
#include "acquisition/formats/binary_util.h"
#include "acquisition/formats/readers.h"
#include "acquisition/formats/text_util.h"

namespace s2m::formats {
namespace {

struct Field {
  std::string name;
  std::size_t size = 4;
  char type = 'F';
  std::size_t count = 1;
  ScalarType scalar = ScalarType::kFloat32;
  std::size_t offset = 0;  // within a binary record
};

std::optional<ScalarType> ScalarOf(char type, std::size_t size) {
  if (type == 'F' && size == 4) return ScalarType::kFloat32;
  if (type == 'F' && size == 8) return ScalarType::kFloat64;
  if (type == 'I' && size == 1) return ScalarType::kInt8;
  if (type == 'I' && size == 2) return ScalarType::kInt16;
  if (type == 'I' && size == 4) return ScalarType::kInt32;
  if (type == 'I' && size == 8) return ScalarType::kInt64;
  if (type == 'U' && size == 1) return ScalarType::kUint8;
  if (type == 'U' && size == 2) return ScalarType::kUint16;
  if (type == 'U' && size == 4) return ScalarType::kUint32;
  if (type == 'U' && size == 8) return ScalarType::kUint64;
  return std::nullopt;
}

// LZF decompression (Lehmann's liblzf format, as PCL writes it). Returns false on malformed input.
bool LzfDecompress(const unsigned char* in, std::size_t in_size, unsigned char* out, std::size_t out_size) {
  std::size_t ip = 0, op = 0;
  while (ip < in_size) {
    const unsigned ctrl = in[ip++];
    if (ctrl < 32) {  // literal run of ctrl + 1 bytes
      const std::size_t len = ctrl + 1;
      if (ip + len > in_size || op + len > out_size) return false;
      std::memcpy(out + op, in + ip, len);
      ip += len;
      op += len;
    } else {  // back reference
      std::size_t len = ctrl >> 5;
      if (len == 7) {
        if (ip >= in_size) return false;
        len += in[ip++];
      }
      len += 2;
      if (ip >= in_size) return false;
      const std::size_t distance = ((ctrl & 0x1f) << 8) + in[ip++] + 1;
      if (distance > op || op + len > out_size) return false;
      for (std::size_t k = 0; k < len; ++k, ++op) out[op] = out[op - distance];  // may overlap: byte by byte
    }
  }
  return op == out_size;
}

class PcdParser {
 public:
  PcdParser(const std::string& bytes, const std::string& file) : bytes_(bytes), file_(file) {}

  Scan Parse() {
    ParseHeader();
    if (points_ == 0) throw FormatError(file_, "header", "empty point set: POINTS is 0");
    RefuseCountBeyondSize();
    raw_.resize(3, static_cast<Eigen::Index>(points_));
    if (HasNormals()) raw_normals_.resize(3, static_cast<Eigen::Index>(points_));
    if (label_ >= 0) raw_labels_.resize(points_);
    if (data_ == "ascii")
      ReadAscii();
    else if (data_ == "binary")
      ReadBinary();
    else
      ReadCompressed();
    return Finish();
  }

 private:
  [[noreturn]] void Fail(const std::string& location, const std::string& problem) const {
    throw FormatError(file_, location, problem);
  }

  // A point's segmentation label: an integer field, but its text (or an unsigned 64-bit value) may still be
  // one that std::int64_t cannot hold.
  std::int64_t Label(double value, std::size_t point, const std::string& where) const {
    if (!IsWholeInt64(value))
      Fail(where, "point " + std::to_string(point) + ": label " + std::to_string(value) +
                      " is not an integer a 64-bit label can hold");
    return static_cast<std::int64_t>(value);
  }

  int FieldIndex(const char* name) const {
    for (std::size_t i = 0; i < fields_.size(); ++i) {
      if (fields_[i].name == name) return static_cast<int>(i);
    }
    return -1;
  }
  bool HasNormals() const { return nx_ >= 0 && ny_ >= 0 && nz_ >= 0; }

  void ParseHeader() {
    std::vector<std::string_view> tok;
    Line line;
    std::size_t width = 0, height = 1;
    bool have_points = false;
    std::vector<std::size_t> sizes, counts;
    std::vector<char> types;
    while (true) {
      if (!lines_.Next(line)) Fail(AtLine(lines_.line_number()), "truncated header: no DATA line");
      Tokenize(line.text, tok);
      if (tok.empty() || tok[0].front() == '#') continue;
      const std::string where = AtLine(line.number);
      const std::string_view key = tok[0];
      auto integers = [&](std::vector<std::size_t>& out) {
        out.clear();
        for (std::size_t i = 1; i < tok.size(); ++i) {
          std::size_t v;
          if (!ParseInteger(tok[i], v)) Fail(where, "not an integer: " + Quoted(tok[i]));
          out.push_back(v);
        }
      };
      if (key == "VERSION") continue;
      if (key == "FIELDS" || key == "COLUMNS") {
        fields_.clear();
        for (std::size_t i = 1; i < tok.size(); ++i) fields_.push_back({std::string(tok[i])});
      } else if (key == "SIZE") {
        integers(sizes);
      } else if (key == "TYPE") {
        types.clear();
        for (std::size_t i = 1; i < tok.size(); ++i) {
          if (tok[i].size() != 1) Fail(where, "bad TYPE " + Quoted(tok[i]));
          types.push_back(tok[i][0]);
        }
      } else if (key == "COUNT") {
        integers(counts);
      } else if (key == "WIDTH" || key == "HEIGHT" || key == "POINTS") {
        std::size_t v = 0;
        if (tok.size() != 2 || !ParseInteger(tok[1], v))
          Fail(where, "malformed " + std::string(key) + " line");
        if (key == "WIDTH") width = v;
        if (key == "HEIGHT") height = v;
        if (key == "POINTS") {
          points_ = v;
          have_points = true;
        }
      } else if (key == "VIEWPOINT") {
        double vp[7];
        if (tok.size() != 8) Fail(where, "VIEWPOINT needs 7 numbers");
        for (int i = 0; i < 7; ++i) {
          if (!ParseDouble(tok[static_cast<std::size_t>(i + 1)], vp[i]) || !std::isfinite(vp[i]))
            Fail(where, "bad VIEWPOINT value");
        }
        // PCD viewpoint: translation tx ty tz, then orientation qw qx qy qz: the sensor pose.
        viewpoint_ = RigidMotion::FromQuaternion(Eigen::Quaterniond(vp[3], vp[4], vp[5], vp[6]),
                                                 {vp[0], vp[1], vp[2]});
      } else if (key == "DATA") {
        if (tok.size() != 2 || (tok[1] != "ascii" && tok[1] != "binary" && tok[1] != "binary_compressed")) {
          Fail(where, "unsupported DATA " + Quoted(line.text) + " (ascii, binary or binary_compressed)");
        }
        data_ = std::string(tok[1]);
        break;
      } else {
        Fail(where, "unknown header keyword " + Quoted(key));
      }
    }
    if (fields_.empty()) Fail("header", "no FIELDS line");
    if (sizes.size() != fields_.size() || types.size() != fields_.size()) {
      Fail("header", "FIELDS, SIZE and TYPE list different numbers of fields");
    }
    if (!counts.empty() && counts.size() != fields_.size())
      Fail("header", "COUNT lists a different number of fields");
    std::size_t offset = 0;
    for (std::size_t i = 0; i < fields_.size(); ++i) {
      Field& f = fields_[i];
      f.size = sizes[i];
      f.type = types[i];
      f.count = counts.empty() ? 1 : counts[i];
      auto scalar = ScalarOf(f.type, f.size);
      if (!scalar)
        Fail("header", "field '" + f.name + "' has an unsupported TYPE/SIZE " + std::string(1, f.type) + "/" +
                           std::to_string(f.size));
      f.scalar = *scalar;
      f.offset = offset;
      offset += f.size * f.count;
    }
    record_size_ = offset;
    if (!have_points) points_ = width * height;
    if (width * height != points_) {
      Fail("header", "WIDTH x HEIGHT (" + std::to_string(width) + " x " + std::to_string(height) +
                         ") differs from POINTS " + std::to_string(points_));
    }
    organized_ = height > 1;
    x_ = FieldIndex("x"), y_ = FieldIndex("y"), z_ = FieldIndex("z");
    if (x_ < 0 || y_ < 0 || z_ < 0) Fail("header", "FIELDS lacks one of x, y, z");
    nx_ = FieldIndex("normal_x"), ny_ = FieldIndex("normal_y"), nz_ = FieldIndex("normal_z");
    label_ = FieldIndex("label");
    if (label_ >= 0 && fields_[static_cast<std::size_t>(label_)].type == 'F')
      label_ = -1;  // not a segmentation
    data_start_ = lines_.position();
  }

  // A large POINTS count the bytes after the header cannot hold is refused before anything is allocated
  // (docs/reliability.md): ASCII values take at least two bytes each (a digit and a separator), binary
  // records record_size_ bytes, and LZF expands at most 88-fold (a 3-byte back reference copies at most 264
  // bytes). Counts up to 2^20 are read and fail where the data end, which names the place more precisely.
  void RefuseCountBeyondSize() const {
    if (points_ <= (std::size_t{1} << 20)) return;
    const std::size_t left = bytes_.size() - data_start_;
    std::size_t columns = 0;
    for (const Field& f : fields_) columns += f.count;
    const double min_bytes_per_point = data_ == "ascii"    ? 2.0 * static_cast<double>(columns)
                                       : data_ == "binary" ? static_cast<double>(record_size_)
                                                           : static_cast<double>(record_size_) / 88.0;
    if (static_cast<double>(points_) * min_bytes_per_point > static_cast<double>(left)) {
      Fail(AtByte(data_start_), "truncated: POINTS is " + std::to_string(points_) + " but only " +
                                    std::to_string(left) + " bytes of " + data_ + " data follow");
    }
  }

  // Column (scalar) index of the first element of field f in an ascii line.
  std::size_t Column(int f) const {
    std::size_t c = 0;
    for (int i = 0; i < f; ++i) c += fields_[static_cast<std::size_t>(i)].count;
    return c;
  }

  void ReadAscii() {
    std::size_t columns = 0;
    for (const Field& f : fields_) columns += f.count;
    const std::size_t cx = Column(x_), cy = Column(y_), cz = Column(z_);
    std::vector<std::string_view> tok;
    Line line;
    for (std::size_t i = 0; i < points_; ++i) {
      do {
        if (!lines_.Next(line))
          Fail(AtLine(lines_.line_number() + 1), "truncated: POINTS is " + std::to_string(points_) +
                                                     ", the data ends after " + std::to_string(i));
        Tokenize(line.text, tok);
      } while (tok.empty());
      const std::string where = AtLine(line.number);
      if (tok.size() != columns)
        Fail(where, "expected " + std::to_string(columns) + " values, found " + std::to_string(tok.size()));
      auto number = [&](std::size_t c) {
        double v;
        if (!ParseDouble(tok[c], v)) Fail(where, "not a number: " + Quoted(tok[c]));
        return v;
      };
      const auto col = static_cast<Eigen::Index>(i);
      // Every value parsed before the column is written (a braced list evaluates left to right): a format
      // error thrown inside an Eigen comma initializer leaves it half-filled, which Eigen's assertions abort
      // on.
      raw_.col(col) = Eigen::Vector3d{number(cx), number(cy), number(cz)};
      if (HasNormals())
        raw_normals_.col(col) =
            Eigen::Vector3d{number(Column(nx_)), number(Column(ny_)), number(Column(nz_))};
      if (label_ >= 0) raw_labels_[i] = Label(number(Column(label_)), i, where);
    }
  }

  void ReadBinary() {
    const std::size_t left = bytes_.size() - data_start_;
    if (points_ > left / record_size_) {
      Fail(AtByte(data_start_), "truncated: POINTS is " + std::to_string(points_) + " (" +
                                    std::to_string(record_size_) + " bytes each) but only " +
                                    std::to_string(left) + " bytes follow");
    }
    for (std::size_t i = 0; i < points_; ++i) {
      const char* record = bytes_.data() + data_start_ + i * record_size_;
      auto value = [&](int f) {
        const Field& field = fields_[static_cast<std::size_t>(f)];
        return LoadAsDouble(record + field.offset, field.scalar, true);
      };
      const auto col = static_cast<Eigen::Index>(i);
      raw_.col(col) = Eigen::Vector3d{value(x_), value(y_), value(z_)};
      if (HasNormals()) raw_normals_.col(col) = Eigen::Vector3d{value(nx_), value(ny_), value(nz_)};
      if (label_ >= 0) raw_labels_[i] = Label(value(label_), i, AtByte(data_start_ + i * record_size_));
    }
  }

  void ReadCompressed() {
    if (bytes_.size() - data_start_ < 8)
      Fail(AtByte(data_start_), "truncated: missing the compressed-size words");
    const auto compressed = LoadScalar<std::uint32_t>(bytes_.data() + data_start_, true);
    const auto uncompressed = LoadScalar<std::uint32_t>(bytes_.data() + data_start_ + 4, true);
    const std::size_t start = data_start_ + 8;
    if (compressed > bytes_.size() - start) {
      Fail(AtByte(start), "truncated: " + std::to_string(compressed) + " compressed bytes declared, " +
                              std::to_string(bytes_.size() - start) + " present");
    }
    if (uncompressed != points_ * record_size_) {
      Fail(AtByte(data_start_ + 4), "uncompressed size " + std::to_string(uncompressed) +
                                        " does not match POINTS x record size " +
                                        std::to_string(points_ * record_size_));
    }
    std::vector<unsigned char> plain(uncompressed);
    if (!LzfDecompress(reinterpret_cast<const unsigned char*>(bytes_.data() + start), compressed,
                       plain.data(), plain.size())) {
      Fail(AtByte(start), "corrupt LZF data");
    }
    // Field-major layout: all values of field 0, then all of field 1, ...
    std::vector<std::size_t> field_start(fields_.size());
    std::size_t offset = 0;
    for (std::size_t f = 0; f < fields_.size(); ++f) {
      field_start[f] = offset;
      offset += fields_[f].size * fields_[f].count * points_;
    }
    for (std::size_t i = 0; i < points_; ++i) {
      auto value = [&](int f) {
        const Field& field = fields_[static_cast<std::size_t>(f)];
        const char* p = reinterpret_cast<const char*>(plain.data()) +
                        field_start[static_cast<std::size_t>(f)] + i * field.size * field.count;
        return LoadAsDouble(p, field.scalar, true);
      };
      const auto col = static_cast<Eigen::Index>(i);
      raw_.col(col) = Eigen::Vector3d{value(x_), value(y_), value(z_)};
      if (HasNormals()) raw_normals_.col(col) = Eigen::Vector3d{value(nx_), value(ny_), value(nz_)};
      if (label_ >= 0) raw_labels_[i] = Label(value(label_), i, "compressed data");
    }
  }

  Scan Finish() {
    Scan scan;
    std::vector<Eigen::Index> keep;
    keep.reserve(points_);
    for (Eigen::Index i = 0; i < raw_.cols(); ++i) {
      if (raw_.col(i).allFinite()) keep.push_back(i);
    }
    if (keep.empty())
      Fail("", "no valid point: all " + std::to_string(points_) + " points have NaN or infinite coordinates");
    const std::size_t dropped = points_ - keep.size();
    scan.points.resize(3, static_cast<Eigen::Index>(keep.size()));
    for (std::size_t k = 0; k < keep.size(); ++k)
      scan.points.col(static_cast<Eigen::Index>(k)) = raw_.col(keep[k]);
    if (HasNormals()) {
      bool finite = true;
      scan.normals.resize(3, scan.points.cols());
      for (std::size_t k = 0; k < keep.size(); ++k) {
        scan.normals.col(static_cast<Eigen::Index>(k)) = raw_normals_.col(keep[k]);
        finite = finite && raw_normals_.col(keep[k]).allFinite();
      }
      if (!finite) {
        scan.normals.resize(3, 0);
        scan.metadata.notes.push_back("normals dropped: some valid points have NaN normals");
      }
    }
    if (label_ >= 0) {
      scan.labels.resize(keep.size());
      for (std::size_t k = 0; k < keep.size(); ++k)
        scan.labels[k] = raw_labels_[static_cast<std::size_t>(keep[k])];
    }
    if (dropped > 0) {
      scan.metadata.notes.push_back("dropped " + std::to_string(dropped) + " of " + std::to_string(points_) +
                                    " points with NaN coordinates (PCD's invalid-point marker" +
                                    std::string(organized_ ? ", organized cloud" : "") + ")");
    }
    scan.world_T_scan = viewpoint_;
    // An organized cloud is a depth camera's pixel grid: its kind chooses the fit's default loss
    // (pipeline/fit_option_table.h, ClassifyInput).
    scan.metadata.device = organized_ ? "file:organized" : "file";
    scan.metadata.source = file_;
    return scan;
  }

  const std::string& bytes_;
  const std::string& file_;
  LineReader lines_{bytes_};
  std::vector<Field> fields_;
  std::size_t points_ = 0, record_size_ = 0, data_start_ = 0;
  std::string data_;
  bool organized_ = false;
  int x_ = -1, y_ = -1, z_ = -1, nx_ = -1, ny_ = -1, nz_ = -1, label_ = -1;
  std::vector<std::int64_t> raw_labels_;
  RigidMotion viewpoint_;
  Eigen::Matrix3Xd raw_, raw_normals_;
};

}  // namespace

Scan ParsePcd(const std::string& bytes, const std::string& file) {
  return PcdParser(bytes, file).Parse();
}

}  // namespace s2m::formats
