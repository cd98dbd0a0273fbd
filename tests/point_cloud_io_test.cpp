#include "acquisition/point_cloud_io.h"

#include <gtest/gtest.h>
#include <sys/resource.h>
#include <zlib.h>

#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <set>
#include <string>

#include "acquisition/format_error.h"
#include "test_paths.h"

namespace s2m {
namespace {

namespace fs = std::filesystem;

class PointCloudIo : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() /
           ("s2m_io_" + std::string(::testing::UnitTest::GetInstance()->current_test_info()->name()));
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }

  fs::path Write(const std::string& name, const std::string& bytes) {
    const fs::path p = dir_ / name;
    std::ofstream(p, std::ios::binary) << bytes;
    return p;
  }
  fs::path WriteGz(const std::string& name, const std::string& bytes) {
    const fs::path p = dir_ / name;
    gzFile gz = gzopen(p.c_str(), "wb");
    gzwrite(gz, bytes.data(), static_cast<unsigned>(bytes.size()));
    gzclose(gz);
    return p;
  }

  // Reading `path` must fail with a FormatError that names the file and contains each of `fragments`.
  void ExpectError(const fs::path& path, std::initializer_list<std::string> fragments) {
    try {
      ReadPointCloud(path);
      ADD_FAILURE() << "no error for " << path;
    } catch (const FormatError& e) {
      const std::string what = e.what();
      EXPECT_EQ(e.file(), path.string());
      EXPECT_NE(what.find(path.string()), std::string::npos) << what;
      for (const std::string& f : fragments)
        EXPECT_NE(what.find(f), std::string::npos) << "'" << f << "' not in: " << what;
    }
  }

  fs::path dir_;
};

template <class T>
std::string Bytes(T value, bool big_endian = false) {
  std::string s(sizeof(T), '\0');
  std::memcpy(s.data(), &value, sizeof(T));
  if (big_endian) std::reverse(s.begin(), s.end());
  return s;
}

const char* kAsciiPly =
    "ply\nformat ascii 1.0\ncomment units mm\nobj_info scanner test\n"
    "element vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
    "property float nx\nproperty float ny\nproperty float nz\n"
    "element range_grid 4\nproperty list uchar int vertex_indices\nend_header\n"
    "1 2 3 0 0 1\n4 5 6 0 1 0\n7 8 9.5 1 0 0\n1 0\n0\n1 2\n0\n";

// ---- PLY
// ------------------------------------------------------------------------------------------------------

TEST_F(PointCloudIo, ReadsAsciiPlyWithNormalsAndSkipsTheRangeGrid) {
  const Scan s = ReadPointCloud(Write("a.ply", kAsciiPly));
  ASSERT_EQ(s.size(), 3);
  EXPECT_TRUE(s.has_normals());
  EXPECT_EQ(s.units, "mm");
  EXPECT_EQ(s.points.col(2), Eigen::Vector3d(7, 8, 9.5));
  EXPECT_EQ(s.normals.col(1), Eigen::Vector3d(0, 1, 0));
}

TEST_F(PointCloudIo, ReadsGzippedPly) {
  const Scan s = ReadPointCloud(WriteGz("a.ply.gz", kAsciiPly));
  EXPECT_EQ(s.size(), 3);
  EXPECT_EQ(s.points.col(0), Eigen::Vector3d(1, 2, 3));
}

TEST_F(PointCloudIo, ReadsBinaryPlyInBothByteOrders) {
  for (bool big : {false, true}) {
    std::string ply = std::string("ply\nformat ") + (big ? "binary_big_endian" : "binary_little_endian") +
                      " 1.0\nelement vertex 2\nproperty double x\nproperty float y\nproperty int z\n"
                      "element face 1\nproperty list uchar int vertex_indices\nend_header\n";
    ply += Bytes(1.25, big) + Bytes(2.5f, big) + Bytes<int32_t>(-3, big);
    ply += Bytes(4.0, big) + Bytes(5.0f, big) + Bytes<int32_t>(6, big);
    ply += Bytes<uint8_t>(2) + Bytes<int32_t>(0, big) + Bytes<int32_t>(1, big);
    const Scan s = ReadPointCloud(Write(big ? "be.ply" : "le.ply", ply));
    ASSERT_EQ(s.size(), 2);
    EXPECT_EQ(s.points.col(0), Eigen::Vector3d(1.25, 2.5, -3));
    EXPECT_EQ(s.points.col(1), Eigen::Vector3d(4, 5, 6));
  }
}

TEST_F(PointCloudIo, PlyWriteReadRoundTripIsExact) {
  Scan s;
  s.points = Eigen::Matrix3Xd::Random(3, 100) * 1234.5678;
  s.normals = Eigen::Matrix3Xd::Random(3, 100).colwise().normalized();
  s.weights = Eigen::VectorXd::Random(100).cwiseAbs();
  s.units = "mm";
  s.world_T_scan = RigidMotion::FromHelicalVelocity({0.1, -0.2, 0.3}, {10, 20, 30});
  for (PlyEncoding e : {PlyEncoding::kBinaryLittleEndian, PlyEncoding::kAscii}) {
    const fs::path p = dir_ / (e == PlyEncoding::kAscii ? "ascii.ply" : "binary.ply");
    WritePly(p, s, e);
    EXPECT_FALSE(fs::exists(p.string() + ".partial"));
    const Scan r = ReadPointCloud(p);
    EXPECT_EQ(r.points, s.points);
    EXPECT_EQ(r.normals, s.normals);
    EXPECT_EQ(r.weights, s.weights);
    EXPECT_EQ(r.units, "mm");
    EXPECT_EQ(r.world_T_scan.matrix(), s.world_T_scan.matrix());
  }
}

TEST_F(PointCloudIo, BrokenPlyFilesGetClearErrors) {
  ExpectError(Write("magic.ply", "plx\nformat ascii 1.0\n"), {"line 1", "not a PLY file"});
  ExpectError(Write("header.ply", "ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\n"),
              {"no 'end_header'"});
  ExpectError(
      Write("noxyz.ply", "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nend_header\n1\n"),
      {"x, y, z"});
  ExpectError(Write("empty.ply",
                    "ply\nformat ascii 1.0\nelement vertex 0\nproperty float x\nproperty float y\nproperty "
                    "float z\nend_header\n"),
              {"empty point set"});
  const std::string head =
      "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float "
      "z\nend_header\n";
  ExpectError(Write("short.ply", head + "1 2 3\n4 5 6\n"), {"truncated", "line 10", "declares 3"});
  ExpectError(Write("nan.ply", head + "1 2 3\n4 nan 6\n7 8 9\n"), {"line 9", "vertex 1", "y is not finite"});
  ExpectError(Write("word.ply", head + "1 2 3\n4 five 6\n7 8 9\n"), {"line 9", "not a number: 'five'"});
  ExpectError(Write("extra.ply", head + "1 2 3\n4 5 6 7\n7 8 9\n"), {"line 9", "expected 3 values"});
  ExpectError(Write("nobody.ply", head), {"truncated"});
  const std::string bin =
      "ply\nformat binary_little_endian 1.0\nelement vertex 1000\nproperty float x\nproperty float "
      "y\nproperty float z\nend_header\n";
  ExpectError(Write("bin.ply", bin + std::string(100, '\0')),
              {"byte " + std::to_string(bin.size()), "truncated", "1000 entries"});
  const std::string list =
      "ply\nformat binary_little_endian 1.0\nelement vertex 1\nproperty float x\nproperty float y\nproperty "
      "float z\n"
      "element face 1\nproperty list uchar int vertex_indices\nend_header\n";
  ExpectError(Write("list.ply", list + std::string(12, '\0') + Bytes<uint8_t>(200) + "abc"),
              {"truncated", "element 'face'"});
  ExpectError(Write("type.ply", "ply\nformat ascii 1.0\nelement vertex 1\nproperty quad x\nend_header\n"),
              {"line 4", "unknown property type"});
  // A signed list count that is negative (the mesh fuzzer's finding: undefined behaviour converting it to a
  // size), and, in ASCII, a count so large that adding it to the token index wrapped round.
  const std::string signed_list =
      "ply\nformat binary_little_endian 1.0\nelement vertex 1\nproperty float x\nproperty float y\nproperty "
      "float z\nelement face 1\nproperty list int8 int vertex_indices\nend_header\n";
  ExpectError(
      Write("negative_list.ply", signed_list + std::string(12, '\0') + Bytes<int8_t>(-3) + "abcdefghijkl"),
      {"element 'face' entry 0", "count -3", "not a non-negative integer"});
  const std::string ascii_list =
      "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\nproperty float z\n"
      "element face 1\nproperty list uchar int vertex_indices\nend_header\n1 2 3\n";
  ExpectError(Write("wrapping_list.ply", ascii_list + "18446744073709551615 0 0 0\n"),
              {"line 11", "declares 18446744073709551615 items"});
  ExpectError(Write("zero.ply", ""), {"empty file"});
}

TEST_F(PointCloudIo, TruncatedGzipIsAnError) {
  const fs::path whole = WriteGz("whole.ply.gz", std::string(kAsciiPly) + std::string(5000, '\n'));
  std::ifstream in(whole, std::ios::binary);
  std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  ExpectError(Write("cut.ply.gz", bytes.substr(0, bytes.size() / 2)), {"gzip"});
}

TEST_F(PointCloudIo, ReadsARealStanfordRangeScan) {
  if (!test::HaveSharedData()) GTEST_SKIP() << "../shared/data is absent";
  const Scan s = ReadPointCloud(test::SharedData("stanford_bunny_scans/bun000.ply"));
  EXPECT_EQ(s.size(), 40256);  // the range_grid element (204800 entries) is validated and dropped
  const Scan gz = ReadPointCloud(test::SharedData("stanford_bunny_scans/bun090.ply.gz"));
  EXPECT_GT(gz.size(), 30000);
  EXPECT_LT(ComputeBounds(gz.points).diagonal(), 0.5);  // metres
}

// ---- PCD
// ------------------------------------------------------------------------------------------------------

const char* kPcdHeader =
    "# .PCD v0.7\nVERSION 0.7\nFIELDS x y z normal_x normal_y normal_z\nSIZE 4 4 4 4 4 4\nTYPE F F F F F F\n"
    "COUNT 1 1 1 1 1 1\nWIDTH 2\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS 2\n";

TEST_F(PointCloudIo, ReadsAsciiAndBinaryPcd) {
  const Scan a =
      ReadPointCloud(Write("a.pcd", std::string(kPcdHeader) + "DATA ascii\n1 2 3 0 0 1\n4 5 6 1 0 0\n"));
  ASSERT_EQ(a.size(), 2);
  EXPECT_TRUE(a.has_normals());
  EXPECT_EQ(a.points.col(1), Eigen::Vector3d(4, 5, 6));
  std::string bin = std::string(kPcdHeader) + "DATA binary\n";
  for (float v : {1.f, 2.f, 3.f, 0.f, 0.f, 1.f, 4.f, 5.f, 6.f, 1.f, 0.f, 0.f}) bin += Bytes(v);
  const Scan b = ReadPointCloud(Write("b.pcd", bin));
  EXPECT_EQ(b.points, a.points);
  EXPECT_EQ(b.normals, a.normals);
}

TEST_F(PointCloudIo, ReadsLzfCompressedPcd) {
  // Field-major payload x0 x1 y0 y1 z0 z1 with z = x: 16 literal bytes, then an 8-byte back reference 16
  // bytes back.
  std::string plain;
  for (float v : {1.f, 4.f, 2.f, 5.f}) plain += Bytes(v);
  std::string lzf = Bytes<uint8_t>(15) + plain + Bytes<uint8_t>(0xC0) + Bytes<uint8_t>(0x0F);
  std::string pcd =
      "VERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nWIDTH 2\nHEIGHT 1\nPOINTS 2\nDATA "
      "binary_compressed\n";
  pcd += Bytes<uint32_t>(static_cast<uint32_t>(lzf.size())) + Bytes<uint32_t>(24) + lzf;
  const Scan s = ReadPointCloud(Write("c.pcd", pcd));
  ASSERT_EQ(s.size(), 2);
  EXPECT_EQ(s.points.col(0), Eigen::Vector3d(1, 2, 1));
  EXPECT_EQ(s.points.col(1), Eigen::Vector3d(4, 5, 4));
  std::string corrupt = pcd;
  corrupt.back() = 0x7F;  // back reference before the start of the output
  ExpectError(Write("bad.pcd", corrupt), {"corrupt LZF"});
}

TEST_F(PointCloudIo, PcdInvalidPointsAreDroppedAndCounted) {
  const std::string head = "FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nWIDTH 2\nHEIGHT 2\nPOINTS 4\nDATA ascii\n";
  const Scan s = ReadPointCloud(Write("org.pcd", head + "1 2 3\nnan nan nan\n4 5 6\nnan nan nan\n"));
  EXPECT_EQ(s.size(), 2);
  ASSERT_EQ(s.metadata.notes.size(), 1u);
  EXPECT_NE(s.metadata.notes[0].find("dropped 2 of 4"), std::string::npos);
  ExpectError(Write("allnan.pcd", head + "nan nan nan\nnan nan nan\nnan nan nan\nnan nan nan\n"),
              {"no valid point"});
}

TEST_F(PointCloudIo, PcdLabelsFollowTheValidPoints) {
  const std::string head =
      "FIELDS label x y z\nSIZE 4 4 4 4\nTYPE U F F F\nWIDTH 3\nHEIGHT 1\nPOINTS 3\nDATA ascii\n";
  const Scan s = ReadPointCloud(Write("labels.pcd", head + "20 1 2 3\n0 nan nan nan\n30 4 5 6\n"));
  ASSERT_EQ(s.size(), 2);
  EXPECT_EQ(s.labels, (std::vector<std::int64_t>{20, 30}));
}

// A label is an integer field, but its value may still be one a 64-bit label cannot hold (a text of 1e30, an
// unsigned 64-bit value above 2^63): an error naming the point, not a conversion with undefined behaviour.
TEST_F(PointCloudIo, PcdLabelsBeyondTheInt64RangeAreRefused) {
  const std::string ascii =
      "FIELDS label x y z\nSIZE 4 4 4 4\nTYPE U F F F\nWIDTH 2\nHEIGHT 1\nPOINTS 2\nDATA ascii\n";
  ExpectError(Write("big.pcd", ascii + "20 1 2 3\n1e30 4 5 6\n"), {"line 9", "point 1", "label"});
  ExpectError(Write("nan.pcd", ascii + "nan 1 2 3\n1 4 5 6\n"), {"point 0", "label"});
  std::string binary =
      "FIELDS x y z label\nSIZE 4 4 4 8\nTYPE F F F U\nWIDTH 2\nHEIGHT 1\nPOINTS 2\nDATA binary\n";
  for (std::uint64_t label : {std::uint64_t{7}, std::uint64_t{0xFFFFFFFFFFFFFFFFull}})
    binary += Bytes(1.f) + Bytes(2.f) + Bytes(3.f) + Bytes<std::uint64_t>(label);
  ExpectError(Write("big_binary.pcd", binary), {"byte", "point 1", "label"});
  const std::string max_label =
      "FIELDS x y z label\nSIZE 4 4 4 8\nTYPE F F F I\nWIDTH 1\nHEIGHT 1\nPOINTS "
      "1\nDATA binary\n" +
      Bytes(1.f) + Bytes(2.f) + Bytes(3.f) + Bytes<std::int64_t>(-(std::int64_t{1} << 62));
  EXPECT_EQ(ReadPointCloud(Write("ok_binary.pcd", max_label)).labels,
            (std::vector<std::int64_t>{-(std::int64_t{1} << 62)}));
}

// The labelled mOSD scene (binary_compressed, organized 640 x 480 with NaNs): the labels survive the
// dropping of invalid points.
TEST_F(PointCloudIo, ReadsTheLabelledClutterScene) {
  if (!test::HaveSharedData()) GTEST_SKIP() << "../shared/data is absent";
  const Scan s = ReadPointCloud(test::SharedData("real_clutter_scenes/test36.pcd"));
  ASSERT_EQ(s.labels.size(), static_cast<std::size_t>(s.size()));
  EXPECT_LT(s.size(), 640 * 480);
  std::set<std::int64_t> distinct(s.labels.begin(), s.labels.end());
  EXPECT_GE(distinct.size(), 4u);  // table and three objects at least
}

TEST_F(PointCloudIo, BrokenPcdFilesGetClearErrors) {
  ExpectError(Write("short.pcd", std::string(kPcdHeader) + "DATA ascii\n1 2 3 0 0 1\n"),
              {"truncated", "line 13"});
  ExpectError(Write("cols.pcd", std::string(kPcdHeader) + "DATA ascii\n1 2 3 0 0 1\n4 5 6\n"),
              {"line 13", "expected 6 values, found 3"});
  ExpectError(Write("bin.pcd", std::string(kPcdHeader) + "DATA binary\n" + std::string(10, '\0')),
              {"truncated", "byte"});
  ExpectError(
      Write("fields.pcd", "FIELDS x y z\nSIZE 4 4\nTYPE F F F\nWIDTH 1\nPOINTS 1\nDATA ascii\n1 2 3\n"),
      {"different numbers of fields"});
  ExpectError(Write("nodata.pcd", "FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\n"), {"no DATA line"});
  ExpectError(Write("empty.pcd", "FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nWIDTH 0\nPOINTS 0\nDATA ascii\n"),
              {"empty point set"});
  ExpectError(Write("xy.pcd", "FIELDS x y\nSIZE 4 4\nTYPE F F\nWIDTH 1\nPOINTS 1\nDATA ascii\n1 2\n"),
              {"lacks one of x, y, z"});
}

TEST_F(PointCloudIo, ReadsPclsBunnyPcd) {
  if (!test::HaveSharedData()) GTEST_SKIP() << "../shared/data is absent";
  const Scan s = ReadPointCloud(test::SharedData("pcl_bunny_small/bun0.pcd"));
  EXPECT_EQ(s.size(), 397);
  EXPECT_TRUE(s.has_normals());
  EXPECT_EQ(ReadPointCloud(test::SharedData("pcl_bunny_small/bun4.pcd")).size(), 361);
}

// ---- Text and NIST .ds
// ------------------------------------------------------------------------------------------

TEST_F(PointCloudIo, ReadsXyzAndCsvWithHeaders) {
  const Scan xyz = ReadPointCloud(Write("a.xyz", "# comment\n1 2 3\n\n4\t5 6\r\n"));
  ASSERT_EQ(xyz.size(), 2);
  EXPECT_EQ(xyz.points.col(1), Eigen::Vector3d(4, 5, 6));
  const Scan csv = ReadPointCloud(Write("a.csv", "id,X,Y,Z,nx,ny,nz\n7,1,2,3,0,0,1\n8,4,5,6,0,1,0\n"));
  ASSERT_EQ(csv.size(), 2);
  EXPECT_EQ(csv.points.col(0), Eigen::Vector3d(1, 2, 3));
  EXPECT_EQ(csv.normals.col(1), Eigen::Vector3d(0, 1, 0));
  const Scan six = ReadPointCloud(Write("b.txt", "1 2 3 0 0 1\n"));
  EXPECT_TRUE(six.has_normals());
}

TEST_F(PointCloudIo, BrokenTextFilesGetClearErrors) {
  ExpectError(Write("nan.xyz", "1 2 3\n4 5 NaN\n"), {"line 2", "z is not finite"});
  ExpectError(Write("cols.xyz", "1 2 3\n4 5\n"), {"line 2", "expected 3 values, found 2"});
  ExpectError(Write("two.xyz", "1 2\n"), {"line 1", "at least 3 values"});
  ExpectError(Write("word.csv", "x,y,z\n1,2,abc\n"), {"line 2", "not a number: 'abc'"});
  ExpectError(Write("hdr.csv", "a,b,c\n1,2,3\n"), {"line 1", "no x, y and z"});
  ExpectError(Write("comments.xyz", "# only a comment\n"), {"empty point set"});
}

TEST_F(PointCloudIo, ReadsNistDsAndRejectsBrokenOnes) {
  const Scan s = ReadPointCloud(test::TestData("nist/cyl1.ds"));
  EXPECT_EQ(s.size(), 500);
  ExpectError(Write("short.ds", "3\r\n1 2 3\r\n4 5 6\r\n"), {"truncated", "3 points declared, 2 present"});
  ExpectError(Write("long.ds", "1\n1 2 3\n4 5 6\n"), {"line 3", "more data lines"});
  ExpectError(Write("count.ds", "1 2 3\n"), {"line 1", "point count"});
  ExpectError(Write("inf.ds", "1\n1 inf 3\n"), {"line 2", "not finite"});
  ExpectError(Write("zero.ds", "0\n"), {"empty point set"});
}

TEST_F(PointCloudIo, UnknownMissingAndDirectoryInputs) {
  ExpectError(Write("a.stl", "solid"), {"unknown point-cloud format '.stl'"});
  ExpectError(dir_ / "missing.ply", {"cannot open"});
  fs::create_directories(dir_ / "folder.ply");
  ExpectError(dir_ / "folder.ply", {"is a directory"});
}

// Inputs that claim huge sizes are refused before anything is allocated (docs/reliability.md). Run in a child
// whose address space is limited to 512 MiB, so that an allocation of the claimed size fails there
// (std::bad_alloc instead of the FormatError) even on a machine that overcommits memory. AddressSanitizer
// reserves terabytes of shadow memory up front, so under it the limit is left out and only the error's kind
// is checked.
#if defined(__SANITIZE_ADDRESS__)
#define S2M_UNDER_ASAN 1
#elif defined(__has_feature)
#if __has_feature(address_sanitizer)
#define S2M_UNDER_ASAN 1
#endif
#endif

void ReadUnderAddressLimitAndExit(const fs::path& path) {
#ifndef S2M_UNDER_ASAN
  const rlimit limit{512ull << 20, 512ull << 20};
  if (setrlimit(RLIMIT_AS, &limit) != 0) std::_Exit(3);
#endif
  try {
    ReadPointCloud(path);
  } catch (const FormatError& e) {
    std::_Exit(std::string(e.what()).find("truncated") != std::string::npos ? 0 : 4);
  } catch (const std::bad_alloc&) {
    std::_Exit(1);
  } catch (...) {
    std::_Exit(2);
  }
  std::_Exit(5);
}

TEST_F(PointCloudIo, HugeClaimedCountsAreRefusedBeforeAllocating) {
  GTEST_FLAG_SET(death_test_style, "threadsafe");
  const std::string ply_ascii =
      "ply\nformat ascii 1.0\nelement vertex 1099511627776\nproperty double x\nproperty double y\n"
      "property double z\nend_header\n1 2 3\n";
  const std::string ply_binary =
      "ply\nformat binary_little_endian 1.0\nelement vertex 1099511627776\nproperty double x\n"
      "property double y\nproperty double z\nend_header\n" +
      std::string(24, '\0');
  // A vertex record with a list (variable size): at least its scalars and the list's count per record (the
  // first coverage-guided run found this one allocating the claimed count; tests/data/fuzz/point_cloud/).
  const std::string ply_binary_list =
      "ply\nformat binary_little_endian 1.0\nelement vertex 21474836485\nproperty float x\n"
      "property float y\nproperty float z\nproperty list uchar int indices\nend_header\n" +
      std::string(40, '\0');
  // An element without properties claiming 2^34 entries: records of no bytes, nothing to read (the point
  // cloud fuzzer's finding: the reader spun through the count).
  const std::string ply_empty_element =
      "ply\nformat binary_little_endian 1.0\nelement vertex 1\nproperty float x\nproperty float y\n"
      "property float z\nelement face 17179869184\nend_header\n" +
      std::string(12, '\0');
  const std::string pcd_header =
      "VERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nWIDTH 1000000000\nHEIGHT 1\n"
      "VIEWPOINT 0 0 0 1 0 0 0\nPOINTS 1000000000\nDATA ";
  const fs::path files[] = {
      Write("two_to_the_forty.ply", ply_ascii),
      Write("two_to_the_forty_binary.ply", ply_binary),
      Write("huge_binary_with_a_list.ply", ply_binary_list),
      Write("billion_ascii.pcd", pcd_header + "ascii\n1 2 3\n"),
      Write("billion_binary.pcd", pcd_header + "binary\n" + std::string(12, '\0')),
      // 2^32 - 1 bytes uncompressed declared for 12 compressed bytes (a billion points of 12 bytes do not fit
      // 32 bits, so the reader must refuse the count, not trust the size words).
      Write("billion_compressed.pcd", pcd_header + "binary_compressed\n" +
                                          std::string("\x0c\0\0\0\xff\xff\xff\xff", 8) +
                                          std::string(12, '\0')),
  };
  for (const fs::path& file : files)
    EXPECT_EXIT(ReadUnderAddressLimitAndExit(file), ::testing::ExitedWithCode(0), "") << file;
  EXPECT_EQ(ReadPointCloud(Write("empty_element.ply", ply_empty_element)).size(), 1);
}

}  // namespace
}  // namespace s2m
