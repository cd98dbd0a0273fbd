// The whole Horus path without hardware: the libusb board driver talking to an emulated board on an emulated
// USB bus (tests/emulated_horus_board.h, umockdev), images rendered by the virtual rig in the state the
// emulated firmware reports (turntable angle, lasers), laser-line extraction and triangulation with OpenCV,
// and the scan loop recording as it goes. The board vanishes mid-scan: what was acquired stays recorded, the
// error is clear, and a resumed scan on a re-plugged board completes the recording with points on the true
// surface.

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <memory>
#include <string>

#include "acquisition/frame_source.h"
#include "acquisition/recording.h"
#include "devices/horus_board.h"
#include "devices/horus_scan.h"
#include "devices/laser_line.h"
#include "devices/usb_transport.h"
#include "devices/virtual_horus.h"
#include "emulated_horus_board.h"
#include "test_support.h"

namespace s2m {
namespace {

namespace fs = std::filesystem;
using test::EmulatedHorusBoard;

constexpr double kDegree = M_PI / 180.0;

// Renders what the camera would see in the state the emulated firmware is in: the rig follows the board.
class FirmwareDrivenCamera : public ImageCamera {
 public:
  FirmwareDrivenCamera(const EmulatedHorusBoard& board, std::shared_ptr<VirtualHorusRig> rig)
      : board_(board), rig_(std::move(rig)) {}
  std::string Name() const override { return "virtual camera following the emulated board"; }
  Image8 Capture() override {
    rig_->set_angle_rad(board_.Angle() * kDegree);
    for (int laser = 0; laser < 2; ++laser) rig_->set_laser(laser, board_.Laser(laser));
    return rig_->Render();
  }

 private:
  const EmulatedHorusBoard& board_;
  std::shared_ptr<VirtualHorusRig> rig_;
};

HorusBoardOptions FastBoard() {
  HorusBoardOptions o;  // the emulator answers at once or never; generous for a loaded 2-core machine
  o.timeout_ms = 400;
  o.retries = 2;
  o.banner_timeout_ms = 500;
  o.move_timeout_ms = 500;
  return o;
}

HorusScanOptions EightSteps(bool resume) {
  HorusScanOptions o;
  o.steps = 8;
  o.views = HorusScanOptions::ViewGrouping::kLaserSweep;
  o.sleep = [](double) {};
  o.resume = resume;
  return o;
}

TEST(HorusUsbScan, VanishingBoardKeepsTheFramesAndAResumeCompletesTheScan) {
  if (!EmulatedHorusBoard::InMockEnvironment())
    GTEST_SKIP() << "not running under umockdev-wrapper: the emulated USB board is unavailable";
  const fs::path dir = test::FreshTempDir("horus_usb_scan");
  const fs::path out = dir / "vase.s2mrec";
  VirtualHorus virtual_rig = MakeVirtualHorus("horus-virtual:vase");
  const HorusCalibration& calibration = virtual_rig.truth;
  const LaserProfileFunction profile = [&calibration](const Image8& on, const Image8& off, int laser) {
    return TriangulateLaserLine(ExtractLaserLine(on, off), calibration, laser);
  };

  HorusScanResult first;
  {
    EmulatedHorusBoard emulated;
    UsbContext context;
    std::unique_ptr<HorusBoard> board = OpenHorusBoard(context, FastBoard());
    FirmwareDrivenCamera camera(emulated, virtual_rig.rig);
    // Set-up takes 6 commands (reset, feed, acceleration, motor, two lasers off), each step 5 (move, laser on
    // and off twice): the board goes during step 3.
    emulated.VanishAfterCommands(6 + 5 * 3 + 2);
    first = RunHorusScan(*board, camera, calibration, profile, out, EightSteps(false));
  }
  EXPECT_FALSE(first.complete);
  ASSERT_TRUE(first.error_kind.has_value());
  EXPECT_EQ(*first.error_kind, DeviceError::Kind::kDisconnected) << first.error;
  EXPECT_NE(first.error.find("2341:0043"), std::string::npos) << first.error;  // names the device
  EXPECT_EQ(first.total, 16);
  EXPECT_GE(first.done, 6);  // steps 0-2, both lasers
  EXPECT_LT(first.done, 16);
  EXPECT_EQ(first.frames, first.done);  // every pair acquired before the loss is in the recording
  EXPECT_EQ(first.status.rfind("interrupted", 0), 0u) << first.status;
  {
    const std::unique_ptr<FrameSource> partial = OpenRecordingSource(out);  // valid and readable as it is
    std::int64_t frames = 0;
    while (partial->Next()) ++frames;
    EXPECT_EQ(frames, first.frames);
  }

  HorusScanResult resumed;
  {
    EmulatedHorusBoard replugged;
    UsbContext context;
    std::unique_ptr<HorusBoard> board = OpenHorusBoard(context, FastBoard());
    FirmwareDrivenCamera camera(replugged, virtual_rig.rig);
    resumed = RunHorusScan(*board, camera, calibration, profile, out, EightSteps(true));
    EXPECT_FALSE(replugged.MotorEnabled());  // the scan leaves the scanner safe
    EXPECT_FALSE(replugged.Laser(0));
    EXPECT_FALSE(replugged.Laser(1));
  }
  EXPECT_TRUE(resumed.complete) << resumed.error;
  EXPECT_EQ(resumed.resumed_from, first.done);
  EXPECT_EQ(resumed.done, 16);
  EXPECT_EQ(resumed.frames, 16);

  // Every recorded point, mapped by its frame's pose, lies on the vase: the camera ray through it meets the
  // exact surface there. Tolerances as tests/horus_test.cpp's for the same rig (0.84 mm of range per pixel of
  // column error at the 30-degree laser angle; extraction is good to a few hundredths of a pixel).
  const std::unique_ptr<FrameSource> source = OpenRecordingSource(out);
  double sum = 0, worst = 0;
  std::int64_t n = 0, frames = 0;
  while (std::optional<Frame> frame = source->Next()) {
    ++frames;
    ASSERT_TRUE(frame->world_T_scan.has_value());
    ASSERT_GT(frame->points.cols(), 50);
    const RigidMotion& world_T_camera = *frame->world_T_scan;
    Eigen::Matrix3Xd origins(3, frame->points.cols()), directions(3, frame->points.cols());
    for (Eigen::Index i = 0; i < frame->points.cols(); ++i) {
      origins.col(i) = world_T_camera.translation();
      directions.col(i) =
          world_T_camera * Eigen::Vector3d(frame->points.col(i)) - world_T_camera.translation();
    }
    const std::vector<RayHit> hits = virtual_rig.rig->caster().Cast(origins, directions);
    for (Eigen::Index i = 0; i < frame->points.cols(); ++i) {
      const RayHit& hit = hits[static_cast<std::size_t>(i)];
      ASSERT_TRUE(hit.hit);
      const double e = (hit.point - world_T_camera * Eigen::Vector3d(frame->points.col(i))).norm();
      sum += e * e;
      worst = std::max(worst, e);
      ++n;
    }
  }
  EXPECT_EQ(frames, 16);
  const double rms = std::sqrt(sum / static_cast<double>(n));
  std::cout << "[ measured ] " << n << " points of 16 profiles: RMS " << rms << " mm, max " << worst
            << " mm from the true surface\n";
  EXPECT_LT(rms, 0.05);
  EXPECT_LT(worst, 0.3);
}

}  // namespace
}  // namespace s2m
