// `scan2model devices`: the connected devices scan2model can drive (docs/devices.md): USB boards through
// libusb (Horus turntable boards: Arduino-class CDC-ACM, plus the serial converters we recognise) and
// cameras, listed as their V4L2 nodes (/dev/video*).

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <nlohmann/json.hpp>
#include <string>
#include <system_error>
#include <vector>

#include "apps/commands.h"

#ifdef S2M_HAVE_USB
#include "devices/usb_transport.h"
#endif

namespace s2m::app {
namespace {

std::string Hex4(unsigned v) {
  char buf[8];
  std::snprintf(buf, sizeof(buf), "%04x", v & 0xffffu);
  return buf;
}

// V4L2 device nodes, sorted (video0 before video10).
std::vector<std::string> VideoNodes() {
  std::vector<std::string> nodes;
  std::error_code ec;
  for (std::filesystem::directory_iterator it("/dev", ec), end; !ec && it != end; it.increment(ec)) {
    const std::string name = it->path().filename().string();
    if (name.rfind("video", 0) == 0 && name.size() > 5 &&
        std::all_of(name.begin() + 5, name.end(), [](char c) { return c >= '0' && c <= '9'; })) {
      nodes.push_back(it->path().string());
    }
  }
  std::sort(nodes.begin(), nodes.end(), [](const std::string& a, const std::string& b) {
    return a.size() != b.size() ? a.size() < b.size() : a < b;
  });
  return nodes;
}

int ListDevices(bool json) {
  nlohmann::json usb = nlohmann::json::array();
  std::string usb_error;
#ifdef S2M_HAVE_USB
  try {
    for (const UsbDeviceInfo& d : ListSupportedDevices()) {
      usb.push_back({{"bus", d.bus},
                     {"address", d.address},
                     {"vendor_id", Hex4(d.vendor_id)},
                     {"product_id", Hex4(d.product_id)},
                     {"manufacturer", d.manufacturer},
                     {"product", d.product},
                     {"serial_number", d.serial_number},
                     {"supported_as", d.supported_as},
                     {"cdc_acm", d.has_cdc_acm},
                     {"accessible", d.accessible},
                     // What drives it: the Horus board driver needs CDC-ACM (docs/devices.md).
                     {"driver", d.has_cdc_acm ? "horus" : "none"}});
      if (!d.accessible) usb.back()["open_error"] = d.open_error;
    }
  } catch (const std::exception& e) {
    usb_error = e.what();
  }
#else
  usb_error = "USB support was not built (libusb-1.0-0-dev was missing at build time)";
#endif
  const std::vector<std::string> cameras = VideoNodes();
  std::vector<std::string> hints;
  if (usb.empty()) {
    hints = {"connect the scanner's board by USB and check its power",
             "run `lsusb`: the board shows as an Arduino (2341:xxxx), CH340 (1a86:7523) or FTDI (0403:xxxx) "
             "device",
             "if it is listed there but not here, its USB id is not a known one: see docs/devices.md"};
  }
  if (cameras.empty()) hints.push_back("no camera: check `v4l2-ctl --list-devices` (package v4l-utils)");
  if (json) {
    nlohmann::json j = {
        {"schema", "scan2model.devices/1"}, {"usb", usb}, {"cameras", nlohmann::json::array()}};
    for (const std::string& c : cameras) j["cameras"].push_back({{"node", c}});
    if (!usb_error.empty()) j["usb_error"] = usb_error;
    j["hints"] = hints;
    std::cout << j.dump(2) << "\n";
    return kOk;
  }
  if (usb.empty())
    std::cout << (cameras.empty() ? "no supported device found\n" : "no supported USB device found\n");
  if (!usb_error.empty()) std::cout << "USB: cannot list devices: " << usb_error << "\n";
  for (const nlohmann::json& d : usb) {
    std::cout << "usb     " << d["vendor_id"].get<std::string>() << ":" << d["product_id"].get<std::string>()
              << "  bus " << d["bus"] << " address " << d["address"] << "  "
              << d["supported_as"].get<std::string>();
    const std::string product = d["product"], manufacturer = d["manufacturer"], serial = d["serial_number"];
    if (!product.empty() || !manufacturer.empty())
      std::cout << "  '" << manufacturer << " " << product << "'";
    if (!serial.empty()) std::cout << "  serial " << serial;
    if (!d["cdc_acm"].get<bool>()) std::cout << "  (not CDC-ACM: the Horus driver cannot use it)";
    std::cout << "\n";
    if (!d["accessible"].get<bool>()) std::cout << "        " << d["open_error"].get<std::string>() << "\n";
  }
  for (const std::string& c : cameras) std::cout << "camera  " << c << "\n";
  for (const std::string& h : hints) std::cout << "hint: " << h << "\n";
  return kOk;
}

}  // namespace

Runner AddDevicesCommand(CLI::App& app) {
  auto json = std::make_shared<bool>(false);
  CLI::App* cmd = app.add_subcommand(
      "devices", "List connected scanner devices: USB turntable boards (Horus) and cameras (/dev/video*)");
  cmd->add_flag("--json", *json, "Machine-readable output (schema scan2model.devices/1, docs/devices.md)");
  return [json]() { return ListDevices(*json); };
}

}  // namespace s2m::app
