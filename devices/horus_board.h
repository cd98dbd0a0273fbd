#pragma once
// The Horus turntable board (issue 6): an Arduino-class board running the Horus firmware (bq's Grbl fork for
// the Ciclop scanner), driven over its USB CDC-ACM bulk endpoints through libusb (devices/usb_transport.h).
//
// Protocol (the Horus application's driver, horus/engine/driver/board.py, and the firmware's G-code set):
// 115200 8N1; commands are ASCII lines ending "\r\n" ("G1X90", "M71T1"); every command is acknowledged by a
// line "ok" (an "error:..." line refuses it); M50 answers a number line before its "ok". Ctrl-X (0x18) resets
// the firmware, which then prints an empty line and the banner "Horus 0.1 ['$' for help]".

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "devices/horus_interfaces.h"
#include "devices/usb_transport.h"

namespace s2m {

struct HorusBoardOptions {
  // Which board: vendor_id 0 tries every connected Arduino-class CDC-ACM board (SupportedUsbIds()) and takes
  // the first that answers the Horus banner; product_id 0: any product of the vendor.
  std::uint16_t vendor_id = 0;
  std::uint16_t product_id = 0;
  std::string serial_number;  // empty: any; else the USB serial number string must equal it
  std::uint32_t baud_rate = 115200;
  int timeout_ms = 1000;         // per read or write attempt of a command
  int retries = 2;               // further attempts after a timeout or a stall
  int banner_timeout_ms = 3000;  // after a reset (an Uno's bootloader waits about 2 s before the sketch runs)
  int move_timeout_ms = 20000;   // a G1 X move answers when it is done: up to 360 degrees at a slow feed rate
  // Banners accepted at open and after Reset().
  std::vector<std::string> banners = {"Horus 0.1 ['$' for help]", "Horus 0.2 ['$' for help]"};
};

// The driver. Every call sends one command and waits for its acknowledgement; failures throw DeviceError
// naming the device and the command. After a reset the board's settings are sent again (motor, feed rate,
// acceleration; lasers are off after a reset, as the firmware leaves them).
class HorusBoard : public TurntableBoard {
 public:
  ~HorusBoard() override;
  std::string Banner() const override;
  void EnableMotor(bool on) override;
  void SetFeedRate(double degrees_per_second) override;
  void SetAcceleration(double degrees_per_second2) override;
  void MoveTo(double absolute_degrees) override;
  void SetLaser(int laser, bool on) override;
  int ReadLightSensor(int sensor) override;
  void Reset() override;

  // Sends a raw command line (without "\r\n") and returns the lines before its "ok".
  std::vector<std::string> Command(const std::string& command, int timeout_ms = -1);
  const UsbDeviceInfo& Device() const;
  UsbDevice::Stats TransportStats() const;

  struct Impl;
  explicit HorusBoard(std::unique_ptr<Impl> impl);

 private:
  std::unique_ptr<Impl> impl_;
};

// Finds, opens and handshakes the board (throws DeviceError: kNotFound with hints when no candidate is
// connected, kPermission with the udev rule, kBusy, kProtocol when the banner is wrong, kTimeout...).
std::unique_ptr<TurntableBoard> OpenHorusBoard(const HorusBoardOptions& options = {});
std::unique_ptr<HorusBoard> OpenHorusBoard(UsbContext& context, const HorusBoardOptions& options = {});

// A number in a G-code word: at most 3 decimals, no trailing zeros ("10", "12.5", "-0.125").
std::string GcodeNumber(double value);

}  // namespace s2m
