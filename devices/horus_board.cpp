// Horus board driver over CDC-ACM (devices/horus_board.h). CDC requests: USB CDC PSTN subclass 1.2,
// section 6.3.10 SET_LINE_CODING (7 bytes: dwDTERate, bCharFormat, bParityType, bDataBits) and 6.3.12
// SET_CONTROL_LINE_STATE (wValue bit 0 DTR, bit 1 RTS).

#include "devices/horus_board.h"

#include <chrono>
#include <cmath>
#include <cstdio>
#include <stdexcept>

namespace s2m {
namespace {

constexpr std::uint8_t kCdcRequestType = 0x21;  // host to device, class, interface
constexpr std::uint8_t kSetLineCoding = 0x20;
constexpr std::uint8_t kSetControlLineState = 0x22;
constexpr std::uint16_t kDtrRts = 0x03;
constexpr char kCtrlX = 0x18;

bool IsBannerLike(const std::string& line) {
  return line.find("['$' for help]") != std::string::npos;
}

std::string Quote(const std::string& s) {
  std::string out = "'";
  for (const char c : s) {
    if (c >= 0x20 && c < 0x7f) {
      out += c;
    } else {
      char buf[8];
      std::snprintf(buf, sizeof(buf), "\\x%02x", static_cast<unsigned char>(c));
      out += buf;
    }
  }
  return out + "'";
}

}  // namespace

std::string GcodeNumber(double value) {
  char buf[64];
  std::snprintf(buf, sizeof(buf), "%.3f", value);
  std::string s = buf;
  while (!s.empty() && s.back() == '0') s.pop_back();
  if (!s.empty() && s.back() == '.') s.pop_back();
  if (s == "-0") s = "0";
  return s;
}

struct HorusBoard::Impl {
  std::unique_ptr<UsbDevice> device;
  UsbDevice::CdcAcmEndpoints endpoints;
  HorusBoardOptions options;
  std::string banner;
  std::string pending;  // bytes read after the last complete line
  bool healthy = true;  // false after a disconnection or timeout: the destructor does not talk to the board
  // What Reset() restores (the firmware forgets it).
  bool motor_on = false;
  double feed_rate = NAN, acceleration = NAN;

  std::string What(const std::string& command) const { return "command " + Quote(command); }

  void Write(const std::string& text, const std::string& what) {
    device->BulkWrite(endpoints.bulk_out, std::vector<std::uint8_t>(text.begin(), text.end()), what);
  }

  // The next line (without "\r\n"), reading as needed; throws kTimeout (after the transport's retries).
  std::string ReadLine(const std::string& what, int timeout_ms) {
    for (;;) {
      const std::size_t eol = pending.find('\n');
      if (eol != std::string::npos) {
        std::string line = pending.substr(0, eol);
        pending.erase(0, eol + 1);
        while (!line.empty() && (line.back() == '\r' || line.back() == '\n')) line.pop_back();
        return line;
      }
      const std::vector<std::uint8_t> got = device->BulkRead(endpoints.bulk_in, 64, what, timeout_ms);
      pending.append(got.begin(), got.end());
    }
  }

  // Throws away what the board sent before (a banner after the DTR reset of an Uno, stale replies).
  void Drain() {
    for (int k = 0; k < 64; ++k) {
      if (device->BulkReadAvailable(endpoints.bulk_in, 64, 20, "draining input").empty()) break;
    }
    pending.clear();
  }

  template <class F>
  auto Guard(F f) {
    try {
      return f();
    } catch (const DeviceError& e) {
      if (e.kind() == DeviceError::Kind::kDisconnected || e.kind() == DeviceError::Kind::kTimeout)
        healthy = false;
      throw;
    }
  }

  std::vector<std::string> Command(const std::string& command, int timeout_ms) {
    return Guard([&] {
      const std::string what = What(command);
      Write(command + "\r\n", what);
      std::vector<std::string> lines;
      for (;;) {
        const std::string line = ReadLine(what, timeout_ms);
        if (line == "ok") return lines;
        if (line.rfind("error", 0) == 0) {
          throw DeviceError(DeviceError::Kind::kProtocol,
                            device->Info().Name() + ": " + what + ": the board refused it: " + Quote(line));
        }
        if (line.empty() || IsBannerLike(line)) continue;  // a late banner, blank lines
        lines.push_back(line);
      }
    });
  }

  // Ctrl-X, then the banner (Grbl prints "\r\n" and the banner on reset).
  void ResetAndCheckBanner() {
    Guard([&] {
      const std::string what = "reset (Ctrl-X), waiting for the Horus banner";
      Write(std::string(1, kCtrlX) + "\r\n", what);
      const auto start = std::chrono::steady_clock::now();
      for (;;) {
        const std::string line = ReadLine(what, options.banner_timeout_ms);
        if (line.empty() || line == "ok") {
          if (std::chrono::steady_clock::now() - start >
              std::chrono::milliseconds(4 * options.banner_timeout_ms)) {
            break;
          }
          continue;
        }
        for (const std::string& b : options.banners) {
          if (line == b) {
            banner = line;
            return;
          }
        }
        throw DeviceError(DeviceError::Kind::kProtocol,
                          device->Info().Name() + ": " + what + ": read " + Quote(line) + " instead of " +
                              Quote(options.banners.front()) +
                              ". Is the Horus firmware flashed on this board? (Horus: Firmware > Upload)");
      }
      throw DeviceError(DeviceError::Kind::kProtocol,
                        device->Info().Name() + ": " + what + ": only blank lines came back, no banner");
    });
    pending.clear();
  }
};

HorusBoard::HorusBoard(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}

HorusBoard::~HorusBoard() {
  if (!impl_ || !impl_->healthy) return;
  // Leave the scanner safe, as Horus does on disconnect: lasers off, motor released. Best effort.
  try {
    impl_->Command("M70T1", impl_->options.timeout_ms);
    impl_->Command("M70T2", impl_->options.timeout_ms);
    impl_->Command("M18", impl_->options.timeout_ms);
  } catch (const DeviceError&) {
  }
}

std::string HorusBoard::Banner() const {
  return impl_->banner;
}

std::vector<std::string> HorusBoard::Command(const std::string& command, int timeout_ms) {
  return impl_->Command(command, timeout_ms);
}

const UsbDeviceInfo& HorusBoard::Device() const {
  return impl_->device->Info();
}
UsbDevice::Stats HorusBoard::TransportStats() const {
  return impl_->device->GetStats();
}

void HorusBoard::EnableMotor(bool on) {
  impl_->Command(on ? "M17" : "M18", -1);
  impl_->motor_on = on;
}

void HorusBoard::SetFeedRate(double degrees_per_second) {
  impl_->Command("G1F" + GcodeNumber(degrees_per_second), -1);
  impl_->feed_rate = degrees_per_second;
}

void HorusBoard::SetAcceleration(double degrees_per_second2) {
  impl_->Command("$120=" + GcodeNumber(degrees_per_second2), -1);
  impl_->acceleration = degrees_per_second2;
}

void HorusBoard::MoveTo(double absolute_degrees) {
  impl_->Command("G1X" + GcodeNumber(absolute_degrees), impl_->options.move_timeout_ms);
}

void HorusBoard::SetLaser(int laser, bool on) {
  if (laser < 0 || laser > 1) {
    throw std::invalid_argument("Horus board: laser " + std::to_string(laser) + " does not exist (0 or 1)");
  }
  impl_->Command(std::string(on ? "M71T" : "M70T") + std::to_string(laser + 1), -1);
}

int HorusBoard::ReadLightSensor(int sensor) {
  const std::string command = "M50T" + std::to_string(sensor);
  const std::vector<std::string> lines = impl_->Command(command, -1);
  for (const std::string& line : lines) {
    try {
      std::size_t used = 0;
      const int value = std::stoi(line, &used);
      if (used == line.size()) return value;
    } catch (const std::exception&) {
    }
  }
  throw DeviceError(DeviceError::Kind::kProtocol, Device().Name() + ": " + impl_->What(command) +
                                                      ": no number in the reply (" +
                                                      std::to_string(lines.size()) + " lines before 'ok')");
}

void HorusBoard::Reset() {
  impl_->ResetAndCheckBanner();
  // Recovery: the firmware restarted with its defaults; send back what the caller had set.
  if (!std::isnan(impl_->feed_rate)) SetFeedRate(impl_->feed_rate);
  if (!std::isnan(impl_->acceleration)) SetAcceleration(impl_->acceleration);
  if (impl_->motor_on) EnableMotor(true);
}

namespace {

std::unique_ptr<HorusBoard> Handshake(UsbContext& context, const UsbDeviceInfo& info,
                                      const HorusBoardOptions& options) {
  UsbDevice::Options transfer;
  transfer.timeout_ms = options.timeout_ms;
  transfer.retries = options.retries;
  auto impl = std::make_unique<HorusBoard::Impl>();
  impl->options = options;
  impl->device = context.Open(info, transfer);
  impl->endpoints = impl->device->FindCdcAcm();
  const UsbDevice::CdcAcmEndpoints& ep = impl->endpoints;
  if (ep.comm_interface < 0 || ep.data_interface < 0 || ep.bulk_in == 0 || ep.bulk_out == 0) {
    throw DeviceError(DeviceError::Kind::kProtocol,
                      info.Name() + ": no CDC-ACM interface with bulk endpoints: not an Arduino-class board");
  }
  impl->device->ClaimInterface(ep.comm_interface);
  impl->device->ClaimInterface(ep.data_interface);
  const std::uint32_t baud = options.baud_rate;
  std::vector<std::uint8_t> coding = {static_cast<std::uint8_t>(baud & 0xff),
                                      static_cast<std::uint8_t>((baud >> 8) & 0xff),
                                      static_cast<std::uint8_t>((baud >> 16) & 0xff),
                                      static_cast<std::uint8_t>((baud >> 24) & 0xff),
                                      0,   // 1 stop bit
                                      0,   // no parity
                                      8};  // 8 data bits
  const auto comm = static_cast<std::uint16_t>(ep.comm_interface);
  impl->device->Control(kCdcRequestType, kSetLineCoding, 0, comm, coding, "SET_LINE_CODING 115200 8N1");
  std::vector<std::uint8_t> none;
  impl->device->Control(kCdcRequestType, kSetControlLineState, kDtrRts, comm, none,
                        "SET_CONTROL_LINE_STATE (DTR, RTS)");
  impl->Drain();
  impl->ResetAndCheckBanner();
  return std::make_unique<HorusBoard>(std::move(impl));
}

}  // namespace

std::unique_ptr<HorusBoard> OpenHorusBoard(UsbContext& context, const HorusBoardOptions& options) {
  const std::vector<UsbDeviceInfo> all = context.Enumerate();
  std::vector<UsbDeviceInfo> candidates;
  std::vector<std::string> converters;  // known serial converters we cannot drive over libusb
  for (const UsbDeviceInfo& d : all) {
    if (options.vendor_id != 0) {
      if (d.vendor_id != options.vendor_id ||
          (options.product_id != 0 && d.product_id != options.product_id)) {
        continue;
      }
    } else {
      if (d.supported_as.empty()) continue;
      if (!d.has_cdc_acm) {
        converters.push_back(d.Name() + " (" + d.supported_as + ")");
        continue;
      }
    }
    if (!options.serial_number.empty() && d.serial_number != options.serial_number) continue;
    candidates.push_back(d);
  }
  if (candidates.empty()) {
    std::string msg = "no Horus board found";
    if (options.vendor_id != 0) {
      char id[16];
      std::snprintf(id, sizeof(id), "%04x:%04x", options.vendor_id, options.product_id);
      msg += std::string(" with id ") + id + (options.product_id == 0 ? " (any product)" : "");
    }
    if (!options.serial_number.empty()) msg += " with serial number '" + options.serial_number + "'";
    msg += " among " + std::to_string(all.size()) + " USB devices.";
    for (const std::string& c : converters) {
      msg += " Found " + c + ": its serial converter is not CDC-ACM, which this driver needs;";
    }
    msg += " Check the cable and the board's power, and run `scan2model devices` (docs/devices.md)";
    throw DeviceError(DeviceError::Kind::kNotFound, msg);
  }
  std::string failures;
  for (std::size_t k = 0; k < candidates.size(); ++k) {
    try {
      return Handshake(context, candidates[k], options);
    } catch (const DeviceError& e) {
      if (candidates.size() == 1) throw;
      failures += std::string("\n  ") + e.what();
      if (k + 1 == candidates.size()) {
        throw DeviceError(e.kind(), "no candidate answered as a Horus board:" + failures);
      }
    }
  }
  throw DeviceError(DeviceError::Kind::kNotFound, "no Horus board found");
}

std::unique_ptr<TurntableBoard> OpenHorusBoard(const HorusBoardOptions& options) {
  UsbContext context;  // the board's device keeps libusb alive after this goes out of scope
  return OpenHorusBoard(context, options);
}

}  // namespace s2m
