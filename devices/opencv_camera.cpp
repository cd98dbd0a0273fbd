// OpenCV (V4L2) and image-file cameras: devices/opencv_camera.h.

#include "devices/opencv_camera.h"

#include <algorithm>
#include <cctype>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <opencv2/videoio.hpp>

namespace s2m {
namespace {

Image8 FromMat(const cv::Mat& mat) {
  cv::Mat m = mat;
  if (m.depth() != CV_8U) m.convertTo(m, CV_8U);
  if (m.channels() == 4) cv::cvtColor(m, m, cv::COLOR_BGRA2BGR);
  if (!m.isContinuous()) m = m.clone();
  Image8 image;
  image.width = m.cols;
  image.height = m.rows;
  image.channels = m.channels();
  image.pixels.assign(m.data, m.data + m.total() * m.elemSize());
  return image;
}

class OpenCvCamera : public ImageCamera {
 public:
  OpenCvCamera(std::string device, const OpenCvCameraOptions& options)
      : device_(std::move(device)), options_(options) {
    const bool index = !device_.empty() && std::all_of(device_.begin(), device_.end(),
                                                       [](unsigned char c) { return std::isdigit(c) != 0; });
    const bool opened =
        index ? capture_.open(std::stoi(device_), cv::CAP_V4L2) : capture_.open(device_, cv::CAP_V4L2);
    if (!opened || !capture_.isOpened())
      throw DeviceError(
          DeviceError::Kind::kNotFound,
          "camera '" + device_ +
              "' could not be opened through V4L2 (is it plugged in? `v4l2-ctl --list-devices` lists "
              "cameras; your user needs to be in the 'video' group)");
    if (options_.width > 0) capture_.set(cv::CAP_PROP_FRAME_WIDTH, options_.width);
    if (options_.height > 0) capture_.set(cv::CAP_PROP_FRAME_HEIGHT, options_.height);
    if (options_.exposure >= 0) {
      capture_.set(cv::CAP_PROP_AUTO_EXPOSURE, 1);  // V4L2: 1 = manual
      capture_.set(cv::CAP_PROP_EXPOSURE, options_.exposure);
    }
    cv::Mat first;
    if (!capture_.read(first) || first.empty())
      throw DeviceError(
          DeviceError::Kind::kNotFound,
          "camera '" + device_ + "' opened but delivered no frame (in use by another program?)");
  }

  std::string Name() const override { return "opencv:" + device_; }

  Image8 Capture() override {
    cv::Mat frame;
    // grab() dequeues a buffer without decoding it: the stale ones are dropped cheaply.
    for (int i = 0; i < options_.flush_frames; ++i) capture_.grab();
    if (!capture_.read(frame) || frame.empty())
      throw DeviceError(DeviceError::Kind::kDisconnected,
                        "camera '" + device_ + "' stopped delivering frames (unplugged?)");
    return FromMat(frame);
  }

 private:
  std::string device_;
  OpenCvCameraOptions options_;
  cv::VideoCapture capture_;
};

class ImageFileCamera : public ImageCamera {
 public:
  explicit ImageFileCamera(std::vector<std::filesystem::path> files) : files_(std::move(files)) {
    if (files_.empty()) throw DeviceError(DeviceError::Kind::kNotFound, "image camera: no image files given");
    for (const auto& f : files_)
      if (!std::filesystem::is_regular_file(f))
        throw DeviceError(DeviceError::Kind::kNotFound, "image camera: '" + f.string() + "' does not exist");
  }
  std::string Name() const override { return "images:" + files_.front().parent_path().string(); }
  Image8 Capture() override {
    if (next_ >= files_.size())
      throw DeviceError(DeviceError::Kind::kDisconnected,
                        "image camera: all " + std::to_string(files_.size()) + " images were used");
    return ReadImagePng(files_[next_++]);
  }

 private:
  std::vector<std::filesystem::path> files_;
  std::size_t next_ = 0;
};

}  // namespace

std::unique_ptr<ImageCamera> OpenOpenCvCamera(const std::string& device, const OpenCvCameraOptions& options) {
  return std::make_unique<OpenCvCamera>(device, options);
}

std::unique_ptr<ImageCamera> OpenImageFileCamera(std::vector<std::filesystem::path> files) {
  return std::make_unique<ImageFileCamera>(std::move(files));
}

std::unique_ptr<ImageCamera> OpenImageDirectoryCamera(const std::filesystem::path& directory) {
  if (!std::filesystem::is_directory(directory))
    throw DeviceError(DeviceError::Kind::kNotFound,
                      "image camera: '" + directory.string() + "' is not a directory");
  std::vector<std::filesystem::path> files;
  for (const auto& e : std::filesystem::directory_iterator(directory))
    if (e.is_regular_file() && e.path().extension() == ".png") files.push_back(e.path());
  std::sort(files.begin(), files.end());
  if (files.empty())
    throw DeviceError(DeviceError::Kind::kNotFound,
                      "image camera: no .png files in '" + directory.string() + "'");
  return OpenImageFileCamera(std::move(files));
}

Image8 ReadImagePng(const std::filesystem::path& path) {
  const cv::Mat m = cv::imread(path.string(), cv::IMREAD_UNCHANGED);
  if (m.empty()) throw std::runtime_error("'" + path.string() + "' is not a readable image");
  return FromMat(m);
}

void WriteImagePng(const Image8& image, const std::filesystem::path& path) {
  if (image.channels != 1 && image.channels != 3)
    throw std::invalid_argument("'" + path.string() + "': only 1- or 3-channel images are written");
  const cv::Mat m(image.height, image.width, image.channels == 1 ? CV_8UC1 : CV_8UC3,
                  const_cast<std::uint8_t*>(image.pixels.data()));
  bool ok = false;
  try {
    ok = cv::imwrite(path.string(), m);
  } catch (const cv::Exception&) {
    ok = false;
  }
  if (!ok) throw std::runtime_error("could not write the image '" + path.string() + "'");
}

}  // namespace s2m
