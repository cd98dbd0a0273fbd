#pragma once
// A Horus scanner's parts from a device string (issue 6, docs/horus-scan.md): the real board (libusb,
// devices/horus_board.h) with an OpenCV/V4L2 camera (devices/opencv_camera.h), or the virtual rig rendering a
// model (devices/virtual_horus.h). Each part is built only when its library is (libusb, OpenCV, Open3D);
// asking for one that is not throws DeviceError naming what the build lacks. Nothing here includes OpenCV or
// libusb.

#include <memory>
#include <optional>
#include <string>

#include "devices/horus_interfaces.h"

namespace s2m {

struct HorusRig {
  std::unique_ptr<TurntableBoard> board;
  std::unique_ptr<ImageCamera> camera;
  std::optional<HorusCalibration> truth;  // the virtual rig's calibration, true by construction
  std::string description_json;           // the recording's device description
  std::shared_ptr<void> keep_alive;       // whatever board and camera share (the virtual scene)
};

// "horus[,camera=/dev/video0,vid=0x2341,pid=0x0043,serial=...,width=1280,height=960,exposure=...,
//  timeout_ms=...]": the real scanner (vid/pid in hex with 0x or decimal; no vid: every supported
// Arduino-class board is tried; camera default /dev/video0).
// "horus-virtual:<scene>[,key=value...]": the virtual rig (scene and keys as ParseVirtualHorus takes them),
// plus unplug_at_move=N: the board is disconnected on its N-th move (0-based), to try a scan's disconnect and
// resume. Throws std::invalid_argument for a malformed string, DeviceError when a part cannot be opened or is
// not built.
HorusRig OpenHorusRig(const std::string& device_spec);

// True for "horus" and "horus-virtual:..." strings (what OpenHorusRig accepts).
bool IsHorusDeviceSpec(const std::string& device_spec);

}  // namespace s2m
