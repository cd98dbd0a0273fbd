// The libusb transport and the Horus board driver against an emulated board on an emulated USB bus
// (tests/emulated_horus_board.h, umockdev). Runs under umockdev-wrapper (tests/CMakeLists.txt); without the
// preload library the emulated tests skip (libusb would see the real bus).

#include "devices/horus_board.h"

#include <gtest/gtest.h>

#include <chrono>
#include <condition_variable>
#include <mutex>
#include <string>
#include <vector>

#include "devices/usb_transport.h"
#include "emulated_horus_board.h"

namespace s2m {
namespace {

using test::EmulatedHorusBoard;

class HorusBoardTest : public ::testing::Test {
 protected:
  void SetUp() override {
    if (!EmulatedHorusBoard::InMockEnvironment()) {
      GTEST_SKIP() << "not running under umockdev-wrapper (the umockdev preload library): the emulated USB "
                      "board is unavailable";
    }
  }
  // Short timeouts: the emulator answers at once or never (still generous for a loaded 2-core machine, where
  // an answer takes a few milliseconds).
  static HorusBoardOptions Fast() {
    HorusBoardOptions o;
    o.timeout_ms = 400;
    o.retries = 2;
    o.banner_timeout_ms = 500;
    o.move_timeout_ms = 500;
    return o;
  }
  static DeviceError::Kind KindOf(const std::function<void()>& f, std::string* message) {
    try {
      f();
    } catch (const DeviceError& e) {
      *message = e.what();
      return e.kind();
    }
    ADD_FAILURE() << "no DeviceError thrown";
    return DeviceError::Kind::kOther;
  }
};

TEST(UsbErrorTest, MessagesSayWhatToDo) {
  UsbDeviceInfo d;
  d.bus = 3;
  d.address = 7;
  d.vendor_id = 0x2341;
  d.product_id = 0x0043;
  const DeviceError access = UsbError(-3 /* LIBUSB_ERROR_ACCESS */, d, "opening");
  EXPECT_EQ(access.kind(), DeviceError::Kind::kPermission);
  const std::string m = access.what();
  EXPECT_NE(
      m.find("SUBSYSTEM==\"usb\", ATTRS{idVendor}==\"2341\", ATTRS{idProduct}==\"0043\", MODE=\"0660\", "
             "TAG+=\"uaccess\""),
      std::string::npos)
      << m;
  EXPECT_NE(m.find("/etc/udev/rules.d/60-scan2model.rules"), std::string::npos);
  EXPECT_NE(m.find("udevadm control --reload && sudo udevadm trigger"), std::string::npos);
  EXPECT_NE(m.find("2341:0043 (bus 3, address 7)"), std::string::npos);
  EXPECT_EQ(UsbError(-6, d, "x").kind(), DeviceError::Kind::kBusy);
  EXPECT_EQ(UsbError(-4, d, "x").kind(), DeviceError::Kind::kDisconnected);
  EXPECT_EQ(UsbError(-7, d, "x").kind(), DeviceError::Kind::kTimeout);
  EXPECT_EQ(UsbError(-9, d, "x").kind(), DeviceError::Kind::kStall);
  EXPECT_EQ(UsbError(-5, d, "x").kind(), DeviceError::Kind::kNotFound);
  EXPECT_EQ(UsbError(-1, d, "x").kind(), DeviceError::Kind::kOther);
}

TEST(GcodeNumberTest, ShortestWithThreeDecimals) {
  EXPECT_EQ(GcodeNumber(10.0), "10");
  EXPECT_EQ(GcodeNumber(12.5), "12.5");
  EXPECT_EQ(GcodeNumber(-0.125), "-0.125");
  EXPECT_EQ(GcodeNumber(0.00004), "0");
  EXPECT_EQ(GcodeNumber(359.9999), "360");
}

TEST_F(HorusBoardTest, EnumerationSeesTheEmulatedBoard) {
  EmulatedHorusBoard emu;
  UsbContext context;
  const std::vector<UsbDeviceInfo> by_id = context.FindByVidPid(0x2341, 0x0043);
  ASSERT_EQ(by_id.size(), 1u);
  const UsbDeviceInfo& d = by_id[0];
  EXPECT_EQ(d.bus, 1);
  EXPECT_EQ(d.address, 5);
  EXPECT_EQ(d.device_class, kUsbClassCdcComm);
  EXPECT_TRUE(d.has_cdc_acm);
  EXPECT_EQ(d.interface_classes, (std::vector<std::uint8_t>{kUsbClassCdcComm, kUsbClassCdcData}));
  EXPECT_EQ(d.manufacturer, "Arduino (www.arduino.cc)");
  EXPECT_EQ(d.product, "Horus turntable (emulated)");
  EXPECT_EQ(d.serial_number, "EMU0001");
  EXPECT_EQ(d.supported_as, "Arduino board (CDC-ACM)");
  EXPECT_TRUE(d.accessible);
  EXPECT_EQ(context.FindByVidPid(0x2341, 0).size(), 1u);
  EXPECT_EQ(context.FindByVidPid(0x0403, 0x6001).size(), 0u);
  EXPECT_EQ(context.FindByInterfaceClass(kUsbClassCdcData).size(), 1u);
  EXPECT_EQ(context.FindByInterfaceClass(0x08 /* mass storage */).size(), 0u);
  const std::vector<UsbDeviceInfo> supported = ListSupportedDevices(context);
  ASSERT_EQ(supported.size(), 1u);
  EXPECT_EQ(supported[0].Name(), "2341:0043 'Horus turntable (emulated)' (bus 1, address 5)");
  EXPECT_EQ(ListSupportedDevices().size(), 1u);  // its own context
}

TEST_F(HorusBoardTest, TransportTransfersAndOutlivesItsContext) {
  EmulatedHorusBoard emu;
  std::unique_ptr<UsbDevice> device;
  {
    UsbContext context;
    const std::vector<UsbDeviceInfo> found = context.FindByInterfaceClass(kUsbClassCdcComm);
    ASSERT_EQ(found.size(), 1u);
    UsbDevice::Options options;
    options.timeout_ms = 300;
    options.retries = 1;
    device = context.Open(found[0], options);
  }  // the device keeps libusb (and its event thread) alive
  const UsbDevice::CdcAcmEndpoints ep = device->FindCdcAcm();
  EXPECT_EQ(ep.comm_interface, 0);
  EXPECT_EQ(ep.data_interface, 1);
  EXPECT_EQ(ep.bulk_out, 0x04);
  EXPECT_EQ(ep.bulk_in, 0x83);
  // GET_DESCRIPTOR (string 2, English) as a raw control transfer: bLength, bDescriptorType 3, UTF-16LE.
  std::vector<std::uint8_t> data(255);
  device->Control(0x80, 6, 0x0302, 0x0409, data, "reading the product string");
  ASSERT_EQ(data.size(), 2u + 2u * std::string("Horus turntable (emulated)").size());
  EXPECT_EQ(data[1], 3);
  EXPECT_EQ(data[2], 'H');
  device->ClaimInterface(1);
  device->BulkWrite(ep.bulk_out, {0x18, '\r', '\n'}, "reset");
  std::string text;
  while (text.find("help]") == std::string::npos) {
    const std::vector<std::uint8_t> got = device->BulkRead(ep.bulk_in, 64, "banner");
    text.append(got.begin(), got.end());
  }
  EXPECT_EQ(text, "\r\nHorus 0.1 ['$' for help]\r\n");
  EXPECT_TRUE(device->BulkReadAvailable(ep.bulk_in, 64, 50, "nothing more").empty());
  const UsbDevice::Stats stats = device->GetStats();
  EXPECT_EQ(stats.timeouts, 0);
  EXPECT_EQ(stats.retries, 0);
  EXPECT_GE(stats.transfers, 3);
  device.reset();  // closes the device, then libusb_exit and the event thread's join
}

TEST_F(HorusBoardTest, HandshakeSetsTheLineAndReadsTheBanner) {
  EmulatedHorusBoard emu;
  UsbContext context;
  const std::unique_ptr<HorusBoard> board = OpenHorusBoard(context, Fast());
  EXPECT_EQ(board->Banner(), "Horus 0.1 ['$' for help]");
  EXPECT_EQ(emu.BaudRate(), 115200u);
  EXPECT_EQ(emu.DataBits(), 8);
  EXPECT_EQ(emu.ControlLineState(), 0x03);  // DTR and RTS
  EXPECT_EQ(emu.Resets(), 1);
  EXPECT_EQ(emu.CommandLog(), std::vector<std::string>{"^X"});
  EXPECT_EQ(board->Device().serial_number, "EMU0001");
}

TEST_F(HorusBoardTest, NormalScanSequence) {
  EmulatedHorusBoard emu;
  UsbContext context;
  std::unique_ptr<HorusBoard> board = OpenHorusBoard(context, Fast());
  board->EnableMotor(true);
  board->SetFeedRate(200);
  board->SetAcceleration(300);
  std::vector<std::string> expected = {"^X", "M17", "G1F200", "$120=300"};
  std::vector<int> light;
  for (int step = 0; step < 5; ++step) {
    const double angle = 10.0 * step;
    board->MoveTo(angle);
    expected.push_back("G1X" + std::to_string(10 * step));
    EXPECT_DOUBLE_EQ(emu.Angle(), angle);
    for (int laser = 0; laser < 2; ++laser) {
      board->SetLaser(laser, true);
      EXPECT_TRUE(emu.Laser(laser));
      light.push_back(board->ReadLightSensor(1));
      board->SetLaser(laser, false);
      const std::string t = std::to_string(laser + 1);
      expected.insert(expected.end(), {"M71T" + t, "M50T1", "M70T" + t});
    }
  }
  light.push_back(board->ReadLightSensor(1));
  expected.push_back("M50T1");
  EXPECT_EQ(emu.CommandLog(), expected);
  EXPECT_EQ(light.size(), 11u);
  for (std::size_t k = 0; k + 1 < light.size(); ++k) EXPECT_EQ(light[k], 120 + 300) << k;  // one laser on
  EXPECT_EQ(light.back(), 120);                                                            // all off
  EXPECT_DOUBLE_EQ(emu.FeedRate(), 200);
  EXPECT_DOUBLE_EQ(emu.Acceleration(), 300);
  EXPECT_TRUE(emu.MotorEnabled());
  EXPECT_EQ(board->TransportStats().retries, 0);
  board.reset();  // leaves the scanner safe: lasers off, motor released
  const std::vector<std::string> log = emu.CommandLog();
  EXPECT_EQ(std::vector<std::string>(log.end() - 3, log.end()),
            (std::vector<std::string>{"M70T1", "M70T2", "M18"}));
  EXPECT_FALSE(emu.MotorEnabled());
}

TEST_F(HorusBoardTest, StallIsClearedAndRetried) {
  EmulatedHorusBoard emu;
  UsbContext context;
  const std::unique_ptr<HorusBoard> board = OpenHorusBoard(context, Fast());
  emu.StallOnce(0x04);  // bulk OUT
  board->MoveTo(10);
  EXPECT_DOUBLE_EQ(emu.Angle(), 10);
  EXPECT_EQ(emu.ClearHalts(), 1);
  emu.StallOnce(0x83);  // bulk IN
  EXPECT_EQ(board->ReadLightSensor(2), 120);
  EXPECT_EQ(emu.ClearHalts(), 2);
  const UsbDevice::Stats stats = board->TransportStats();
  EXPECT_EQ(stats.stalls_cleared, 2);
  EXPECT_EQ(stats.retries, 2);
  // The stalled write did not reach the firmware: each command ran once.
  EXPECT_EQ(emu.CommandLog(), (std::vector<std::string>{"^X", "G1X10", "M50T2"}));
}

TEST_F(HorusBoardTest, SilentBoardTimesOutAfterTheRetries) {
  EmulatedHorusBoard emu;
  UsbContext context;
  const std::unique_ptr<HorusBoard> board = OpenHorusBoard(context, Fast());
  emu.SetUnresponsive(true);
  std::string message;
  EXPECT_EQ(KindOf([&] { board->SetLaser(1, true); }, &message), DeviceError::Kind::kTimeout);
  EXPECT_NE(message.find("2341:0043"), std::string::npos) << message;
  EXPECT_NE(message.find("bus 1, address 5"), std::string::npos) << message;
  EXPECT_NE(message.find("command 'M71T2'"), std::string::npos) << message;
  EXPECT_NE(message.find("3 attempts of 400 ms"), std::string::npos) << message;
  const UsbDevice::Stats stats = board->TransportStats();
  EXPECT_EQ(stats.timeouts, 3);
  EXPECT_EQ(stats.retries, 2);
}

TEST_F(HorusBoardTest, SilentAtOpenTimesOutWaitingForTheBanner) {
  EmulatedHorusBoard emu;
  emu.SetUnresponsive(true);
  UsbContext context;
  std::string message;
  EXPECT_EQ(KindOf([&] { OpenHorusBoard(context, Fast()); }, &message), DeviceError::Kind::kTimeout);
  EXPECT_NE(message.find("reset (Ctrl-X), waiting for the Horus banner"), std::string::npos) << message;
  EXPECT_NE(message.find("3 attempts of 500 ms"), std::string::npos) << message;
  EXPECT_EQ(emu.Resets(), 1);  // the reset reached the board; its answer did not come back
}

TEST_F(HorusBoardTest, VanishingMidScanKeepsWhatWasDone) {
  EmulatedHorusBoard emu;
  UsbContext context;
  std::unique_ptr<HorusBoard> board = OpenHorusBoard(context, Fast());
  board->EnableMotor(true);
  // Each step is two commands (move, light reading); the board goes after 1 + 2 * 3 commands: step 3 fails.
  emu.VanishAfterCommands(1 + 2 * 3);
  std::vector<double> acquired;
  std::string message;
  const DeviceError::Kind kind = KindOf(
      [&] {
        for (int step = 0; step < 8; ++step) {
          board->MoveTo(45.0 * step);
          board->ReadLightSensor(1);
          acquired.push_back(45.0 * step);
        }
      },
      &message);
  EXPECT_EQ(kind, DeviceError::Kind::kDisconnected);
  EXPECT_EQ(acquired, (std::vector<double>{0, 45, 90}));
  EXPECT_NE(message.find("disconnected"), std::string::npos) << message;
  EXPECT_NE(message.find("command 'G1X135'"), std::string::npos) << message;
  EXPECT_NE(message.find("2341:0043"), std::string::npos) << message;
  board.reset();  // must not hang or throw on a gone device
}

TEST_F(HorusBoardTest, UnpluggedBetweenStepsIsDisconnected) {
  EmulatedHorusBoard emu;
  UsbContext context;
  const std::unique_ptr<HorusBoard> board = OpenHorusBoard(context, Fast());
  board->MoveTo(10);
  emu.Vanish();  // removed from sysfs as well
  std::string message;
  EXPECT_EQ(KindOf([&] { board->MoveTo(20); }, &message), DeviceError::Kind::kDisconnected);
  EXPECT_DOUBLE_EQ(emu.Angle(), 10);
}

TEST_F(HorusBoardTest, NoPermissionGivesTheUdevRule) {
  EmulatedHorusBoard emu;
  UsbContext context;
  emu.DenyAccess(true);
  std::string message;
  DeviceError::Kind kind;
  {
    test::ScopedNoDacOverride unprivileged;  // file modes bind root too while this lives
    if (!unprivileged.ok())
      GTEST_SKIP() << "cannot drop CAP_DAC_OVERRIDE here, so file modes cannot deny access";
    kind = KindOf([&] { OpenHorusBoard(context, Fast()); }, &message);
  }
  EXPECT_EQ(kind, DeviceError::Kind::kPermission);
  {
    test::ScopedNoDacOverride unprivileged;
    const std::vector<UsbDeviceInfo> listed = ListSupportedDevices(context);
    ASSERT_EQ(listed.size(), 1u);  // enumeration needs no access (sysfs); its strings do
    EXPECT_FALSE(listed[0].accessible);
    EXPECT_EQ(listed[0].product, "");
    EXPECT_NE(listed[0].open_error.find(UdevRuleFor(0x2341, 0x0043)), std::string::npos)
        << listed[0].open_error;
  }
  EXPECT_NE(message.find(UdevRuleFor(0x2341, 0x0043)), std::string::npos) << message;
  EXPECT_NE(message.find("opening: no permission"), std::string::npos) << message;
  EXPECT_NE(message.find("/etc/udev/rules.d/60-scan2model.rules"), std::string::npos) << message;
  emu.DenyAccess(false);
  EXPECT_EQ(OpenHorusBoard(context, Fast())->Banner(), "Horus 0.1 ['$' for help]");
}

TEST_F(HorusBoardTest, BusyInterfaceSaysWhoToAsk) {
  EmulatedHorusBoard emu;
  UsbContext context;
  emu.SetBusy(true);
  std::string message;
  EXPECT_EQ(KindOf([&] { OpenHorusBoard(context, Fast()); }, &message), DeviceError::Kind::kBusy);
  EXPECT_NE(message.find("claiming interface 0"), std::string::npos) << message;
  EXPECT_NE(message.find("another program has claimed it"), std::string::npos) << message;
  EXPECT_NE(message.find("2341:0043"), std::string::npos) << message;
  emu.SetBusy(false);
  EXPECT_NO_THROW(OpenHorusBoard(context, Fast()));
}

TEST_F(HorusBoardTest, BusyKernelDriverIsNamed) {
  EmulatedHorusBoard emu;
  UsbContext context;
  emu.SetBusy(true, "cdc_acm");
  std::string message;
  EXPECT_EQ(KindOf([&] { OpenHorusBoard(context, Fast()); }, &message), DeviceError::Kind::kBusy);
  EXPECT_NE(message.find("the kernel driver cdc_acm holds it"), std::string::npos) << message;
  EXPECT_NE(message.find("/sys/bus/usb/drivers/cdc_acm/unbind"), std::string::npos) << message;
  EXPECT_NE(message.find("fuser -v /dev/ttyACM*"), std::string::npos) << message;
}

TEST_F(HorusBoardTest, WrongBannerIsAProtocolError) {
  EmulatedHorusBoard::Options o;
  o.banner = "Grbl 0.9j ['$' for help]";
  EmulatedHorusBoard emu(o);
  UsbContext context;
  std::string message;
  EXPECT_EQ(KindOf([&] { OpenHorusBoard(context, Fast()); }, &message), DeviceError::Kind::kProtocol);
  EXPECT_NE(message.find("read 'Grbl 0.9j ['$' for help]' instead of 'Horus 0.1 ['$' for help]'"),
            std::string::npos)
      << message;
}

TEST_F(HorusBoardTest, ResetRecoversTheSettings) {
  EmulatedHorusBoard emu;
  UsbContext context;
  const std::unique_ptr<HorusBoard> board = OpenHorusBoard(context, Fast());
  board->SetFeedRate(50);
  board->SetAcceleration(200);
  board->EnableMotor(true);
  board->SetLaser(0, true);
  board->MoveTo(30);
  board->Reset();
  EXPECT_EQ(emu.Resets(), 2);
  EXPECT_FALSE(emu.Laser(0));  // the firmware's reset turns lasers off
  EXPECT_DOUBLE_EQ(emu.FeedRate(), 50);
  EXPECT_DOUBLE_EQ(emu.Acceleration(), 200);
  EXPECT_TRUE(emu.MotorEnabled());
  board->MoveTo(40);
  EXPECT_DOUBLE_EQ(emu.Angle(), 40);
  const std::vector<std::string> log = emu.CommandLog();
  EXPECT_EQ(std::vector<std::string>(log.begin() + 6, log.end()),
            (std::vector<std::string>{"^X", "G1F50", "$120=200", "M17", "G1X40"}));
}

TEST_F(HorusBoardTest, NotFoundNamesWhatWasSearched) {
  EmulatedHorusBoard emu;
  UsbContext context;
  HorusBoardOptions o = Fast();
  o.serial_number = "OTHER";
  std::string message;
  EXPECT_EQ(KindOf([&] { OpenHorusBoard(context, o); }, &message), DeviceError::Kind::kNotFound);
  EXPECT_NE(message.find("serial number 'OTHER'"), std::string::npos) << message;
  o.serial_number.clear();
  o.vendor_id = 0x1a86;
  o.product_id = 0x7523;
  EXPECT_EQ(KindOf([&] { OpenHorusBoard(context, o); }, &message), DeviceError::Kind::kNotFound);
  EXPECT_NE(message.find("1a86:7523"), std::string::npos) << message;
  o.vendor_id = 0x2341;  // explicit id, any product
  o.product_id = 0;
  o.serial_number = "EMU0001";
  EXPECT_EQ(OpenHorusBoard(context, o)->Device().address, 5);
}

TEST_F(HorusBoardTest, HotplugReportsArrivalAndRemoval) {
  EmulatedHorusBoard::Options o;
  o.plugged = false;
  EmulatedHorusBoard emu(o);
  UsbContext context;
  ASSERT_TRUE(context.HotplugSupported());
  std::mutex mutex;
  std::condition_variable cv;
  std::vector<std::pair<std::uint16_t, bool>> events;
  const int id = context.AddHotplugCallback([&](const UsbDeviceInfo& d, bool arrived) {
    std::lock_guard<std::mutex> lock(mutex);
    events.emplace_back(d.vendor_id, arrived);
    cv.notify_all();
  });
  ASSERT_GE(id, 0);
  emu.Plug();
  {
    std::unique_lock<std::mutex> lock(mutex);
    cv.wait_for(lock, std::chrono::seconds(10), [&] { return !events.empty(); });
    ASSERT_EQ(events.size(), 1u);
    EXPECT_EQ(events[0], std::make_pair(std::uint16_t{0x2341}, true));
  }
  emu.Vanish();
  {
    std::unique_lock<std::mutex> lock(mutex);
    cv.wait_for(lock, std::chrono::seconds(10), [&] { return events.size() >= 2; });
    ASSERT_EQ(events.size(), 2u);
    EXPECT_EQ(events[1], std::make_pair(std::uint16_t{0x2341}, false));
  }
  context.RemoveHotplugCallback(id);
}

}  // namespace
}  // namespace s2m
