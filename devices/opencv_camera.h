#pragma once
// Cameras for the Horus scanner (issue 6) behind the ImageCamera interface of devices/horus_interfaces.h: a
// USB (UVC) camera through OpenCV's V4L2 backend at run time, and a camera replaying image files in order,
// for tests and for calibration sets captured earlier. OpenCV appears only in devices/opencv_camera.cpp.

#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include "devices/horus_interfaces.h"

namespace s2m {

struct OpenCvCameraOptions {
  int width = 1280, height = 960;  // requested frame size (Ciclop's Logitech C270: 1280 x 960); 0: driver's
  // Manual exposure in the V4L2 driver's units (for UVC cameras: 100 microseconds), or < 0: leave the
  // driver's automatic exposure alone. Laser-line scanning wants a short fixed exposure so the line does not
  // saturate.
  double exposure = -1.0;
  // Frames read and dropped before the one returned by Capture: V4L2 keeps a queue of buffers (usually 4)
  // filled before the call, so a frame returned right after a turntable move or a laser switch could show the
  // state before it. 0 disables the flush.
  int flush_frames = 4;
};

// Opens "0" (an index) or "/dev/videoN" with OpenCV's V4L2 backend. Throws DeviceError (kNotFound) naming the
// device when it cannot be opened or delivers no first frame; Capture throws DeviceError (kDisconnected) when
// a read fails later (the camera was unplugged).
std::unique_ptr<ImageCamera> OpenOpenCvCamera(const std::string& device, const OpenCvCameraOptions& options);

// A camera returning the given image files (PNG, or anything OpenCV reads) one per Capture, in order. Throws
// DeviceError (kNotFound) when the list is empty or a file is missing; Capture throws DeviceError
// (kDisconnected) after the last image, FormatError-like std::runtime_error naming a file that cannot be
// decoded.
std::unique_ptr<ImageCamera> OpenImageFileCamera(std::vector<std::filesystem::path> files);

// The same for every *.png in `directory`, sorted by name.
std::unique_ptr<ImageCamera> OpenImageDirectoryCamera(const std::filesystem::path& directory);

// PNG reading and writing of Image8 (3 channels BGR or 1 channel grey). Read throws std::runtime_error naming
// the file; Write throws naming the file when it cannot be written.
Image8 ReadImagePng(const std::filesystem::path& path);
void WriteImagePng(const Image8& image, const std::filesystem::path& path);

}  // namespace s2m
