#include "acquisition/point_cloud_io.h"

#include <array>
#include <bit>
#include <cctype>
#include <cstdio>
#include <fstream>
#include <sstream>
#include <vector>

#include "acquisition/depth_frame.h"
#include "acquisition/e57_io.h"
#include "acquisition/format_error.h"
#include "acquisition/formats/readers.h"
#include "fitting/enum_names.h"

namespace s2m {
namespace {

std::string LowerExtension(const std::filesystem::path& path) {
  std::string name = path.filename().string();
  for (char& c : name) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  if (name.size() > 3 && name.ends_with(".gz")) {
    const std::string inner = std::filesystem::path(name.substr(0, name.size() - 3)).extension().string();
    return inner + ".gz";
  }
  return std::filesystem::path(name).extension().string();
}

}  // namespace

const char* ToString(PointCloudFormat format) {
  static constexpr std::array<EnumName<PointCloudFormat>, 6> kFormatNames = {{
      {PointCloudFormat::kPly, "ply"},
      {PointCloudFormat::kPcd, "pcd"},
      {PointCloudFormat::kText, "text"},
      {PointCloudFormat::kNistDs, "nist-ds"},
      {PointCloudFormat::kE57, "e57"},
      {PointCloudFormat::kDepthFrame, "depth-frame"},
  }};
  return NameOf(kFormatNames, format);
}

PointCloudFormat DetectFormat(const std::filesystem::path& path) {
  const std::string ext = LowerExtension(path);
  if (ext == ".ply" || ext == ".ply.gz") return PointCloudFormat::kPly;
  if (ext == ".pcd") return PointCloudFormat::kPcd;
  if (ext == ".xyz" || ext == ".txt" || ext == ".csv" || ext == ".pts" || ext == ".xyz.gz" ||
      ext == ".csv.gz") {
    return PointCloudFormat::kText;
  }
  if (ext == ".ds") return PointCloudFormat::kNistDs;
  if (ext == kE57Extension) return PointCloudFormat::kE57;
  if (ext == ".tiff" || ext == ".tif") return PointCloudFormat::kDepthFrame;
  throw FormatError(path.string(), "",
                    "unknown point-cloud format '" + ext +
                        "' (supported: .ply, .ply.gz, .pcd, .xyz, .txt, .csv, .pts, .ds, .e57, and a depth "
                        "frame .tiff with its intrinsics .xml)");
}

Scan ReadPointCloud(const std::filesystem::path& path) {
  return ReadPointCloud(path, DetectFormat(path));
}

Scan ReadPointCloud(const std::filesystem::path& path, PointCloudFormat format) {
  const std::string file = path.string();
  std::error_code ec;
  if (std::filesystem::is_directory(path, ec))
    throw FormatError(file, "", "is a directory, not a point-cloud file");
  if (format == PointCloudFormat::kE57) return ToOneCloud(ReadE57(path), path);
  if (format == PointCloudFormat::kDepthFrame) return ReadDepthFrame(path);
  const std::string bytes = formats::ReadFileBytes(file);
  if (bytes.empty()) throw FormatError(file, "", "empty file");
  switch (format) {
    case PointCloudFormat::kPly:
      return formats::ParsePly(bytes, file);
    case PointCloudFormat::kPcd:
      return formats::ParsePcd(bytes, file);
    case PointCloudFormat::kText:
      return formats::ParseTextPoints(bytes, file);
    case PointCloudFormat::kNistDs:
      return formats::ParseNistDs(bytes, file);
    case PointCloudFormat::kE57:
    case PointCloudFormat::kDepthFrame:
      break;
  }
  throw FormatError(file, "", "unknown format");
}

void WritePly(const std::filesystem::path& path, const Scan& scan, PlyEncoding encoding) {
  const std::string file = path.string();
  if (scan.empty()) throw FormatError(file, "", "refusing to write an empty point set");
  const bool normals = scan.has_normals();
  const bool weights = scan.has_weights();
  std::ostringstream header;
  header << "ply\nformat " << (encoding == PlyEncoding::kAscii ? "ascii" : "binary_little_endian")
         << " 1.0\n";
  header << "comment written by scan2model\n";
  header << "comment units " << scan.units << "\n";
  header.precision(17);
  header << "comment world_T_scan";
  const Eigen::Matrix4d m = scan.world_T_scan.matrix();
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 4; ++c) header << ' ' << m(r, c);
  header << "\nelement vertex " << scan.size()
         << "\nproperty double x\nproperty double y\nproperty double z\n";
  if (normals) header << "property double nx\nproperty double ny\nproperty double nz\n";
  if (weights) header << "property double weight\n";
  header << "end_header\n";

  const std::filesystem::path tmp = path.string() + ".partial";
  {
    std::ofstream out(tmp, std::ios::binary | std::ios::trunc);
    if (!out) throw FormatError(file, "", "cannot create " + tmp.string());
    out << header.str();
    std::vector<double> record;
    for (Eigen::Index i = 0; i < scan.size(); ++i) {
      record.assign(scan.points.col(i).data(), scan.points.col(i).data() + 3);
      if (normals) record.insert(record.end(), scan.normals.col(i).data(), scan.normals.col(i).data() + 3);
      if (weights) record.push_back(scan.weights[i]);
      if (encoding == PlyEncoding::kAscii) {
        out.precision(17);
        for (std::size_t k = 0; k < record.size(); ++k) out << (k ? " " : "") << record[k];
        out << '\n';
      } else {
        static_assert(std::endian::native == std::endian::little,
                      "binary PLY writer assumes a little-endian host");
        out.write(reinterpret_cast<const char*>(record.data()),
                  static_cast<std::streamsize>(record.size() * sizeof(double)));
      }
    }
    out.flush();
    if (!out) throw FormatError(file, "", "write failed (disk full?)");
  }
  std::error_code ec;
  std::filesystem::rename(tmp, path, ec);
  if (ec) throw FormatError(file, "", "cannot move the finished file into place: " + ec.message());
}

}  // namespace s2m
