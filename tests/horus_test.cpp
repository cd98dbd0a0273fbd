// Laser-line scanning and calibration of the Horus scanner (issue 6) against the virtual rig's ground truth:
// extraction and triangulation on rendered images of the vase, calibration from rendered pattern images, the
// calibration's JSON form, and the image cameras.

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>

#include "devices/horus_calibration.h"
#include "devices/laser_line.h"
#include "devices/opencv_camera.h"
#include "devices/virtual_horus.h"
#include "test_support.h"

namespace s2m {
namespace {

namespace fs = std::filesystem;
constexpr double kDegree = M_PI / 180.0;

double AngleBetween(const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  return std::atan2(a.cross(b).norm(), a.dot(b));
}

// ------------------------------------------------------------------------------------------ extraction

// Rows with a sampled Gaussian stripe at known sub-pixel centres, quantized to 8 bits: every method finds
// them.
TEST(LaserLine, ExtractionFindsSubPixelCentres) {
  Image8 off{64, 40, 3, {}}, on{64, 40, 3, {}};
  off.pixels.assign(64 * 40 * 3, 20);
  on.pixels = off.pixels;
  std::vector<double> truth;
  for (int row = 0; row < 40; ++row) {
    const double centre = 20.0 + 0.37 * row;  // sub-pixel positions over a whole pixel period and more
    truth.push_back(centre);
    for (int c = 0; c < 64; ++c) {
      const double v = 20 + 180 * std::exp(-(c - centre) * (c - centre) / (2 * 1.5 * 1.5));
      on.pixels[(static_cast<std::size_t>(row) * 64 + c) * 3 + 2] = static_cast<std::uint8_t>(std::lround(v));
    }
  }
  for (auto method : {LaserExtractionOptions::Method::kCenterOfMass,
                      LaserExtractionOptions::Method::kGaussian, LaserExtractionOptions::Method::kParabola}) {
    LaserExtractionOptions o;
    o.method = method;
    const auto line = ExtractLaserLine(on, off, o);
    ASSERT_EQ(line.size(), 40u);
    double worst = 0;
    for (const auto& p : line)
      worst = std::max(worst, std::abs(p.x() - truth[static_cast<std::size_t>(p.y())]));
    // Fisher and Naidu 1996: the parabola is biased by up to about 0.1 px on a Gaussian of this width; the
    // centre of mass and the Gaussian fit far less (8-bit quantization remains).
    EXPECT_LT(worst, method == LaserExtractionOptions::Method::kParabola ? 0.12 : 0.03)
        << static_cast<int>(method);
  }
  // Nothing is found where the difference stays below the threshold, and mismatched images are refused.
  EXPECT_TRUE(ExtractLaserLine(off, off).empty());
  Image8 small{8, 8, 3, std::vector<std::uint8_t>(8 * 8 * 3, 0)};
  EXPECT_THROW(ExtractLaserLine(on, small), std::invalid_argument);
}

// ------------------------------------------------------------------------------------------ virtual rig

VirtualHorus Rig(const std::string& extra = "") {
  return MakeVirtualHorus("horus-virtual:vase" + extra);
}

// The whole image -> points path on the vase with the true calibration: the extracted line against the
// rendered stripe's true centre (pixels), and the triangulated points against the exact surface (the distance
// along the camera's ray to where that ray meets the surface).
void ScanOfVaseLiesOnTheTrueSurface(const std::string& extra) {
  VirtualHorus v = Rig(extra);
  v.board->EnableMotor(true);
  const RigidMotion camera_in_platform = v.truth.platform_T_camera;
  double pixel_sum = 0, range_sum = 0, range_max = 0;
  std::size_t pixel_n = 0, range_n = 0;
  for (double degrees : {0.0, 100.0, 215.0}) {
    v.board->MoveTo(degrees);
    const Image8 off = v.camera->Capture();
    for (int laser = 0; laser < 2; ++laser) {
      v.board->SetLaser(laser, true);
      const Image8 on = v.camera->Capture();
      v.board->SetLaser(laser, false);
      const VirtualHorusRig::Stripe truth = v.rig->TrueStripe(laser);
      ASSERT_GT(truth.pixels.size(), 200u);  // the vase fills most rows
      const std::vector<Eigen::Vector2d> line = ExtractLaserLine(on, off);
      std::map<int, double> true_column;
      for (const auto& p : truth.pixels) true_column[static_cast<int>(p.y())] = p.x();
      for (const auto& p : line) {
        auto it = true_column.find(static_cast<int>(p.y()));
        ASSERT_NE(it, true_column.end()) << "row " << p.y() << " has a line the render did not draw";
        pixel_sum += (p.x() - it->second) * (p.x() - it->second);
        ++pixel_n;
      }
      EXPECT_GT(line.size(), truth.pixels.size() * 9 / 10);
      const Eigen::Matrix3Xd object =
          CameraToObject(TriangulateLaserLine(line, v.truth, laser), v.truth, degrees * kDegree);
      // Camera rays through the points in the object frame, cast on the exact surface.
      const Eigen::Vector3d eye =
          RotationAboutAxis(Eigen::Vector3d::UnitZ(), -degrees * kDegree) * camera_in_platform.translation();
      Eigen::Matrix3Xd origins(3, object.cols()), directions(3, object.cols());
      for (Eigen::Index i = 0; i < object.cols(); ++i) {
        origins.col(i) = eye;
        directions.col(i) = object.col(i) - eye;
      }
      const std::vector<RayHit> hits = v.rig->caster().Cast(origins, directions);
      for (Eigen::Index i = 0; i < object.cols(); ++i) {
        ASSERT_TRUE(hits[static_cast<std::size_t>(i)].hit);
        const double e = (hits[static_cast<std::size_t>(i)].point - object.col(i)).norm();
        range_sum += e * e;
        range_max = std::max(range_max, e);
        ++range_n;
      }
    }
  }
  const double pixel_rms = std::sqrt(pixel_sum / static_cast<double>(pixel_n));
  const double range_rms = std::sqrt(range_sum / static_cast<double>(range_n));
  std::printf("extraction: %zu rows, RMS %.4f px; points: %zu, RMS %.4f mm, max %.4f mm from the surface\n",
              pixel_n, pixel_rms, range_n, range_rms, range_max);
  // Footprint: 300 mm / 715 px = 0.42 mm per pixel at the axis; with 30 degrees between the camera's and the
  // laser's directions a column error e moves the point about 0.42 e / sin(30 deg) = 0.84 e mm along the ray.
  // Sensor noise (1 grey level) and 8-bit quantization leave about 0.03 px: 0.03 mm.
  EXPECT_LT(pixel_rms, 0.05);
  EXPECT_LT(range_rms, 0.05);
  EXPECT_LT(range_max, 0.3);
}

TEST(VirtualHorus, ScanOfVaseLiesOnTheTrueSurface) {
  ScanOfVaseLiesOnTheTrueSurface("");
}

// The same through a lens with barrel distortion (rendered with it, undistorted by cv::undistortPoints).
TEST(VirtualHorus, ScanThroughDistortedLensLiesOnTheTrueSurface) {
  ScanOfVaseLiesOnTheTrueSurface(",k1=-0.12,k2=0.05,p1=0.001");
}

// ------------------------------------------------------------------------------------------ calibration

struct CalibrationRun {
  VirtualHorus rig;
  ChessboardPattern pattern;
  std::vector<Image8> intrinsics_images;
  std::vector<PatternCapture> sweep;
};

CalibrationRun RunCalibrationCaptures(const std::string& extra = "") {
  CalibrationRun r{Rig(extra), {}, {}, {}};
  for (const RigidMotion& pose : r.rig.rig->HandHeldPatternPoses(r.pattern, 12)) {
    r.rig.rig->PlacePattern(r.pattern, pose);
    r.intrinsics_images.push_back(r.rig.camera->Capture());
  }
  r.rig.rig->PlacePattern(r.pattern, VirtualHorusRig::StandingPatternPose(r.pattern));
  std::vector<double> angles;
  for (int k = -4; k <= 4; ++k) angles.push_back(k * 11.25 * kDegree);
  r.sweep = CapturePatternSweep(*r.rig.board, *r.rig.camera, angles, 2);
  return r;
}

TEST(HorusCalibration, RecoversIntrinsicsLaserPlanesAndAxis) {
  CalibrationRun run = RunCalibrationCaptures();
  const HorusCalibration& truth = run.rig.truth;
  const HorusCalibrationReport r = CalibrateHorus(run.intrinsics_images, run.sweep, run.pattern);
  const CameraIntrinsics& k = r.calibration.camera;
  std::printf(
      "intrinsics: fx %.3f fy %.3f cx %.3f cy %.3f (true %.3f %.3f %.3f %.3f), k1 %.5f, RMS %.4f px, %d "
      "images\n",
      k.fx, k.fy, k.cx, k.cy, truth.camera.fx, truth.camera.fy, truth.camera.cx, truth.camera.cy,
      k.distortion[0], r.intrinsics.rms_px, r.intrinsics.images_used);
  EXPECT_EQ(r.intrinsics.images_used, 12);
  EXPECT_LT(r.intrinsics.rms_px, 0.1);
  EXPECT_NEAR(k.fx, truth.camera.fx, 2.1);  // 0.3 %
  EXPECT_NEAR(k.fy, truth.camera.fy, 2.1);
  EXPECT_NEAR(k.cx, truth.camera.cx, 2.0);
  EXPECT_NEAR(k.cy, truth.camera.cy, 2.0);
  ASSERT_EQ(r.calibration.lasers.size(), 2u);
  for (int l = 0; l < 2; ++l) {
    const LaserPlane& e = r.calibration.lasers[static_cast<std::size_t>(l)];
    const LaserPlane& t = truth.lasers[static_cast<std::size_t>(l)];
    const double angle = AngleBetween(e.normal, t.normal) / kDegree;
    std::printf(
        "laser %d: normal off by %.4f deg, distance %.3f mm (true %.3f), RMS %.4f mm over %d points\n", l,
        angle, e.distance, t.distance, r.lasers.rms_mm[static_cast<std::size_t>(l)],
        r.lasers.points[static_cast<std::size_t>(l)]);
    EXPECT_LT(angle, 0.2);
    EXPECT_NEAR(e.distance, t.distance, 0.5);
    EXPECT_LT(r.lasers.rms_mm[static_cast<std::size_t>(l)], 0.1);
  }
  // The axis: its direction, and where it meets the table (the platform's origin), in the camera frame.
  const Eigen::Vector3d true_axis = truth.platform_T_camera.inverse().rotation().col(2);
  const Eigen::Vector3d true_origin = truth.platform_T_camera.inverse().translation();
  const double axis_angle = AngleBetween(r.axis.axis_direction_camera, true_axis) / kDegree;
  const double origin_error = (r.axis.axis_point_camera - true_origin).norm();
  const double rotation_error =
      (r.calibration.platform_T_camera * truth.platform_T_camera.inverse()).angle() / kDegree;
  std::printf(
      "axis: direction off by %.4f deg, origin off by %.3f mm, platform rotation off by %.4f deg; circle RMS "
      "%.4f mm\n",
      axis_angle, origin_error, rotation_error, r.axis.circle_rms_mm);
  EXPECT_EQ(r.axis.poses_used, 9);
  EXPECT_LT(axis_angle, 0.2);
  EXPECT_LT(origin_error, 1.0);
  EXPECT_LT(rotation_error, 0.2);

  // Scanning the vase with the estimated calibration: each row's triangulated point (camera frame) against
  // the lit surface point the render drew there.
  VirtualHorus& v = run.rig;
  v.rig->PlacePattern(run.pattern, std::nullopt);
  double sum = 0, worst = 0;
  std::size_t n = 0;
  const RigidMotion camera_T_platform = truth.platform_T_camera.inverse();
  for (double degrees : {30.0, 250.0}) {
    v.board->MoveTo(degrees);
    const Image8 off = v.camera->Capture();
    for (int laser = 0; laser < 2; ++laser) {
      v.board->SetLaser(laser, true);
      const Image8 on = v.camera->Capture();
      v.board->SetLaser(laser, false);
      const VirtualHorusRig::Stripe stripe = v.rig->TrueStripe(laser);
      std::map<int, Eigen::Vector3d> truth_at_row;
      const Eigen::Matrix3d rz = RotationAboutAxis(Eigen::Vector3d::UnitZ(), degrees * kDegree);
      for (std::size_t i = 0; i < stripe.pixels.size(); ++i)
        truth_at_row[static_cast<int>(stripe.pixels[i].y())] =
            camera_T_platform * (rz * stripe.object_points[i]);
      for (const Eigen::Vector2d& p : ExtractLaserLine(on, off)) {
        const Eigen::Matrix3Xd x = TriangulateLaserLine({p}, r.calibration, laser);
        ASSERT_EQ(x.cols(), 1);
        const double e = (x.col(0) - truth_at_row.at(static_cast<int>(p.y()))).norm();
        sum += e * e;
        worst = std::max(worst, e);
        ++n;
      }
      // Into the object frame with the estimated platform pose: the same rows, the points above the table.
      const Eigen::Matrix3Xd object = ScanLaserLine(on, off, r.calibration, laser, degrees * kDegree);
      EXPECT_GT(object.cols(), static_cast<Eigen::Index>(stripe.pixels.size() * 9 / 10));
      for (Eigen::Index i = 0; i < object.cols(); ++i) {
        const double radius = object.col(i).head<2>().norm();
        EXPECT_GT(radius, 29.0);  // the vase's profile: radii 30 .. 66 mm, heights 0 .. 150 mm
        EXPECT_LT(radius, 67.0);
        EXPECT_LT(object(2, i), 151.0);
      }
    }
  }
  const double rms = std::sqrt(sum / static_cast<double>(n));
  std::printf(
      "vase scanned with the estimated calibration: %zu points, RMS %.4f mm, max %.4f mm from the truth\n", n,
      rms, worst);
  // The estimated focal lengths are off by about 0.08 % (cornerSubPix's 0.06 px corner error): at 300 mm that
  // alone is 0.24 mm of scale error.
  EXPECT_LT(rms, 0.4);
  EXPECT_LT(worst, 1.0);
}

// What the procedures say when the images cannot calibrate: no pattern in the intrinsics images, a pattern
// whose plane contains the axis (every laser line on one line), too few turntable stops.
TEST(HorusCalibration, DegenerateInputIsExplained) {
  VirtualHorus v = Rig();
  ChessboardPattern pattern;
  std::vector<Image8> vase;
  for (int k = 0; k < 3; ++k) vase.push_back(v.camera->Capture());
  try {
    CalibrateIntrinsics(vase, pattern);
    FAIL() << "calibrated without a pattern";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("pattern was found in 0 of 3 images"), std::string::npos)
        << e.what();
  }
  // The pattern's plane through the axis: the laser planes (1.5 mm off the axis) meet it near the axis at
  // every angle.
  v.rig->PlacePattern(pattern, VirtualHorusRig::StandingPatternPose(pattern, 0.0));
  const std::vector<PatternCapture> sweep =
      CapturePatternSweep(*v.board, *v.camera, {-20 * kDegree, 0.0, 20 * kDegree}, 2);
  try {
    CalibrateLaserPlanes(sweep, v.truth.camera, pattern);
    FAIL() << "a plane from (nearly) collinear points";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("lie (nearly) on one line"), std::string::npos) << e.what();
  }
  const std::vector<PatternCapture> two(sweep.begin(), sweep.begin() + 2);
  try {
    CalibrateTurntableAxis(two, v.truth.camera, pattern);
    FAIL() << "an axis from two poses";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("found at 2 of 2 angles; at least 3"), std::string::npos)
        << e.what();
  }
}

// ------------------------------------------------------------------------------------------------ JSON

TEST(HorusCalibration, JsonRoundTrip) {
  VirtualHorusOptions o;
  o.distortion = {-0.1, 0.02, 0.001, -0.002, 0.0};
  const HorusCalibration c = VirtualHorusTruth(o);
  const nlohmann::json j = nlohmann::json::parse(HorusCalibrationToJson(c).dump());
  const HorusCalibration d = HorusCalibrationFromJson(j);
  EXPECT_EQ(d.camera.width, c.camera.width);
  EXPECT_EQ(d.camera.height, c.camera.height);
  EXPECT_DOUBLE_EQ(d.camera.fx, c.camera.fx);
  EXPECT_DOUBLE_EQ(d.camera.cy, c.camera.cy);
  for (int i = 0; i < 5; ++i) EXPECT_DOUBLE_EQ(d.camera.distortion[i], c.camera.distortion[i]);
  ASSERT_EQ(d.lasers.size(), 2u);
  for (int l = 0; l < 2; ++l) {
    EXPECT_LT((d.lasers[l].normal - c.lasers[l].normal).norm(), 1e-15);
    EXPECT_DOUBLE_EQ(d.lasers[l].distance, c.lasers[l].distance);
  }
  EXPECT_LT((d.platform_T_camera.matrix() - c.platform_T_camera.matrix()).norm(), 1e-12);
}

TEST(HorusCalibration, BadJsonIsRefusedWithTheField) {
  const nlohmann::json good = HorusCalibrationToJson(VirtualHorusTruth({}));
  auto message = [](const nlohmann::json& j) {
    try {
      HorusCalibrationFromJson(j, "calib.json");
    } catch (const std::invalid_argument& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  nlohmann::json j = good;
  j.erase("camera");
  EXPECT_NE(message(j).find("calib.json: missing field 'camera'"), std::string::npos) << message(j);
  j = good;
  j["camera"]["fx"] = "big";
  EXPECT_NE(message(j).find("'fx' is not a finite number"), std::string::npos) << message(j);
  j = good;
  j["camera"]["distortion"] = {1, 2};
  EXPECT_NE(message(j).find("distortion is not an array of 5"), std::string::npos) << message(j);
  j = good;
  j["lasers"][1]["normal"] = {1, 1, 0};
  EXPECT_NE(message(j).find("lasers[1].normal is not a unit vector"), std::string::npos) << message(j);
  j = good;
  j["platform_T_camera"][3] = {0, 0};
  EXPECT_NE(message(j).find("platform_T_camera row 3"), std::string::npos) << message(j);
  EXPECT_NE(message(nlohmann::json::array()).find("must be a JSON object"), std::string::npos);
  // Files: the calibration under "horus", named in every error.
  const fs::path dir = test::FreshTempDir("horus_json");
  std::ofstream(dir / "good.json") << nlohmann::json{{"horus", good}}.dump();
  EXPECT_DOUBLE_EQ(ReadHorusCalibrationFile(dir / "good.json").camera.fx, good["camera"]["fx"].get<double>());
  std::ofstream(dir / "other.json") << good.dump();
  std::ofstream(dir / "broken.json") << "{\"horus\": ";
  for (const char* name : {"other.json", "broken.json", "absent.json"}) {
    try {
      ReadHorusCalibrationFile(dir / name);
      ADD_FAILURE() << name;
    } catch (const std::runtime_error& e) {
      EXPECT_NE(std::string(e.what()).find(name), std::string::npos) << e.what();
    }
  }
  fs::remove_all(dir);
}

// ---------------------------------------------------------------------------------------------- cameras

TEST(ImageCameras, ReplayFilesInOrderThenReportTheEnd) {
  const fs::path dir = test::FreshTempDir("horus_images");
  for (int i = 0; i < 3; ++i) {
    Image8 image{5, 4, 3, std::vector<std::uint8_t>(5 * 4 * 3, static_cast<std::uint8_t>(10 * i))};
    image.pixels[7] = 255;
    WriteImagePng(image, dir / ("frame_" + std::to_string(i) + ".png"));
  }
  std::unique_ptr<ImageCamera> camera = OpenImageDirectoryCamera(dir);
  for (int i = 0; i < 3; ++i) {
    const Image8 image = camera->Capture();
    ASSERT_EQ(image.width, 5);
    ASSERT_EQ(image.height, 4);
    ASSERT_EQ(image.channels, 3);
    EXPECT_EQ(image.pixels[0], 10 * i);
    EXPECT_EQ(image.pixels[7], 255);
  }
  try {
    camera->Capture();
    FAIL() << "a fourth image";
  } catch (const DeviceError& e) {
    EXPECT_EQ(e.kind(), DeviceError::Kind::kDisconnected);
  }
  try {
    OpenImageFileCamera({dir / "frame_0.png", dir / "missing.png"});
    FAIL() << "a missing file";
  } catch (const DeviceError& e) {
    EXPECT_EQ(e.kind(), DeviceError::Kind::kNotFound);
    EXPECT_NE(std::string(e.what()).find("missing.png' does not exist"), std::string::npos) << e.what();
  }
  std::ofstream(dir / "broken.png") << "not a png";
  EXPECT_THROW(ReadImagePng(dir / "broken.png"), std::runtime_error);
  fs::remove_all(dir);
}

TEST(ImageCameras, MissingV4l2CameraIsAClearError) {
  try {
    OpenOpenCvCamera("/dev/video-s2m-missing", {});
    FAIL() << "opened a camera that does not exist";
  } catch (const DeviceError& e) {
    EXPECT_EQ(e.kind(), DeviceError::Kind::kNotFound);
    EXPECT_NE(std::string(e.what()).find("camera '/dev/video-s2m-missing' could not be opened"),
              std::string::npos)
        << e.what();
  }
}

// `scan2model calibrate` on the virtual rig writes the calibration under "horus" with its residuals and its
// errors against the truth; the saved image set calibrates to the same result; bad input gives clear errors.
// A real scanner that is not connected: the calibration stops before asking for anything, says what to check,
// and writes no file (the emulated board's own tests are in horus_board_test).
TEST(CalibrateCommand, RealScannerNotConnectedIsAClearError) {
  const fs::path dir = test::FreshTempDir("horus_calibrate_real");
  const test::ShellResult result =
      test::Shell(std::string(S2M_CLI_PATH) + " calibrate --device horus,vid=0xffff,pid=0xfffe --out " +
                  (dir / "calib.json").string() + " < /dev/null");
  EXPECT_EQ(result.exit_code, 5) << result.out;
  EXPECT_NE(result.out.find("no Horus board found with id ffff:fffe"), std::string::npos) << result.out;
  EXPECT_NE(result.out.find("scan2model devices"), std::string::npos) << result.out;
  EXPECT_FALSE(fs::exists(dir / "calib.json"));
}

TEST(CalibrateCommand, VirtualRigThenSavedImages) {
  const fs::path dir = test::FreshTempDir("horus_calibrate");
  const std::string cli = S2M_CLI_PATH;
  const test::ShellResult first =
      test::Shell(cli + " calibrate --device horus-virtual:vase --poses 8 --angles 7 --out " +
                  (dir / "calib.json").string() + " --save-images " + (dir / "images").string());
  ASSERT_EQ(first.exit_code, 0) << first.out;
  EXPECT_NE(first.out.find("calibrate: pattern sweep: 7/7"), std::string::npos) << first.out;
  nlohmann::json doc = nlohmann::json::parse(std::ifstream(dir / "calib.json"));
  const HorusCalibration c = ReadHorusCalibrationFile(dir / "calib.json");
  EXPECT_EQ(c.lasers.size(), 2u);
  EXPECT_LT(doc["residuals"]["intrinsics"]["rms_px"].get<double>(), 0.1);
  EXPECT_LT(std::abs(doc["errors_vs_truth"]["fx_px"].get<double>()), 3.0);
  EXPECT_LT(doc["errors_vs_truth"]["axis_direction_deg"].get<double>(), 0.2);
  EXPECT_LT(doc["errors_vs_truth"]["platform_origin_mm"].get<double>(), 1.5);
  for (const auto& l : doc["errors_vs_truth"]["lasers"]) {
    EXPECT_LT(l["normal_deg"].get<double>(), 0.2);
    EXPECT_LT(std::abs(l["distance_mm"].get<double>()), 1.0);
  }
  const test::ShellResult again = test::Shell(cli + " calibrate -q --images " + (dir / "images").string() +
                                              " --out " + (dir / "again.json").string());
  ASSERT_EQ(again.exit_code, 0) << again.out;
  const nlohmann::json redo = nlohmann::json::parse(std::ifstream(dir / "again.json"));
  EXPECT_NEAR(redo["horus"]["camera"]["fx"].get<double>(), doc["horus"]["camera"]["fx"].get<double>(), 1e-9);
  EXPECT_NEAR(redo["horus"]["lasers"][1]["distance"].get<double>(),
              doc["horus"]["lasers"][1]["distance"].get<double>(), 1e-9);
  const test::ShellResult missing = test::Shell(cli + " calibrate --images " + (dir / "nothing").string() +
                                                " --out " + (dir / "x.json").string());
  EXPECT_EQ(missing.exit_code, 3);
  EXPECT_NE(missing.out.find("calibration_images.json' does not exist"), std::string::npos) << missing.out;
  const test::ShellResult bad =
      test::Shell(cli + " calibrate --device horus-virtual:vase,fov=9 --out " + (dir / "x.json").string());
  EXPECT_EQ(bad.exit_code, 2);
  EXPECT_NE(bad.out.find("unknown device option 'fov'"), std::string::npos) << bad.out;
  fs::remove_all(dir);
}

TEST(VirtualHorus, SpecErrorsNameTheOption) {
  std::string scene, units;
  const VirtualHorusOptions o =
      ParseVirtualHorus("horus-virtual:vase,width=320,k1=-0.1,noise=0", scene, units);
  EXPECT_EQ(scene, "vase");
  EXPECT_EQ(o.width, 320);
  EXPECT_DOUBLE_EQ(o.distortion[0], -0.1);
  EXPECT_DOUBLE_EQ(o.noise, 0.0);
  try {
    ParseVirtualHorus("horus-virtual:vase,colour=red", scene, units);
    FAIL();
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("unknown device option 'colour'"), std::string::npos) << e.what();
  }
  EXPECT_THROW(ParseVirtualHorus("horus-virtual:vase,width=-3", scene, units), std::invalid_argument);
  EXPECT_THROW(ParseVirtualHorus("horus-virtual:", scene, units), std::invalid_argument);
}

}  // namespace
}  // namespace s2m
