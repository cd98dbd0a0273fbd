#pragma once
// E57 (ASTM E2807) point-cloud files: reading every data3D scan with its pose, and writing cartesian point
// sets with poses (docs/e57.md). An E57 file is a multi-view set: each scan's pose becomes its world_T_scan,
// exactly like a scan2model.views/1 manifest. Coordinates are metres, as the standard prescribes.
//
// Reading: cartesian or spherical coordinates, intensity, colour, row/column indices and the invalid-state
// fields, coded as Float (single, double), Integer or ScaledInteger by the bit-pack codec, in data, index and
// empty packets, every 1024-byte page's CRC-32C checked. Records whose cartesianInvalidState (or, for
// spherical data, sphericalInvalidState) is not 0 carry no usable position and are dropped; the scan's notes
// say how many. Every error is a FormatError naming the file, the byte offset and the problem.

#include <Eigen/Core>
#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include "registration/scan.h"

namespace s2m {

inline constexpr const char* kE57Extension = ".e57";

// One data3D entry.
struct E57Scan {
  std::string guid, name, description;
  // Points in the scan's own frame (metres), world_T_scan from the pose (identity when the file has none),
  // units "m", metadata.source "<file> data3D/<k> '<name>'", metadata.device "file:organized" when rows and
  // columns are given (a scanner's grid), else "file".
  Scan scan;
  Eigen::VectorXd intensity;  // empty, or one value per point as stored (NaN where isIntensityInvalid is 1)
  Eigen::Matrix3Xd colour;  // empty, or red, green, blue per point as stored (NaN where isColorInvalid is 1)
  std::vector<std::int64_t> row_index, column_index;  // empty, or one per point

  // How the file held it (for `info`).
  std::string coordinates;          // "cartesian" or "spherical"
  std::uint64_t records = 0;        // records in the file, invalid ones included
  std::uint64_t invalid = 0;        // records dropped for their invalid state
  std::vector<std::string> fields;  // one line per prototype field, e.g. "cartesianX: ScaledInteger, 19 bits"
};

struct E57Data {
  std::string guid;
  std::string library_version;  // e57LibraryVersion, or empty
  std::vector<E57Scan> scans;
  std::size_t images = 0;  // images2D entries (not read)
};

// True for a name ending in .e57 (any case).
bool IsE57File(const std::filesystem::path& path);

E57Data ReadE57(const std::filesystem::path& path);
// The scans as views: each with its pose, in file order; scans without a valid point are left out (a note on
// the first view says so). Throws FormatError when no scan has a point.
ScanSet ToScanSet(const E57Data& data, const std::filesystem::path& path);
ScanSet ReadE57ScanSet(const std::filesystem::path& path);
// All scans as one cloud in the file's world frame, each placed by its pose (a single scan too, so the
// cloud's frame does not depend on how many scans the file holds); world_T_scan is the identity.
Scan ToOneCloud(const E57Data& data, const std::filesystem::path& path);

enum class E57CoordinateEncoding { kFloat64, kFloat32, kScaledInteger };
enum class E57IntensityEncoding { kFloat32, kFloat64, kScaledInteger };

struct E57WriteOptions {
  // kFloat64 keeps every coordinate exactly; kFloat32 rounds to 24 significant bits; kScaledInteger stores
  // round(x / coordinate_scale) in as few bits as the scan's range needs (error at most coordinate_scale /
  // 2).
  E57CoordinateEncoding coordinates = E57CoordinateEncoding::kFloat64;
  double coordinate_scale = 1e-5;  // metres per integer step (kScaledInteger): 10 micrometres
  E57IntensityEncoding intensity = E57IntensityEncoding::kFloat32;
  double intensity_scale = 1e-3;  // per integer step (kScaledInteger)
  // Records per data packet at most (0: as many as fit in a packet's 64 KiB); small values make many packets.
  std::uint64_t max_records_per_packet = 0;

  bool IsValid() const;
};

// Writes the scans as data3D entries: cartesianX/Y/Z (in metres: scan.units is converted, and must be a
// length unit: m, cm, mm or um), the pose from world_T_scan, intensity when given (one per point; NaN is
// written as isIntensityInvalid 1). A point with a non-finite coordinate is written with
// cartesianInvalidState 2. The file appears atomically (written beside it, then renamed). Throws FormatError
// naming the file and the problem (an empty scan, unknown units, a coordinate beyond the scaled-integer
// range), std::invalid_argument for options that are not IsValid.
void WriteE57(const std::filesystem::path& path, const std::vector<E57Scan>& scans,
              const E57WriteOptions& options = {});
// The views of a set, each with its pose (no intensity).
void WriteE57(const std::filesystem::path& path, const ScanSet& set, const E57WriteOptions& options = {});

}  // namespace s2m
