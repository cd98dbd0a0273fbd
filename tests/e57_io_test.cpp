// E57 reading and writing (acquisition/e57_io.h, docs/e57.md): the page layer's CRC-32C, the bit-pack codec,
// round trips of our writer's files, the hand-made files of tests/data/e57 (made by make_e57_files.py there,
// byte by byte from the standard, for the reader paths our writer never produces), every truncated and
// corrupted variant of a small file, and E57 through the command (info, fit, export, batch).

#include "acquisition/e57_io.h"

#include <gtest/gtest.h>
#include <sys/resource.h>
#include <unistd.h>

#include <Eigen/Geometry>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <nlohmann/json.hpp>
#include <random>
#include <string>

#include "acquisition/format_error.h"
#include "acquisition/formats/e57_bitpack.h"
#include "acquisition/formats/e57_pages.h"
#include "acquisition/point_cloud_io.h"
#include "test_paths.h"
#include "test_support.h"

namespace s2m {
namespace {

namespace fs = std::filesystem;
namespace e57 = formats::e57;

std::string Slurp(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}
void Spit(const fs::path& path, const std::string& bytes) {
  std::ofstream(path, std::ios::binary | std::ios::trunc)
      .write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
}
// The logical stream of a physical file (checksums dropped, not checked).
std::string Logical(const std::string& physical) {
  std::string out;
  for (std::size_t p = 0; p + e57::kPageSize <= physical.size(); p += e57::kPageSize)
    out.append(physical, p, e57::kPagePayload);
  return out;
}

std::string ErrorOf(const fs::path& file) {
  try {
    ReadE57(file);
  } catch (const FormatError& e) {
    return e.what();
  }
  return "";
}

// A scan of n points in a box of `size` metres, posed by a helical motion.
E57Scan RandomScan(int n, double size, std::uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(-size, size);
  E57Scan s;
  s.scan.points.resize(3, n);
  for (int i = 0; i < n; ++i) s.scan.points.col(i) = Eigen::Vector3d(u(rng), u(rng), u(rng));
  s.scan.units = "m";
  s.scan.world_T_scan =
      RigidMotion::FromHelicalVelocity({0.3 * u(rng), 0.2, -0.1 * seed}, {u(rng), 2.0, 3.0});
  s.name = "scan " + std::to_string(seed);
  return s;
}

TEST(E57Pages, Crc32cIsCastagnolis) {
  // The standard check value of CRC-32C: the nine ASCII digits "123456789".
  EXPECT_EQ(e57::Crc32c("123456789", 9), 0xE3069283u);
  EXPECT_EQ(e57::Crc32c("", 0), 0u);
}

TEST(E57Pages, LogicalAndPhysicalOffsetsMapBothWays) {
  for (const std::uint64_t logical : {0ull, 47ull, 1019ull, 1020ull, 2039ull, 2040ull, 123456789ull}) {
    const std::uint64_t physical = e57::LogicalToPhysical(logical);
    EXPECT_LT(physical % e57::kPageSize, e57::kPagePayload);
    EXPECT_EQ(e57::PhysicalToLogical(physical), logical);
  }
  EXPECT_EQ(e57::LogicalToPhysical(1020), 1024u);          // the first byte of page 1
  EXPECT_FALSE(e57::PhysicalToLogical(1021).has_value());  // inside page 0's checksum
}

TEST(E57BitPack, EveryWidthRoundTripsAcrossArbitraryChunks) {
  std::mt19937_64 rng(7);
  e57::BitWriter writer;
  std::vector<std::pair<std::uint64_t, int>> values;
  for (int round = 0; round < 3; ++round) {
    for (int width = 0; width <= 64; ++width) {
      const std::uint64_t v =
          width == 64 ? rng() : (width == 0 ? 0 : rng() & ((std::uint64_t{1} << width) - 1));
      values.emplace_back(v, width);
      writer.Put(v, width);
    }
  }
  // Fed in chunks of 1 to 13 bytes, as packets would cut the bytestream.
  e57::BitReader reader;
  const std::vector<unsigned char>& bytes = writer.bytes();
  std::size_t fed = 0, next = 0;
  while (next < values.size()) {
    if (reader.bits_available() < static_cast<std::uint64_t>(values[next].second) && fed < bytes.size()) {
      const std::size_t n = std::min<std::size_t>(1 + rng() % 13, bytes.size() - fed);
      reader.Append(bytes.data() + fed, n);
      fed += n;
      continue;
    }
    ASSERT_GE(reader.bits_available(), static_cast<std::uint64_t>(values[next].second));
    EXPECT_EQ(reader.Take(values[next].second), values[next].first) << "value " << next;
    ++next;
  }
}

TEST(E57BitPack, IntegerWidthsAndRangeChecks) {
  e57::FieldCodec c;
  c.type = e57::FieldType::kInteger;
  const std::tuple<std::int64_t, std::int64_t, int> cases[] = {
      {0, 0, 0},
      {0, 1, 1},
      {0, 2, 2},
      {0, 3, 2},
      {-1000, 1000, 11},
      {0, 4095, 12},
      {-262144, 262143, 19},
      {std::numeric_limits<std::int64_t>::min(), std::numeric_limits<std::int64_t>::max(), 64}};
  for (const auto& [lo, hi, width] : cases) {
    c.minimum = lo;
    c.maximum = hi;
    EXPECT_EQ(c.BitWidth(), width) << lo << ".." << hi;
    double v = 0;
    ASSERT_TRUE(e57::Decode(c, e57::EncodeInteger(c, hi), v));
    EXPECT_EQ(v, static_cast<double>(hi));
  }
  c.minimum = 0;
  c.maximum = 5;  // 3 bits, but 6 and 7 are not values of the field
  double v = 0;
  EXPECT_FALSE(e57::Decode(c, 6, v));
}

class E57Io : public ::testing::Test {
 protected:
  void SetUp() override { dir_ = test::FreshTempDir("e57_io"); }
  void TearDown() override { fs::remove_all(dir_); }
  fs::path dir_;
};

TEST_F(E57Io, DoublesRoundTripExactlyWithPosesAndIntensity) {
  std::vector<E57Scan> scans = {RandomScan(1000, 5.0, 1), RandomScan(1, 1.0, 2), RandomScan(70000, 50.0, 3)};
  scans[0].intensity = Eigen::VectorXd::LinSpaced(1000, 0.0, 1.0);
  E57WriteOptions options;
  options.intensity = E57IntensityEncoding::kFloat64;
  WriteE57(dir_ / "a.e57", scans, options);
  const E57Data back = ReadE57(dir_ / "a.e57");
  ASSERT_EQ(back.scans.size(), 3u);
  for (std::size_t k = 0; k < 3; ++k) {
    const E57Scan& b = back.scans[k];
    EXPECT_EQ(b.scan.points, scans[k].scan.points) << k;  // float64 keeps every bit
    EXPECT_EQ(b.scan.units, "m");
    EXPECT_EQ(b.name, scans[k].name);
    EXPECT_EQ(b.coordinates, "cartesian");
    // The pose goes through a unit quaternion: rounding of a few ulps.
    EXPECT_LT((b.scan.world_T_scan.matrix() - scans[k].scan.world_T_scan.matrix()).norm(), 1e-14) << k;
  }
  EXPECT_EQ(back.scans[0].intensity, scans[0].intensity);
  EXPECT_EQ(back.scans[1].intensity.size(), 0);
  // 70000 points of 24 bytes need several 64 KiB data packets: the index packet lists them.
  EXPECT_GT(fs::file_size(dir_ / "a.e57"), 70000u * 24u);
  const ScanSet set = ReadE57ScanSet(dir_ / "a.e57");
  ASSERT_EQ(set.scans.size(), 3u);
  EXPECT_EQ(set.name, "a");
  EXPECT_EQ(set.scans[2].world_T_scan.matrix(), back.scans[2].scan.world_T_scan.matrix());
}

TEST_F(E57Io, FloatsRoundToSinglePrecision) {
  std::vector<E57Scan> scans = {RandomScan(500, 3.0, 4)};
  scans[0].intensity = Eigen::VectorXd::LinSpaced(500, -2.0, 7.0);
  E57WriteOptions options;
  options.coordinates = E57CoordinateEncoding::kFloat32;
  options.max_records_per_packet = 37;
  WriteE57(dir_ / "f.e57", scans, options);
  const E57Scan back = ReadE57(dir_ / "f.e57").scans.at(0);
  ASSERT_EQ(back.scan.size(), 500);
  for (Eigen::Index i = 0; i < 500; ++i) {
    for (int a = 0; a < 3; ++a)
      ASSERT_EQ(back.scan.points(a, i), static_cast<double>(static_cast<float>(scans[0].scan.points(a, i))));
    ASSERT_EQ(back.intensity[i], static_cast<double>(static_cast<float>(scans[0].intensity[i])));
  }
  EXPECT_NE(back.fields.at(0).find("Float (single)"), std::string::npos);
}

TEST_F(E57Io, ScaledIntegersKeepHalfAStepWithOddBitWidths) {
  // A 0.7 m box at 10 micrometre steps: about 70000 values per axis, 17 bits; intensity in [0, 3] at 1e-3:
  // 3001 values, 12 bits.
  std::vector<E57Scan> scans = {RandomScan(3000, 0.35, 5), RandomScan(200, 0.35, 6)};
  scans[0].intensity = Eigen::VectorXd::LinSpaced(3000, 0.0, 3.0);
  E57WriteOptions options;
  options.coordinates = E57CoordinateEncoding::kScaledInteger;
  options.coordinate_scale = 1e-5;
  options.intensity = E57IntensityEncoding::kScaledInteger;
  options.intensity_scale = 1e-3;
  options.max_records_per_packet = 101;  // 30 data packets: every bitstream cut inside a value
  WriteE57(dir_ / "s.e57", scans, options);
  const E57Data back = ReadE57(dir_ / "s.e57");
  for (std::size_t k = 0; k < 2; ++k) {
    // Rounding to the nearest step: at most half a step, plus the rounding of raw * scale in double.
    const double error = (back.scans[k].scan.points - scans[k].scan.points).cwiseAbs().maxCoeff();
    EXPECT_LE(error, 0.5e-5 * (1 + 1e-9)) << k;
    EXPECT_GT(error, 0.0) << k;
  }
  EXPECT_LE((back.scans[0].intensity - scans[0].intensity).cwiseAbs().maxCoeff(), 0.5e-3 * (1 + 1e-9));
  const std::string& x_field = back.scans[0].fields.at(0);
  EXPECT_NE(x_field.find("ScaledInteger"), std::string::npos) << x_field;
  EXPECT_EQ(std::stoi(x_field.substr(x_field.find(", ") + 2)), 17) << x_field;  // 2^16 < 70000 <= 2^17
  EXPECT_NE(back.scans[0].fields.at(3).find("12 bits"), std::string::npos) << back.scans[0].fields.at(3);
}

TEST_F(E57Io, InvalidPointsAreDroppedAndCounted) {
  std::vector<E57Scan> scans = {RandomScan(100, 2.0, 8)};
  scans[0].intensity = Eigen::VectorXd::LinSpaced(100, 0.0, 99.0);
  for (const int i : {3, 50, 99}) scans[0].scan.points(1, i) = std::numeric_limits<double>::quiet_NaN();
  for (const int i : {4, 60}) scans[0].intensity[i] = std::numeric_limits<double>::quiet_NaN();
  for (const E57CoordinateEncoding c :
       {E57CoordinateEncoding::kFloat64, E57CoordinateEncoding::kScaledInteger}) {
    E57WriteOptions options;
    options.coordinates = c;
    WriteE57(dir_ / "i.e57", scans, options);
    const E57Scan back = ReadE57(dir_ / "i.e57").scans.at(0);
    EXPECT_EQ(back.records, 100u);
    EXPECT_EQ(back.invalid, 3u);
    ASSERT_EQ(back.scan.size(), 97);
    ASSERT_EQ(back.scan.metadata.notes.size(), 1u);
    EXPECT_NE(back.scan.metadata.notes[0].find("dropped 3 of 100 records"), std::string::npos);
    // Kept: points 0, 1, 2, 4, 5, ... (3 dropped): the fourth kept is point 4, whose intensity is unknown.
    EXPECT_EQ(back.intensity[2], 2.0);
    EXPECT_TRUE(std::isnan(back.intensity[3]));
    EXPECT_EQ(back.intensity[4], 5.0);
    EXPECT_TRUE(std::isnan(back.intensity[58]));  // point 60 (points 3 and 50 dropped before it)
    EXPECT_TRUE(back.scan.points.allFinite());
  }
}

TEST_F(E57Io, LengthUnitsAreConvertedToMetres) {
  std::vector<E57Scan> scans = {RandomScan(10, 100.0, 9)};
  scans[0].scan.units = "mm";
  WriteE57(dir_ / "mm.e57", scans);
  const E57Scan back = ReadE57(dir_ / "mm.e57").scans.at(0);
  EXPECT_EQ(back.scan.units, "m");
  EXPECT_LT((back.scan.points - scans[0].scan.points * 1e-3).cwiseAbs().maxCoeff(), 1e-15);
  EXPECT_LT((back.scan.world_T_scan.translation() - scans[0].scan.world_T_scan.translation() * 1e-3).norm(),
            1e-15);
  scans[0].scan.units = "unknown";
  try {
    WriteE57(dir_ / "u.e57", scans);
    ADD_FAILURE() << "unknown units written";
  } catch (const FormatError& e) {
    EXPECT_NE(std::string(e.what()).find("units 'unknown'"), std::string::npos) << e.what();
  }
  EXPECT_FALSE(fs::exists(dir_ / "u.e57"));
  EXPECT_THROW(WriteE57(dir_ / "e.e57", std::vector<E57Scan>{}), FormatError);
}

// tests/data/e57/spherical_grid.e57 (make_e57_files.py says how each value is made; restated here).
TEST(E57HandMade, SphericalGridWithIntensityColourRowsColumnsAndSeveralPackets) {
  const E57Data data = ReadE57(test::TestData("e57/spherical_grid.e57"));
  EXPECT_EQ(data.library_version, "hand-made test file");
  EXPECT_EQ(data.images, 1u);
  ASSERT_EQ(data.scans.size(), 1u);
  const E57Scan& s = data.scans[0];
  EXPECT_EQ(s.name, "grid");
  EXPECT_EQ(s.guid, "{D2629847-A1DB-4579-9E86-5D146B68BEA5}");
  EXPECT_EQ(s.coordinates, "spherical");
  EXPECT_EQ(s.scan.metadata.device, "file:organized");
  constexpr int kRows = 12, kCols = 40;
  EXPECT_EQ(s.records, static_cast<std::uint64_t>(kRows * kCols));
  Eigen::Index kept = 0;
  std::uint64_t dropped = 0;
  for (int r = 0; r < kRows * kCols; ++r) {
    const int i = r / kCols, j = r % kCols;
    const int state = r % 7 == 3 ? 2 : r % 11 == 5 ? 1 : 0;
    if (state != 0) {
      ++dropped;
      continue;
    }
    const double range = (2000 + 7 * i + 3 * j) * 0.001;
    const double azimuth = static_cast<float>(-0.5 + 0.1 * j);
    const double elevation = static_cast<float>(-0.3 + 0.05 * i);
    const Eigen::Vector3d p =
        range * Eigen::Vector3d(std::cos(elevation) * std::cos(azimuth),
                                std::cos(elevation) * std::sin(azimuth), std::sin(elevation));
    ASSERT_LT(kept, s.scan.size());
    EXPECT_LT((s.scan.points.col(kept) - p).norm(), 1e-12) << r;
    EXPECT_EQ(s.row_index[static_cast<std::size_t>(kept)], i);
    EXPECT_EQ(s.column_index[static_cast<std::size_t>(kept)], j);
    if ((i + j) % 5 == 0) {
      EXPECT_TRUE(std::isnan(s.intensity[kept])) << r;
    } else {
      EXPECT_EQ(s.intensity[kept], (37 * i + 11 * j) % 4096) << r;
    }
    EXPECT_EQ(s.colour.col(kept), Eigen::Vector3d((16 * i) % 256, (8 * j) % 256, (i + j) % 256)) << r;
    ++kept;
  }
  EXPECT_EQ(s.scan.size(), kept);
  EXPECT_EQ(s.invalid, dropped);
  // Pose: 0.5 rad about z, translation (10, -5, 1.5).
  const RigidMotion truth(RotationAboutAxis(Eigen::Vector3d::UnitZ(), 0.5), Eigen::Vector3d(10, -5, 1.5));
  EXPECT_LT((s.scan.world_T_scan.matrix() - truth.matrix()).norm(), 1e-12);
}

TEST(E57HandMade, CartesianScansWithOffsetsConstantFieldsExtensionsAndInvalidStates) {
  const E57Data data = ReadE57(test::TestData("e57/cartesian_mixed.e57"));
  ASSERT_EQ(data.scans.size(), 2u);
  const E57Scan& a = data.scans[0];
  EXPECT_EQ(a.name, "no pose");
  EXPECT_EQ(a.scan.world_T_scan.matrix(), Eigen::Matrix4d::Identity());
  ASSERT_EQ(a.scan.size(), 300);
  for (int k = 0; k < 300; ++k) {
    const Eigen::Vector3d p(((37 * k) % 2001 - 1000) * 0.0005 + 10.0,
                            ((53 * k) % 2001 - 1000) * 0.0005 - 20.0,
                            ((11 * k) % 2001 - 1000) * 0.0005 + 0.5);
    EXPECT_EQ(a.scan.points.col(k), p) << k;
    if (k % 9 == 0) {
      EXPECT_TRUE(std::isnan(a.colour(0, k))) << k;
    } else {
      EXPECT_EQ(a.colour.col(k), Eigen::Vector3d(k % 256, (3 * k) % 256, (7 * k) % 256)) << k;
    }
  }
  EXPECT_EQ(a.intensity.size(), 0);
  EXPECT_NE(a.fields.at(7).find("returnIndex: Integer, 0 bits"), std::string::npos) << a.fields.at(7);
  EXPECT_NE(a.fields.at(9).find("ext:quality: Integer, 3 bits [-3, 3]"), std::string::npos) << a.fields.at(9);
  const E57Scan& b = data.scans[1];
  EXPECT_EQ(b.records, 50u);
  EXPECT_EQ(b.invalid, 13u);  // k mod 4 == 1 for k < 50: a direction only, no position
  Eigen::Index kept = 0;
  for (int k = 0; k < 50; ++k) {
    if (k % 4 == 1) continue;
    EXPECT_EQ(b.scan.points.col(kept++), Eigen::Vector3d(0.1 * k, 1.0 - 0.02 * k, 0.003 * k * k)) << k;
  }
  const RigidMotion truth(RotationAboutAxis(Eigen::Vector3d(1, 2, 2) / 3.0, 0.7),
                          Eigen::Vector3d(1.5, -2, 0.25));
  EXPECT_LT((b.scan.world_T_scan.matrix() - truth.matrix()).norm(), 1e-12);
  // As one cloud (what `fit` of a primitive reads): both scans in the world.
  const Scan cloud = ReadPointCloud(test::TestData("e57/cartesian_mixed.e57"));
  EXPECT_EQ(cloud.size(), 300 + 37);
  EXPECT_LT((cloud.points.col(300) - truth * b.scan.points.col(0)).norm(), 1e-12);
}

TEST(E57HandMade, UnknownCodecIsRefusedByName) {
  const std::string error = ErrorOf(test::TestData("e57/unknown_codec.e57"));
  EXPECT_NE(error.find("unknown codec 'zipCodec'"), std::string::npos) << error;
  EXPECT_NE(error.find("unknown_codec.e57: byte "), std::string::npos) << error;
}

// As in point_cloud_io_test.cpp: a child limited to 512 MiB of address space, where an allocation of the
// claimed size would fail with std::bad_alloc; under AddressSanitizer (terabytes of shadow memory reserved up
// front) the limit is left out and only the error's kind is checked.
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
    ReadE57(path);
  } catch (const FormatError& e) {
    std::_Exit(std::string(e.what()).find("recordCount 1000000000000000 needs") != std::string::npos ? 0 : 4);
  } catch (const std::bad_alloc&) {
    std::_Exit(1);
  } catch (...) {
    std::_Exit(2);
  }
  std::_Exit(5);
}

TEST(E57HandMade, HugeRecordCountIsRefusedBeforeAllocating) {
  GTEST_FLAG_SET(death_test_style, "threadsafe");
  EXPECT_EXIT(ReadUnderAddressLimitAndExit(test::TestData("e57/huge_record_count.e57")),
              ::testing::ExitedWithCode(0), "");
}

TEST_F(E57Io, CorruptionIsNamedWithFileOffsetAndProblem) {
  WriteE57(dir_ / "ok.e57", std::vector<E57Scan>{RandomScan(400, 1.0, 10)});
  const std::string good = Slurp(dir_ / "ok.e57");
  ASSERT_GE(good.size(), 3 * e57::kPageSize);
  std::string flipped = good;
  flipped[1500] = static_cast<char>(flipped[1500] ^ 0x10);  // page 1's payload
  Spit(dir_ / "crc.e57", flipped);
  std::string error = ErrorOf(dir_ / "crc.e57");
  EXPECT_NE(error.find("crc.e57: byte 2044: bad CRC-32C checksum of page 1"), std::string::npos) << error;

  Spit(dir_ / "cut.e57", good.substr(0, good.size() - 100));
  error = ErrorOf(dir_ / "cut.e57");
  EXPECT_NE(error.find("cut.e57: byte 16: truncated: the header declares"), std::string::npos) << error;

  // A broken XML section with valid checksums: the error points into the XML.
  std::string logical = Logical(good);
  const std::size_t close = logical.rfind("</e57Root>");
  ASSERT_NE(close, std::string::npos);
  logical.replace(close, 10, "</e57Roo>\n");
  Spit(dir_ / "xml.e57", e57::PageLogicalStream(logical));
  error = ErrorOf(dir_ / "xml.e57");
  EXPECT_NE(error.find("bad XML"), std::string::npos) << error;
  EXPECT_NE(error.find("xml.e57: byte "), std::string::npos) << error;

  Spit(dir_ / "other.e57", "ply\nformat ascii 1.0\n");
  EXPECT_NE(ErrorOf(dir_ / "other.e57").find("not an E57 file"), std::string::npos);
  Spit(dir_ / "empty.e57", "");
  EXPECT_NE(ErrorOf(dir_ / "empty.e57").find("empty file"), std::string::npos);
}

// Every truncation, every byte with one bit flipped in the physical file (caught by the checksums), and every
// byte of the logical stream with a bit flipped and the checksums made good again (reaching the header,
// section, packet and XML checks): each is read without a crash, either correctly or with a FormatError that
// names the file. The file: two small scans, scaled integers with invalid points and intensity, several
// packets.
TEST_F(E57Io, EveryTruncatedOrBitFlippedVariantIsAnErrorOrARead) {
  std::vector<E57Scan> scans = {RandomScan(12, 1.0, 11), RandomScan(5, 1.0, 12)};
  scans[0].scan.points(0, 2) = std::numeric_limits<double>::quiet_NaN();
  scans[0].intensity = Eigen::VectorXd::LinSpaced(12, 0.0, 1.0);
  E57WriteOptions options;
  options.coordinates = E57CoordinateEncoding::kScaledInteger;
  options.coordinate_scale = 1e-3;
  options.max_records_per_packet = 5;
  WriteE57(dir_ / "small.e57", scans, options);
  const std::string good = Slurp(dir_ / "small.e57");
  const std::string logical = Logical(good);
  // In memory where the system has it: rewriting a file thousands of times on a disk mounted with `discard`
  // costs milliseconds each (measured 3.6 ms against 0.03 ms in /dev/shm).
  std::error_code ec;
  const fs::path scratch = fs::is_directory("/dev/shm", ec) ? fs::path("/dev/shm") : dir_;
  const fs::path variant = scratch / ("s2m_e57_variant_" + std::to_string(::getpid()) + ".e57");
  std::size_t errors = 0, reads = 0;
  const auto check = [&](const std::string& bytes, const std::string& what) {
    Spit(variant, bytes);
    try {
      const E57Data d = ReadE57(variant);
      for (const E57Scan& s : d.scans) ASSERT_TRUE(s.scan.points.allFinite()) << what;
      ++reads;
    } catch (const FormatError& e) {
      ASSERT_NE(std::string(e.what()).find(variant.string()), std::string::npos) << what << ": " << e.what();
      ASSERT_FALSE(e.problem().empty()) << what;
      ++errors;
    }
  };
  for (std::size_t n = 0; n < good.size(); ++n) check(good.substr(0, n), "truncated to " + std::to_string(n));
  for (std::size_t i = 0; i < good.size(); ++i) {
    std::string bytes = good;
    bytes[i] = static_cast<char>(bytes[i] ^ (1 << (i % 8)));
    check(bytes, "physical byte " + std::to_string(i) + " flipped");
  }
  EXPECT_EQ(reads, 0u);  // a checksum catches every single-bit error of a page
  for (std::size_t i = 0; i < logical.size(); ++i) {
    std::string bytes = logical;
    bytes[i] = static_cast<char>(bytes[i] ^ (1 << (i % 8)));
    check(e57::PageLogicalStream(bytes), "logical byte " + std::to_string(i) + " flipped");
  }
  EXPECT_GT(reads, 0u);  // flips in coordinate bits and padding read as other values
  EXPECT_GT(errors, good.size() * 2);
  fs::remove(variant, ec);
}

// ------------------------------------------------------------------------------------------ the command

// Standard output only (JSON), or with standard error merged (messages).
test::ShellResult RunCli(const std::string& args, bool with_stderr = false) {
  return test::Shell(std::string(S2M_CLI_PATH) + " " + args, with_stderr);
}

// A sphere of radius 0.25 m about (1, 2, 0.5) in the world, seen by two scans with their poses, points in
// each scan's frame with noise sigma = 0.5 mm along the normal.
std::vector<E57Scan> SphereScans() {
  const Eigen::Vector3d centre(1.0, 2.0, 0.5);
  const double radius = 0.25, sigma = 5e-4;
  std::mt19937 rng(3);
  std::normal_distribution<double> noise(0.0, sigma);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  std::vector<E57Scan> scans(2);
  for (int k = 0; k < 2; ++k) {
    scans[k].scan.units = "m";
    scans[k].scan.world_T_scan = RigidMotion::FromHelicalVelocity({0.2, -0.4 * k, 0.5}, {3.0 * k, -1.0, 0.5});
    scans[k].scan.points.resize(3, 1500);
    const RigidMotion scan_T_world = scans[k].scan.world_T_scan.inverse();
    for (int i = 0; i < 1500; ++i) {
      Eigen::Vector3d d(u(rng), u(rng), u(rng));
      while (d.norm() > 1.0 || d.norm() < 0.1) d = Eigen::Vector3d(u(rng), u(rng), u(rng));
      d.normalize();
      if (k == 1) d.x() = std::abs(d.x());  // the second scan sees one half only
      scans[k].scan.points.col(i) = scan_T_world * (centre + (radius + noise(rng)) * d);
    }
  }
  return scans;
}

TEST_F(E57Io, CommandFitsASphereFromAnE57FileWithTwoPosedScans) {
  E57WriteOptions options;
  options.coordinates = E57CoordinateEncoding::kScaledInteger;
  options.coordinate_scale = 1e-5;  // 10 micrometres: far below the noise
  WriteE57(dir_ / "ball.e57", SphereScans(), options);
  const test::ShellResult fit = RunCli("fit --model sphere --json " + (dir_ / "ball.e57").string());
  ASSERT_EQ(fit.exit_code, 0) << fit.out;
  const nlohmann::json j = nlohmann::json::parse(fit.out);
  EXPECT_EQ(j["input"]["format"], "e57");
  EXPECT_EQ(j["input"]["points"], 3000);
  EXPECT_EQ(j["input"]["units"], "m");
  // The world centre: the scans were placed by their poses. Within 5 standard uncertainties (sigma / sqrt(N)
  // scale, from the fit's own covariance).
  const Eigen::Vector3d truth(1.0, 2.0, 0.5);
  const char* axes[] = {"center_x", "center_y", "center_z"};
  for (int a = 0; a < 3; ++a) {
    const double u = j["uncertainties"][axes[a]]["standard_uncertainty"].get<double>();
    EXPECT_LT(u, 1e-4);
    EXPECT_NEAR(j["parameters"]["center"][a].get<double>(), truth[a], 5 * u) << axes[a];
  }
  const double u_r = j["uncertainties"]["radius"]["standard_uncertainty"].get<double>();
  EXPECT_NEAR(j["parameters"]["radius"].get<double>(), 0.25, 5 * u_r);
  EXPECT_NEAR(j["residuals"]["rms"].get<double>(), 5e-4, 5e-4 * 0.1);  // sigma, to 10 % with 3000 points

  const test::ShellResult info = RunCli("info --json " + (dir_ / "ball.e57").string());
  ASSERT_EQ(info.exit_code, 0) << info.out;
  const nlohmann::json i = nlohmann::json::parse(info.out);
  ASSERT_EQ(i["e57"]["scans"].size(), 2u);
  EXPECT_EQ(i["e57"]["scans"][1]["points"], 1500);
  EXPECT_EQ(i["points"], 3000);
}

// The demo vase's four views (mm) exported to one E57 file (metres) and fitted jointly from there: the scans
// are the views and their poses the starting poses, so the fit is the one of the manifest, scaled to metres.
// Both fits normalize the data into the unit box, so they agree to rounding (1e-6 relative after 3
// iterations).
TEST_F(E57Io, CommandFitsAJointModelToTheScansOfAnE57File) {
  const std::string manifest = std::string(S2M_SOURCE_DIR) + "/recordings/demo_vase/views.json";
  const test::ShellResult out = RunCli("export -q " + manifest + " -o " + (dir_ / "vase.e57").string(), true);
  ASSERT_EQ(out.exit_code, 0) << out.out;
  const std::string options = " --json --model revolution --control-points 8 --max-iterations 3";
  const test::ShellResult a = RunCli("fit" + options + " " + manifest);
  const test::ShellResult b = RunCli("fit" + options + " " + (dir_ / "vase.e57").string());
  ASSERT_EQ(a.exit_code, 0) << a.out;
  ASSERT_EQ(b.exit_code, 0) << b.out;
  const nlohmann::json ja = nlohmann::json::parse(a.out), jb = nlohmann::json::parse(b.out);
  EXPECT_EQ(jb["input"]["views"], 4);
  EXPECT_EQ(jb["input"]["units"], "m");
  EXPECT_EQ(jb["input"]["points"], ja["input"]["points"]);
  const double rms_mm = ja["residuals"]["rms"].get<double>(), rms_m = jb["residuals"]["rms"].get<double>();
  EXPECT_NEAR(rms_m, rms_mm * 1e-3, 1e-6 * rms_mm * 1e-3);
  for (std::size_t k = 0; k < 4; ++k) {
    for (int r = 0; r < 3; ++r) {
      EXPECT_NEAR(jb["views"][k]["world_T_scan"][r][3].get<double>(),
                  ja["views"][k]["world_T_scan"][r][3].get<double>() * 1e-3, 1e-6)
          << "view " << k;
    }
  }
}

TEST_F(E57Io, CommandExportsAndBatchesE57Files) {
  WriteE57(dir_ / "ball.e57", SphereScans());
  // export: the scans as views with their poses, and back to an E57 file.
  const test::ShellResult out =
      RunCli("export -q " + (dir_ / "ball.e57").string() + " -o " + (dir_ / "views").string());
  ASSERT_EQ(out.exit_code, 0) << out.out;
  const nlohmann::json views = nlohmann::json::parse(Slurp(dir_ / "views" / "views.json"));
  ASSERT_EQ(views["views"].size(), 2u);
  const std::vector<E57Scan> scans = SphereScans();
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 4; ++c)
      EXPECT_NEAR(views["views"][1]["world_T_scan"][r][c].get<double>(),
                  scans[1].scan.world_T_scan.matrix()(r, c), 1e-12);
  const test::ShellResult again = RunCli("export -q " + (dir_ / "views" / "views.json").string() + " -o " +
                                         (dir_ / "again.e57").string());
  ASSERT_EQ(again.exit_code, 0) << again.out;
  const E57Data back = ReadE57(dir_ / "again.e57");
  ASSERT_EQ(back.scans.size(), 2u);
  EXPECT_EQ(back.scans[1].scan.points, scans[1].scan.points);
  // record: the scans as frames of a recording, one view each, with their poses.
  const test::ShellResult rec =
      RunCli("record -q " + (dir_ / "ball.e57").string() + " -o " + (dir_ / "ball.s2mrec").string(), true);
  ASSERT_EQ(rec.exit_code, 0) << rec.out;
  const nlohmann::json recorded =
      nlohmann::json::parse(RunCli("info --json " + (dir_ / "ball.s2mrec").string()).out);
  EXPECT_EQ(recorded["views"], 2);
  EXPECT_EQ(recorded["points"], 3000);
  EXPECT_EQ(recorded["posed_frames"], 2);
  // batch: a manifest entry naming an E57 file.
  std::ofstream(dir_ / "objects.csv") << "id,input,model\nball,ball.e57,sphere\n";
  const test::ShellResult batch =
      RunCli("batch -q " + (dir_ / "objects.csv").string() + " -o " + (dir_ / "batch").string());
  ASSERT_EQ(batch.exit_code, 0) << batch.out;
  const nlohmann::json record = nlohmann::json::parse(Slurp(dir_ / "batch" / "objects" / "ball.json"));
  EXPECT_EQ(record["status"], "ok");
  EXPECT_NEAR(record["result"]["parameters"]["radius"].get<double>(), 0.25, 1e-3);
  // A corrupt E57 file through the command: exit code 3 and the file named.
  std::string bytes = Slurp(dir_ / "ball.e57");
  bytes[3000] = static_cast<char>(bytes[3000] ^ 1);
  Spit(dir_ / "bad.e57", bytes);
  const test::ShellResult bad = RunCli("fit --model sphere " + (dir_ / "bad.e57").string(), true);
  EXPECT_EQ(bad.exit_code, 3);
  EXPECT_NE(bad.out.find("bad.e57: byte 3068: bad CRC-32C"), std::string::npos) << bad.out;
}

}  // namespace
}  // namespace s2m
