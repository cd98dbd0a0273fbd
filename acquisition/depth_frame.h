#pragma once
// Depth frames from a structured-light sensor (Kinect/OpenNI, as saved by PCL's OpenNI grabber tools): a
// 16-bit single-channel TIFF of raw depth values plus an XML file of pinhole intrinsics, back-projected to a
// point cloud in the camera frame (x right, y down, z forward along the optical axis), in metres.
//
// The TIFF reader is our own and deliberately small: baseline greyscale, 16 bits per sample, one sample per
// pixel, strips, uncompressed or PackBits (what the grabber writes). Anything else -- tiles, LZW/Deflate,
// colour, 8 or 32 bits, floating-point samples, a predictor -- is rejected with a FormatError naming the
// file, rather than decoded wrongly. Keeping it ours avoids a libtiff dependency in the library; the tests
// decode the same files with libtiff as an independent check.

#include <Eigen/Core>
#include <cstdint>
#include <filesystem>
#include <vector>

#include "registration/scan.h"

namespace s2m {

// Raw sensor values, row-major (v rows of u columns); 0 means "no return".
struct DepthImage {
  int width = 0, height = 0;
  std::vector<std::uint16_t> values;

  std::uint16_t at(int u, int v) const { return values[static_cast<std::size_t>(v) * width + u]; }
};

// Throws FormatError naming the file (and a byte offset where one applies) for anything unsupported,
// inconsistent or truncated.
DepthImage ReadDepthTiff(const std::filesystem::path& path);

struct DepthIntrinsics {
  double fx = 0, fy = 0;  // focal lengths, pixels
  double cx = 0, cy = 0;  // principal point, pixels (column, row; pixel centres at integer coordinates)
  // Metres per raw depth unit. OpenNI writes depth in millimetres, so 0.001 when the file does not say
  // (z_multiplication_factor is optional in the grabber's XML); depth_scale_from_file tells which.
  double depth_scale = 0.001;
  bool depth_scale_from_file = false;
};

// The <depth> section of the grabber's XML: focal_length_x/_y, principal_point_x/_y (required) and
// z_multiplication_factor (optional). The file has two top-level elements (<rgb> and <depth>, no root), so it
// is scanned for tags rather than parsed as a document. Throws FormatError naming the file and the missing or
// malformed tag; focal lengths and the depth scale must be positive and finite.
DepthIntrinsics ReadDepthIntrinsicsXml(const std::filesystem::path& path);

// The grabber's naming: frame_<time>_depth.tiff beside frame_<time>.xml. Throws FormatError when the name
// does not end in _depth.tif/_depth.tiff.
std::filesystem::path DepthIntrinsicsPathFor(const std::filesystem::path& depth_tiff);

struct DepthCloud {
  Eigen::Matrix3Xd points;     // metres, camera frame, pixels in row-major order
  Eigen::Index no_return = 0;  // zero-depth pixels, dropped
};

// Pinhole back-projection: z = raw * depth_scale, x = (u - cx) z / fx, y = (v - cy) z / fy. Throws
// std::invalid_argument for non-positive or non-finite intrinsics or an image whose value count does not
// match its size.
DepthCloud BackProject(const DepthImage& image, const DepthIntrinsics& intrinsics);

// ReadDepthTiff + ReadDepthIntrinsicsXml(DepthIntrinsicsPathFor(tiff)) + BackProject, as a Scan in metres
// whose metadata names the source and notes how many pixels had no return.
Scan ReadDepthFrame(const std::filesystem::path& depth_tiff);

}  // namespace s2m
