#include "devices/horus_rig.h"

#include <nlohmann/json.hpp>
#include <optional>
#include <sstream>
#include <stdexcept>
#include <vector>

#ifdef S2M_HAVE_USB
#include "devices/horus_board.h"
#endif
#ifdef S2M_HAVE_HORUS_OPENCV
#include "devices/opencv_camera.h"
#endif
#ifdef S2M_HAVE_VIRTUAL_HORUS
#include "devices/virtual_horus.h"
#endif

namespace s2m {
namespace {

using nlohmann::json;
constexpr const char* kVirtualPrefix = "horus-virtual:";

std::vector<std::string> Split(const std::string& s, char by) {
  std::vector<std::string> out;
  std::stringstream in(s);
  std::string item;
  while (std::getline(in, item, by)) out.push_back(item);
  return out;
}

[[maybe_unused]] long Number(const std::string& key, const std::string& value, int base = 10) {
  try {
    std::size_t used = 0;
    const long v = std::stol(value, &used, base);
    if (used == value.size()) return v;
  } catch (const std::exception&) {
  }
  throw std::invalid_argument("device horus: " + key + "=" + value + " is not a number");
}

// 0x2341 or 9025.
[[maybe_unused]] double Real(const std::string& key, const std::string& value) {
  try {
    std::size_t used = 0;
    const double v = std::stod(value, &used);
    if (used == value.size()) return v;
  } catch (const std::exception&) {
  }
  throw std::invalid_argument("device horus: " + key + "=" + value + " is not a number");
}

[[maybe_unused]] long UsbId(const std::string& key, const std::string& value) {
  const bool hex = value.rfind("0x", 0) == 0 || value.rfind("0X", 0) == 0;
  const long v = Number(key, hex ? value.substr(2) : value, hex ? 16 : 10);
  if (v < 0 || v > 0xFFFF)
    throw std::invalid_argument("device horus: " + key + "=" + value + " is not a USB id");
  return v;
}

HorusRig OpenRealRig(const std::string& spec) {
  const std::vector<std::string> parts = Split(spec, ',');
  std::string camera = "/dev/video0";
  json description = {{"name", "horus"}};
#ifdef S2M_HAVE_USB
  HorusBoardOptions board_options;
#endif
#ifdef S2M_HAVE_HORUS_OPENCV
  OpenCvCameraOptions camera_options;
#endif
  for (std::size_t k = 1; k < parts.size(); ++k) {
    const std::size_t eq = parts[k].find('=');
    if (eq == std::string::npos)
      throw std::invalid_argument("device horus: '" + parts[k] + "' is not key=value");
    const std::string key = parts[k].substr(0, eq), value = parts[k].substr(eq + 1);
    if (key == "camera") {
      camera = value;
      continue;
    }
#ifdef S2M_HAVE_USB
    if (key == "vid") {
      board_options.vendor_id = static_cast<std::uint16_t>(UsbId(key, value));
      continue;
    }
    if (key == "pid") {
      board_options.product_id = static_cast<std::uint16_t>(UsbId(key, value));
      continue;
    }
    if (key == "serial") {
      board_options.serial_number = value;
      continue;
    }
    if (key == "timeout_ms") {
      board_options.timeout_ms = static_cast<int>(Number(key, value));
      continue;
    }
#endif
#ifdef S2M_HAVE_HORUS_OPENCV
    if (key == "width") {
      camera_options.width = static_cast<int>(Number(key, value));
      continue;
    }
    if (key == "height") {
      camera_options.height = static_cast<int>(Number(key, value));
      continue;
    }
    if (key == "exposure") {
      camera_options.exposure = Real(key, value);
      continue;
    }
#endif
    throw std::invalid_argument("device horus: unknown key '" + key +
                                "' (camera, vid, pid, serial, timeout_ms, width, height, exposure)");
  }
  HorusRig rig;
#ifdef S2M_HAVE_USB
  rig.board = OpenHorusBoard(board_options);
  description["board"] = rig.board->Banner();
  if (const auto* horus = dynamic_cast<const HorusBoard*>(rig.board.get())) {
    const UsbDeviceInfo& usb = horus->Device();
    description["usb"] = {{"device", usb.Name()},
                          {"manufacturer", usb.manufacturer},
                          {"product", usb.product},
                          {"serial", usb.serial_number}};
  }
#else
  throw DeviceError(
      DeviceError::Kind::kOther,
      "device horus: the board driver is not built (libusb-1.0 was not found when scan2model was "
      "built; install libusb-1.0-0-dev and rebuild)");
#endif
#ifdef S2M_HAVE_HORUS_OPENCV
  rig.camera = OpenOpenCvCamera(camera, camera_options);
  description["camera"] = camera;
#else
  throw DeviceError(DeviceError::Kind::kOther,
                    "device horus: the camera is not built (OpenCV was not found when scan2model was built; "
                    "install libopencv-dev and rebuild)");
#endif
  rig.description_json = description.dump();
  return rig;
}

#ifdef S2M_HAVE_VIRTUAL_HORUS
// The virtual board, unplugged on its n-th move (0-based): that move and every later call throw
// kDisconnected, as a real board whose cable is pulled. For trying (and testing) the scan's disconnect and
// resume end to end.
class UnpluggedBoard : public TurntableBoard {
 public:
  UnpluggedBoard(std::unique_ptr<TurntableBoard> board, long at_move)
      : board_(std::move(board)), at_(at_move) {}
  std::string Banner() const override { return board_->Banner(); }
  void EnableMotor(bool on) override {
    Check();
    board_->EnableMotor(on);
  }
  void SetFeedRate(double v) override {
    Check();
    board_->SetFeedRate(v);
  }
  void SetAcceleration(double v) override {
    Check();
    board_->SetAcceleration(v);
  }
  void MoveTo(double degrees) override {
    Check();
    if (moves_++ == at_) {
      gone_ = true;
      Check();
    }
    board_->MoveTo(degrees);
  }
  void SetLaser(int laser, bool on) override {
    Check();
    board_->SetLaser(laser, on);
  }
  int ReadLightSensor(int sensor) override {
    Check();
    return board_->ReadLightSensor(sensor);
  }
  void Reset() override {
    Check();
    board_->Reset();
  }

 private:
  void Check() const {
    if (gone_)
      throw DeviceError(DeviceError::Kind::kDisconnected,
                        "horus-virtual board: disconnected (unplug_at_move=" + std::to_string(at_) + ")");
  }
  std::unique_ptr<TurntableBoard> board_;
  long at_;
  long moves_ = 0;
  bool gone_ = false;
};
#endif

HorusRig OpenVirtualRig(const std::string& full_spec) {
#ifdef S2M_HAVE_VIRTUAL_HORUS
  // Our own key, unplug_at_move=N, is taken out before the rest goes to the virtual rig.
  std::optional<long> unplug_at;
  std::string spec;
  for (const std::string& part : Split(full_spec, ',')) {
    if (part.rfind("unplug_at_move=", 0) == 0) {
      unplug_at = Number("unplug_at_move", part.substr(15));
    } else {
      spec += (spec.empty() ? "" : ",") + part;
    }
  }
  VirtualHorus v = MakeVirtualHorus(spec);
  HorusRig rig;
  rig.board = std::move(v.board);
  if (unplug_at) rig.board = std::make_unique<UnpluggedBoard>(std::move(rig.board), *unplug_at);
  rig.camera = std::move(v.camera);
  rig.truth = v.truth;
  rig.keep_alive = v.rig;
  rig.description_json = json{{"name", spec.substr(0, spec.find(','))}, {"spec", spec}}.dump();
  return rig;
#else
  throw DeviceError(DeviceError::Kind::kOther,
                    "device " + full_spec +
                        ": the virtual Horus rig is not built (it needs OpenCV and Open3D when scan2model is "
                        "built)");
#endif
}

}  // namespace

bool IsHorusDeviceSpec(const std::string& spec) {
  return spec.rfind(kVirtualPrefix, 0) == 0 || spec == "horus" || spec.rfind("horus,", 0) == 0;
}

HorusRig OpenHorusRig(const std::string& spec) {
  if (spec.rfind(kVirtualPrefix, 0) == 0) return OpenVirtualRig(spec);
  if (spec == "horus" || spec.rfind("horus,", 0) == 0) return OpenRealRig(spec);
  throw std::invalid_argument(
      "unknown device '" + spec +
      "' (horus[,camera=/dev/video0,vid=...,pid=...] or horus-virtual:<scene>[,...])");
}

}  // namespace s2m
