// Depth frames: our small TIFF reader and back-projection checked against libtiff (a different decoder of the
// same files) and a separate back-projection with the intrinsics the data's README states, on PCL's three
// real Kinect frames; files written by libtiff in other layouts (uncompressed, several PackBits strips); and
// bad input.

#include "acquisition/depth_frame.h"

#include <gtest/gtest.h>
#include <tiffio.h>

#include <algorithm>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <random>
#include <string>
#include <vector>

#include "acquisition/format_error.h"
#include "test_paths.h"

namespace s2m {
namespace {

namespace fs = std::filesystem;

const char* const kFrames[] = {"frame_20121214T142255.814212", "frame_20121214T142256.068683",
                               "frame_20121214T142256.332395"};

fs::path FramePath(const std::string& frame, const std::string& suffix) {
  return test::SharedData("pcl_kinect_frames/" + frame + suffix);
}

// libtiff's decoding, row by row (it handles PackBits and byte order itself).
DepthImage ReadWithLibtiff(const fs::path& path) {
  TIFF* tif = TIFFOpen(path.c_str(), "r");
  if (tif == nullptr) throw std::runtime_error("libtiff cannot open " + path.string());
  std::uint32_t w = 0, h = 0;
  std::uint16_t bits = 0;
  TIFFGetField(tif, TIFFTAG_IMAGEWIDTH, &w);
  TIFFGetField(tif, TIFFTAG_IMAGELENGTH, &h);
  TIFFGetField(tif, TIFFTAG_BITSPERSAMPLE, &bits);
  DepthImage image;
  image.width = static_cast<int>(w);
  image.height = static_cast<int>(h);
  image.values.resize(static_cast<std::size_t>(w) * h);
  EXPECT_EQ(bits, 16);
  for (std::uint32_t row = 0; row < h; ++row)
    if (TIFFReadScanline(tif, image.values.data() + static_cast<std::size_t>(row) * w, row) < 0)
      throw std::runtime_error("libtiff cannot read row " + std::to_string(row));
  TIFFClose(tif);
  return image;
}

void WriteWithLibtiff(const fs::path& path, int width, int height, int bits, std::uint16_t compression,
                      std::uint32_t rows_per_strip, const std::vector<std::uint16_t>& values) {
  TIFF* tif = TIFFOpen(path.c_str(), "w");
  ASSERT_NE(tif, nullptr);
  TIFFSetField(tif, TIFFTAG_IMAGEWIDTH, static_cast<std::uint32_t>(width));
  TIFFSetField(tif, TIFFTAG_IMAGELENGTH, static_cast<std::uint32_t>(height));
  TIFFSetField(tif, TIFFTAG_BITSPERSAMPLE, static_cast<std::uint16_t>(bits));
  TIFFSetField(tif, TIFFTAG_SAMPLESPERPIXEL, static_cast<std::uint16_t>(1));
  TIFFSetField(tif, TIFFTAG_PHOTOMETRIC, PHOTOMETRIC_MINISBLACK);
  TIFFSetField(tif, TIFFTAG_PLANARCONFIG, PLANARCONFIG_CONTIG);
  TIFFSetField(tif, TIFFTAG_COMPRESSION, compression);
  TIFFSetField(tif, TIFFTAG_ROWSPERSTRIP, rows_per_strip);
  std::vector<std::uint8_t> row8(static_cast<std::size_t>(width));
  for (int v = 0; v < height; ++v) {
    const std::uint16_t* row = values.data() + static_cast<std::size_t>(v) * width;
    if (bits == 16) {
      ASSERT_GE(TIFFWriteScanline(tif, const_cast<std::uint16_t*>(row), static_cast<std::uint32_t>(v)), 0);
    } else {
      std::transform(row, row + width, row8.begin(),
                     [](std::uint16_t x) { return static_cast<std::uint8_t>(x); });
      ASSERT_GE(TIFFWriteScanline(tif, row8.data(), static_cast<std::uint32_t>(v)), 0);
    }
  }
  TIFFClose(tif);
}

class DepthFrameFiles : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() /
           ("s2m_depth_frame_test_" +
            std::string(::testing::UnitTest::GetInstance()->current_test_info()->name()));
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }
  fs::path dir_;
};

// Independent statistics: the README's intrinsics (fx = fy = 525, cx = 320, cy = 240, millimetres), not our
// XML parser's, applied to libtiff's decoding.
struct Stats {
  long valid = 0;
  double mean_z = 0, min_z = 1e300, max_z = -1e300;
  Eigen::Vector3d centroid = Eigen::Vector3d::Zero();
};
Stats Independent(const DepthImage& image) {
  Stats s;
  for (int v = 0; v < image.height; ++v) {
    for (int u = 0; u < image.width; ++u) {
      const double z = image.values[static_cast<std::size_t>(v) * image.width + u] / 1000.0;
      if (z == 0) continue;
      ++s.valid;
      s.centroid += Eigen::Vector3d((u - 320.0) * z / 525.0, (v - 240.0) * z / 525.0, z);
      s.min_z = std::min(s.min_z, z);
      s.max_z = std::max(s.max_z, z);
    }
  }
  s.centroid /= static_cast<double>(s.valid);
  s.mean_z = s.centroid.z();
  return s;
}

TEST(DepthFrame, KinectFramesMatchLibtiffAndAnIndependentBackProjection) {
  if (!test::HaveSharedData()) GTEST_SKIP() << "../shared/data is absent";
  for (const char* frame : kFrames) {
    SCOPED_TRACE(frame);
    const fs::path tiff = FramePath(frame, "_depth.tiff");
    const DepthImage ours = ReadDepthTiff(tiff);
    const DepthImage theirs = ReadWithLibtiff(tiff);
    ASSERT_EQ(ours.width, 640);
    ASSERT_EQ(ours.height, 480);
    ASSERT_EQ(theirs.width, 640);
    ASSERT_EQ(theirs.height, 480);
    EXPECT_TRUE(ours.values == theirs.values) << "pixel values differ from libtiff's decoding";

    const DepthIntrinsics k = ReadDepthIntrinsicsXml(DepthIntrinsicsPathFor(tiff));
    EXPECT_EQ(k.fx, 525.0);
    EXPECT_EQ(k.fy, 525.0);
    EXPECT_EQ(k.cx, 320.0);
    EXPECT_EQ(k.cy, 240.0);
    EXPECT_EQ(k.depth_scale, 0.001);
    EXPECT_TRUE(k.depth_scale_from_file);

    const Scan scan = ReadDepthFrame(tiff);
    const Stats ref = Independent(theirs);
    EXPECT_EQ(scan.units, "m");
    ASSERT_EQ(scan.size(), ref.valid);
    // A real frame: most pixels return, a few hundred thousand points.
    EXPECT_GT(ref.valid, 640 * 480 / 2);
    const Eigen::Vector3d centroid = scan.points.rowwise().mean();
    EXPECT_NEAR((centroid - ref.centroid).norm(), 0.0, 1e-9);
    EXPECT_NEAR(scan.points.row(2).mean(), ref.mean_z, 1e-9);
    EXPECT_DOUBLE_EQ(scan.points.row(2).minCoeff(), ref.min_z);
    EXPECT_DOUBLE_EQ(scan.points.row(2).maxCoeff(), ref.max_z);
    // Kinect v1's working range is about 0.5 to 8 m.
    EXPECT_GT(ref.min_z, 0.3);
    EXPECT_LT(ref.max_z, 10.0);
    ASSERT_EQ(scan.metadata.notes.size(), 2u);
    EXPECT_NE(scan.metadata.notes[0].find(std::to_string(640 * 480 - ref.valid) + " of 307200"),
              std::string::npos);
    std::printf("%s: %ld valid of 307200, z mean %.6f min %.3f max %.3f m, centroid (%.6f, %.6f, %.6f)\n",
                frame, ref.valid, ref.mean_z, ref.min_z, ref.max_z, ref.centroid.x(), ref.centroid.y(),
                ref.centroid.z());
  }
}

TEST_F(DepthFrameFiles, LayoutsWrittenByLibtiffReadBack) {
  std::mt19937 rng(7);
  std::uniform_int_distribution<int> depth(0, 9000);
  const int w = 37, h = 23;
  std::vector<std::uint16_t> values(static_cast<std::size_t>(w) * h);
  // Runs of equal values as well as noise, so PackBits uses both its literal and its repeat runs.
  for (std::size_t i = 0; i < values.size(); ++i)
    values[i] = static_cast<std::uint16_t>(i % 5 == 0 ? depth(rng) : (i / 11) * 3);
  struct Layout {
    std::uint16_t compression;
    std::uint32_t rows_per_strip;
  };
  for (const Layout layout : {Layout{COMPRESSION_NONE, 23}, Layout{COMPRESSION_NONE, 4},
                              Layout{COMPRESSION_PACKBITS, 1}, Layout{COMPRESSION_PACKBITS, 7}}) {
    SCOPED_TRACE(std::to_string(layout.compression) + " / " + std::to_string(layout.rows_per_strip));
    const fs::path path = dir_ / "layout.tiff";
    WriteWithLibtiff(path, w, h, 16, layout.compression, layout.rows_per_strip, values);
    const DepthImage image = ReadDepthTiff(path);
    EXPECT_EQ(image.width, w);
    EXPECT_EQ(image.height, h);
    EXPECT_TRUE(image.values == values);
  }
}

TEST(DepthFrame, BackProjectionIsThePinholeModel) {
  DepthImage image;
  image.width = 3;
  image.height = 2;
  image.values = {0, 1000, 0, 2000, 0, 500};
  const DepthIntrinsics k{100, 200, 1, 0.5, 0.001, true};
  const DepthCloud cloud = BackProject(image, k);
  ASSERT_EQ(cloud.points.cols(), 3);
  EXPECT_EQ(cloud.no_return, 3);
  EXPECT_TRUE(cloud.points.col(0).isApprox(Eigen::Vector3d(0, -0.5 * 1.0 / 200, 1.0)));
  EXPECT_TRUE(cloud.points.col(1).isApprox(Eigen::Vector3d(-1 * 2.0 / 100, 0.5 * 2.0 / 200, 2.0)));
  EXPECT_TRUE(cloud.points.col(2).isApprox(Eigen::Vector3d(1 * 0.5 / 100, 0.5 * 0.5 / 200, 0.5)));
  EXPECT_THROW(BackProject(image, DepthIntrinsics{0, 200, 1, 0.5, 0.001, true}), std::invalid_argument);
  image.values.pop_back();
  EXPECT_THROW(BackProject(image, k), std::invalid_argument);
}

// The FormatError's message for reading `path`, or "" when it read.
std::string TiffError(const fs::path& path) {
  try {
    ReadDepthTiff(path);
  } catch (const FormatError& e) {
    EXPECT_EQ(e.file(), path.string());
    return e.what();
  }
  return "";
}

TEST_F(DepthFrameFiles, TruncatedAndUnsupportedTiffsAreClearErrors) {
  const int w = 16, h = 8;
  std::vector<std::uint16_t> values(static_cast<std::size_t>(w) * h);
  for (std::size_t i = 0; i < values.size(); ++i) values[i] = static_cast<std::uint16_t>(700 + i % 3);

  const fs::path packbits = dir_ / "packbits.tiff";
  WriteWithLibtiff(packbits, w, h, 16, COMPRESSION_PACKBITS, 8, values);
  const fs::path plain = dir_ / "plain.tiff";
  WriteWithLibtiff(plain, w, h, 16, COMPRESSION_NONE, 8, values);
  // libtiff writes the directory after the strip data; cutting into the data leaves a directory that points
  // past the end, cutting the directory leaves it incomplete. Both must be caught, never read as zeros.
  for (const fs::path& source : {packbits, plain}) {
    std::ifstream in(source, std::ios::binary);
    const std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    for (const std::size_t keep : {std::size_t{4}, std::size_t{20}, bytes.size() / 2, bytes.size() - 10}) {
      SCOPED_TRACE(source.filename().string() + " cut to " + std::to_string(keep));
      const fs::path cut = dir_ / "cut.tiff";
      std::ofstream(cut, std::ios::binary).write(bytes.data(), static_cast<std::streamsize>(keep));
      const std::string message = TiffError(cut);
      EXPECT_NE(message.find("cut.tiff"), std::string::npos) << message;
      EXPECT_TRUE(message.find("truncated") != std::string::npos ||
                  message.find("too short") != std::string::npos)
          << message;
    }
  }

  const fs::path eight = dir_ / "eight_bit.tiff";
  WriteWithLibtiff(eight, w, h, 8, COMPRESSION_NONE, 8, values);
  EXPECT_NE(TiffError(eight).find("8 bits per sample: only 16-bit"), std::string::npos) << TiffError(eight);

  const fs::path lzw = dir_ / "lzw.tiff";
  WriteWithLibtiff(lzw, w, h, 16, COMPRESSION_LZW, 8, values);
  EXPECT_NE(TiffError(lzw).find("compression 5 is not supported"), std::string::npos) << TiffError(lzw);

  const fs::path text = dir_ / "not_a.tiff";
  std::ofstream(text) << "P2 16 8 65535\n";
  EXPECT_NE(TiffError(text).find("not a TIFF file"), std::string::npos) << TiffError(text);
  EXPECT_NE(TiffError(dir_ / "absent.tiff").find("cannot open"), std::string::npos);
}

// The FormatError's message for reading `xml`, or "" when it read.
std::string XmlError(const fs::path& path, const std::string& content) {
  std::ofstream(path) << content;
  try {
    ReadDepthIntrinsicsXml(path);
  } catch (const FormatError& e) {
    return e.what();
  }
  return "";
}

TEST_F(DepthFrameFiles, MissingOrMalformedIntrinsicsAreClearErrors) {
  const fs::path xml = dir_ / "frame.xml";
  const std::string rgb =
      "<rgb><focal_length_x>1</focal_length_x><principal_point_y>2</principal_point_y></rgb>\n";
  const std::string good =
      "<focal_length_x>525</focal_length_x>\n<focal_length_y> 525 </focal_length_y>\n"
      "<principal_point_x>319.5</principal_point_x>\n";
  std::string message = XmlError(xml, rgb + "<depth>\n" + good + "</depth>\n");
  EXPECT_NE(message.find("frame.xml"), std::string::npos) << message;
  EXPECT_NE(message.find("missing <principal_point_y> in <depth>"), std::string::npos) << message;

  message = XmlError(xml, rgb);
  EXPECT_NE(message.find("no <depth> element"), std::string::npos) << message;

  message = XmlError(xml, "<depth>\n" + good + "<principal_point_y>24O</principal_point_y>\n</depth>\n");
  EXPECT_NE(message.find("line 5"), std::string::npos) << message;
  EXPECT_NE(message.find("<principal_point_y> is not a finite number: '24O'"), std::string::npos) << message;

  message = XmlError(xml, "<depth>\n" + good + "<principal_point_y>240</principal_point_y>\n");
  EXPECT_NE(message.find("<depth> element is not closed"), std::string::npos) << message;

  // The <rgb> camera's values must not leak in, and a missing depth scale is the documented millimetre
  // default.
  std::ofstream(xml) << rgb << "<depth>\n"
                     << good << "<principal_point_y>240</principal_point_y>\n</depth>\n";
  const DepthIntrinsics k = ReadDepthIntrinsicsXml(xml);
  EXPECT_EQ(k.fx, 525.0);
  EXPECT_EQ(k.fy, 525.0);
  EXPECT_EQ(k.cx, 319.5);
  EXPECT_EQ(k.cy, 240.0);
  EXPECT_EQ(k.depth_scale, 0.001);
  EXPECT_FALSE(k.depth_scale_from_file);

  EXPECT_EQ(DepthIntrinsicsPathFor("/a/frame_1_depth.tiff"), fs::path("/a/frame_1.xml"));
  EXPECT_THROW(DepthIntrinsicsPathFor("/a/frame_1.tiff"), FormatError);
  // A depth TIFF whose intrinsics file is missing: the error names the XML.
  const fs::path tiff = dir_ / "lonely_depth.tiff";
  WriteWithLibtiff(tiff, 4, 4, 16, COMPRESSION_NONE, 4, std::vector<std::uint16_t>(16, 800));
  try {
    ReadDepthFrame(tiff);
    ADD_FAILURE() << "read a frame without intrinsics";
  } catch (const FormatError& e) {
    EXPECT_EQ(e.file(), (dir_ / "lonely.xml").string());
  }
}

}  // namespace
}  // namespace s2m
