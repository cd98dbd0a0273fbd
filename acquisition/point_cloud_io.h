#pragma once
// Reading and writing single-view point sets. Formats: PLY (ASCII and binary, optionally gzipped), PCD
// (ascii, binary, binary_compressed), plain text (XYZ/CSV), the NIST .ds format and E57 (read as one cloud:
// every scan placed in the file's world by its pose; acquisition/e57_io.h reads the scans as views). Every
// reader throws FormatError naming the file, the line or byte offset and the problem for corrupt, truncated,
// NaN-laden or empty input.

#include <filesystem>
#include <string>

#include "registration/scan.h"

namespace s2m {

// kDepthFrame: a 16-bit depth image (.tiff/.tif) with its intrinsics file beside it
// (acquisition/depth_frame.h), back-projected to one organized cloud in metres.
enum class PointCloudFormat { kPly, kPcd, kText, kNistDs, kE57, kDepthFrame };
const char* ToString(PointCloudFormat format);

// From the file name: .ply, .ply.gz, .pcd, .xyz/.txt/.csv/.pts, .ds, .e57, .tiff/.tif (a depth frame). Throws
// FormatError for anything else.
PointCloudFormat DetectFormat(const std::filesystem::path& path);

Scan ReadPointCloud(const std::filesystem::path& path);
Scan ReadPointCloud(const std::filesystem::path& path, PointCloudFormat format);

enum class PlyEncoding { kBinaryLittleEndian, kAscii };

// Writes x y z (double), normals and weights when present, units and world_T_scan as comments. The file
// appears atomically (written beside it, then renamed), so a crash never leaves a half-written PLY under the
// final name.
void WritePly(const std::filesystem::path& path, const Scan& scan,
              PlyEncoding encoding = PlyEncoding::kBinaryLittleEndian);

}  // namespace s2m
