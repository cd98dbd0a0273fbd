#pragma once
// An emulated Horus turntable board on an emulated USB bus (umockdev, as libusb's own tests/umockdev.c does):
// a sysfs device (descriptors of an Arduino Uno: CDC comm interface 0, CDC data interface 1 with bulk
// endpoints 0x04 OUT and 0x83 IN) and an ioctl handler answering the usbfs ioctls libusb's Linux backend
// sends (USBDEVFS_GET_CAPABILITIES, CLAIMINTERFACE, DISCONNECT_CLAIM, SUBMITURB/REAPURBNDELAY/DISCARDURB,
// CLEAR_HALT...). Behind the endpoints runs a small Horus firmware: banner on Ctrl-X, "ok" for each command,
// motor angle, lasers and light sensor. Faults on demand: a stalled endpoint, silence, the device vanishing,
// no permission, a busy interface.
//
// Needs the umockdev preload library (tests run under `umockdev-wrapper`, see tests/CMakeLists.txt): check
// InMockEnvironment() first. One instance at a time per process (umockdev has one testbed per process).

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

namespace s2m::test {

class EmulatedHorusBoard {
 public:
  struct Options {
    std::uint16_t vendor_id = 0x2341, product_id = 0x0043;  // Arduino Uno R3
    int bus = 1, address = 5;
    std::string manufacturer = "Arduino (www.arduino.cc)";
    std::string product = "Horus turntable (emulated)";
    std::string serial_number = "EMU0001";
    std::string banner = "Horus 0.1 ['$' for help]";
    int light_base = 120;  // M50 answers light_base + light_per_laser * (lasers on)
    int light_per_laser = 300;
    bool plugged = true;  // false: Plug() later (hotplug tests)
  };

  EmulatedHorusBoard();
  explicit EmulatedHorusBoard(const Options& options);
  ~EmulatedHorusBoard();
  EmulatedHorusBoard(const EmulatedHorusBoard&) = delete;
  EmulatedHorusBoard& operator=(const EmulatedHorusBoard&) = delete;

  // True when the umockdev preload library is active (else libusb would see the real bus).
  static bool InMockEnvironment();

  void Plug();  // adds the device (a udev "add" event)

  // Faults.
  void StallOnce(
      std::uint8_t endpoint);         // the next URB on this endpoint fails with -EPIPE until a CLEAR_HALT
  void SetUnresponsive(bool silent);  // bulk IN never completes (the firmware hangs)
  void VanishAfterCommands(int n);    // after n command lines the device is gone (-ENODEV everywhere)
  void Vanish();                      // gone now, and removed from sysfs (a udev "remove" event)
  void DenyAccess(bool deny);         // device node mode 0000 (root also needs CAP_DAC_OVERRIDE dropped)
  // Claiming an interface fails with -EBUSY: another program owns it, or (kernel_driver not empty) a kernel
  // driver that would not let go (USBDEVFS_GETDRIVER and sysfs name it).
  void SetBusy(bool busy, const std::string& kernel_driver = "");

  // What the firmware saw and did.
  std::vector<std::string> CommandLog() const;  // lines as received, without "\r\n"; "^X" for a reset
  double Angle() const;
  bool Laser(int index) const;  // 0: T1
  bool MotorEnabled() const;
  double FeedRate() const;
  double Acceleration() const;
  int ClearHalts() const;
  int Resets() const;
  std::uint32_t BaudRate() const;          // from SET_LINE_CODING
  int DataBits() const;                    // from SET_LINE_CODING
  std::uint16_t ControlLineState() const;  // from SET_CONTROL_LINE_STATE (bit 0 DTR, bit 1 RTS)
  std::string DeviceNode() const;          // /dev/bus/usb/BBB/DDD
  std::string SysfsPath() const;

  struct Impl;

 private:
  std::unique_ptr<Impl> impl_;
};

// Drops CAP_DAC_OVERRIDE and CAP_DAC_READ_SEARCH from this thread's effective set while alive, so that file
// modes apply to root too (the permission test); restores them after. No-op when not root.
class ScopedNoDacOverride {
 public:
  ScopedNoDacOverride();
  ~ScopedNoDacOverride();
  ScopedNoDacOverride(const ScopedNoDacOverride&) = delete;
  ScopedNoDacOverride& operator=(const ScopedNoDacOverride&) = delete;
  bool ok() const { return ok_; }

 private:
  bool ok_ = false, changed_ = false;
  std::uint32_t saved_[2] = {0, 0};
};

}  // namespace s2m::test
