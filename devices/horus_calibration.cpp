// Horus calibration: devices/horus_calibration.h.

#include "devices/horus_calibration.h"

#include <Eigen/Geometry>
#include <Eigen/SVD>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>
#include <stdexcept>

#include "devices/laser_line.h"
#include "devices/opencv_camera.h"

namespace s2m {
namespace {

// ------------------------------------------------------------------------------------------------ JSON

const nlohmann::json& Field(const nlohmann::json& j, const char* key, const std::string& where) {
  if (!j.is_object() || !j.contains(key))
    throw std::invalid_argument(where + ": missing field '" + key + "'");
  return j.at(key);
}

double Number(const nlohmann::json& j, const char* key, const std::string& where) {
  const nlohmann::json& v = Field(j, key, where);
  if (!v.is_number() || !std::isfinite(v.get<double>()))
    throw std::invalid_argument(where + ": field '" + key + "' is not a finite number");
  return v.get<double>();
}

std::vector<double> Numbers(const nlohmann::json& v, std::size_t n, const std::string& where) {
  if (!v.is_array() || v.size() != n)
    throw std::invalid_argument(where + " is not an array of " + std::to_string(n) + " numbers");
  std::vector<double> out;
  for (const auto& x : v) {
    if (!x.is_number() || !std::isfinite(x.get<double>()))
      throw std::invalid_argument(where + " is not an array of " + std::to_string(n) + " finite numbers");
    out.push_back(x.get<double>());
  }
  return out;
}

// ------------------------------------------------------------------------------------------- geometry

cv::Mat ToGrey(const Image8& image) {
  cv::Mat m(image.height, image.width, image.channels == 1 ? CV_8UC1 : CV_8UC3,
            const_cast<std::uint8_t*>(image.pixels.data()));
  cv::Mat grey;
  if (image.channels == 1)
    grey = m.clone();
  else
    cv::cvtColor(m, grey, cv::COLOR_BGR2GRAY);
  return grey;
}

cv::Matx33d CameraMatrix(const CameraIntrinsics& k) {
  return {k.fx, 0, k.cx, 0, k.fy, k.cy, 0, 0, 1};
}

// Least-squares plane through points (the smallest singular vector of the centred points): normal, centroid.
struct PlaneFit {
  Eigen::Vector3d normal, centroid;
  double rms = 0, second_singular = 0;
};
PlaneFit FitPlane(const Eigen::Matrix3Xd& p) {
  PlaneFit f;
  f.centroid = p.rowwise().mean();
  const Eigen::Matrix3Xd c = p.colwise() - f.centroid;
  Eigen::JacobiSVD<Eigen::Matrix3Xd> svd(c, Eigen::ComputeFullU);
  f.normal = svd.matrixU().col(2);
  f.rms = std::sqrt((f.normal.transpose() * c).squaredNorm() / static_cast<double>(p.cols()));
  f.second_singular = svd.singularValues()(1) / std::sqrt(static_cast<double>(p.cols()));
  return f;
}

}  // namespace

nlohmann::json HorusCalibrationToJson(const HorusCalibration& c) {
  nlohmann::json j;
  j["camera"] = {{"width", c.camera.width},
                 {"height", c.camera.height},
                 {"fx", c.camera.fx},
                 {"fy", c.camera.fy},
                 {"cx", c.camera.cx},
                 {"cy", c.camera.cy},
                 {"distortion", c.camera.distortion}};
  j["lasers"] = nlohmann::json::array();
  for (const LaserPlane& l : c.lasers)
    j["lasers"].push_back({{"normal", {l.normal.x(), l.normal.y(), l.normal.z()}}, {"distance", l.distance}});
  const Eigen::Matrix4d m = c.platform_T_camera.matrix();
  nlohmann::json rows = nlohmann::json::array();
  for (int r = 0; r < 4; ++r) rows.push_back({m(r, 0), m(r, 1), m(r, 2), m(r, 3)});
  j["platform_T_camera"] = rows;
  j["units"] = "mm";
  return j;
}

HorusCalibration HorusCalibrationFromJson(const nlohmann::json& j, const std::string& what) {
  HorusCalibration c;
  if (!j.is_object()) throw std::invalid_argument(what + ": a Horus calibration must be a JSON object");
  const std::string cam = what + ": camera";
  const nlohmann::json& camera = Field(j, "camera", what);
  const double width = Number(camera, "width", cam), height = Number(camera, "height", cam);
  if (width < 1 || height < 1 || width != std::floor(width) || height != std::floor(height))
    throw std::invalid_argument(cam + ": width and height must be positive integers");
  c.camera.width = static_cast<int>(width);
  c.camera.height = static_cast<int>(height);
  c.camera.fx = Number(camera, "fx", cam);
  c.camera.fy = Number(camera, "fy", cam);
  c.camera.cx = Number(camera, "cx", cam);
  c.camera.cy = Number(camera, "cy", cam);
  if (c.camera.fx <= 0 || c.camera.fy <= 0) throw std::invalid_argument(cam + ": fx and fy must be positive");
  const std::vector<double> d = Numbers(Field(camera, "distortion", cam), 5, cam + ".distortion");
  std::copy(d.begin(), d.end(), c.camera.distortion.begin());
  const nlohmann::json& lasers = Field(j, "lasers", what);
  if (!lasers.is_array()) throw std::invalid_argument(what + ": 'lasers' is not an array");
  for (std::size_t i = 0; i < lasers.size(); ++i) {
    const std::string where = what + ": lasers[" + std::to_string(i) + "]";
    const std::vector<double> n = Numbers(Field(lasers[i], "normal", where), 3, where + ".normal");
    LaserPlane p;
    p.normal = Eigen::Vector3d(n[0], n[1], n[2]);
    if (std::abs(p.normal.norm() - 1.0) > 1e-6)
      throw std::invalid_argument(where + ".normal is not a unit vector");
    p.distance = Number(lasers[i], "distance", where);
    c.lasers.push_back(p);
  }
  const nlohmann::json& rows = Field(j, "platform_T_camera", what);
  if (!rows.is_array() || rows.size() != 4)
    throw std::invalid_argument(what + ": platform_T_camera is not a 4x4 matrix (4 rows of 4 numbers)");
  Eigen::Matrix4d m;
  for (int r = 0; r < 4; ++r) {
    const std::vector<double> row =
        Numbers(rows[static_cast<std::size_t>(r)], 4, what + ": platform_T_camera row " + std::to_string(r));
    for (int k = 0; k < 4; ++k) m(r, k) = row[static_cast<std::size_t>(k)];
  }
  const Eigen::Matrix3d R = m.topLeftCorner<3, 3>();
  if ((R.transpose() * R - Eigen::Matrix3d::Identity()).norm() > 1e-6 || R.determinant() < 0)
    throw std::invalid_argument(what + ": platform_T_camera's rotation is not a rotation matrix");
  c.platform_T_camera = RigidMotion::FromMatrix(m);
  return c;
}

HorusCalibration HorusCalibrationFromDocument(const nlohmann::json& document, const std::string& what) {
  if (!document.is_object() || !document.contains("horus"))
    throw std::invalid_argument(what + ": no 'horus' calibration (run `scan2model calibrate`)");
  return HorusCalibrationFromJson(document.at("horus"), what + ": horus");
}

HorusCalibration ReadHorusCalibrationFile(const std::filesystem::path& path) {
  std::ifstream in(path);
  if (!in) throw std::runtime_error("calibration '" + path.string() + "' cannot be opened");
  try {
    return HorusCalibrationFromDocument(nlohmann::json::parse(in), "'" + path.string() + "'");
  } catch (const nlohmann::json::exception& e) {
    throw std::runtime_error("calibration '" + path.string() + "' is not JSON: " + e.what());
  } catch (const std::invalid_argument& e) {
    throw std::runtime_error(e.what());
  }
}

std::vector<Eigen::Vector3d> ChessboardPattern::ObjectPoints() const {
  std::vector<Eigen::Vector3d> p;
  for (int r = 0; r < rows; ++r)
    for (int c = 0; c < columns; ++c) p.emplace_back(c * square, r * square, 0.0);
  return p;
}

std::optional<std::vector<Eigen::Vector2d>> DetectChessboard(const Image8& image,
                                                             const ChessboardPattern& pattern) {
  if (image.width < 1 || image.height < 1) return std::nullopt;
  const cv::Mat grey = ToGrey(image);
  std::vector<cv::Point2f> corners;
  const cv::Size size(pattern.columns, pattern.rows);
  if (!cv::findChessboardCorners(
          grey, size, corners,
          cv::CALIB_CB_ADAPTIVE_THRESH | cv::CALIB_CB_NORMALIZE_IMAGE | cv::CALIB_CB_FAST_CHECK))
    return std::nullopt;
  cv::cornerSubPix(grey, corners, cv::Size(5, 5), cv::Size(-1, -1),
                   cv::TermCriteria(cv::TermCriteria::EPS | cv::TermCriteria::COUNT, 100, 1e-4));
  // (CALIB_CB_FAST_CHECK: images without a pattern are rejected quickly instead of after seconds of search.)
  // findChessboardCorners may return the grid turned by 180 degrees (its only ambiguity for columns != rows).
  if (corners.front().y + corners.front().x > corners.back().y + corners.back().x)
    std::reverse(corners.begin(), corners.end());
  std::vector<Eigen::Vector2d> out;
  for (const auto& c : corners) out.emplace_back(c.x, c.y);
  return out;
}

std::optional<RigidMotion> PatternPose(const Image8& image, const CameraIntrinsics& camera,
                                       const ChessboardPattern& pattern, double* rms_px) {
  const auto corners = DetectChessboard(image, pattern);
  if (!corners) return std::nullopt;
  std::vector<cv::Point3d> object;
  for (const auto& p : pattern.ObjectPoints()) object.emplace_back(p.x(), p.y(), p.z());
  std::vector<cv::Point2d> pixels;
  for (const auto& c : *corners) pixels.emplace_back(c.x(), c.y());
  const std::vector<double> distortion(camera.distortion.begin(), camera.distortion.end());
  cv::Mat rvec, tvec;
  if (!cv::solvePnP(object, pixels, CameraMatrix(camera), distortion, rvec, tvec, false,
                    cv::SOLVEPNP_ITERATIVE))
    return std::nullopt;
  cv::Mat R;
  cv::Rodrigues(rvec, R);
  Eigen::Matrix3d r;
  for (int i = 0; i < 3; ++i)
    for (int k = 0; k < 3; ++k) r(i, k) = R.at<double>(i, k);
  const RigidMotion camera_T_pattern(
      r, Eigen::Vector3d(tvec.at<double>(0), tvec.at<double>(1), tvec.at<double>(2)));
  if (rms_px) {
    double sum = 0;
    for (std::size_t i = 0; i < object.size(); ++i) {
      const Eigen::Vector2d q = ProjectToPixel(camera, camera_T_pattern * pattern.ObjectPoints()[i]);
      sum += (q - (*corners)[i]).squaredNorm();
    }
    *rms_px = std::sqrt(sum / static_cast<double>(object.size()));
  }
  return camera_T_pattern;
}

IntrinsicsEstimate CalibrateIntrinsics(const std::vector<Image8>& images, const ChessboardPattern& pattern) {
  IntrinsicsEstimate e;
  std::vector<std::vector<cv::Point3f>> object;
  std::vector<std::vector<cv::Point2f>> pixels;
  std::vector<cv::Point3f> board;
  for (const auto& p : pattern.ObjectPoints())
    board.emplace_back(static_cast<float>(p.x()), static_cast<float>(p.y()), static_cast<float>(p.z()));
  cv::Size size;
  for (std::size_t i = 0; i < images.size(); ++i) {
    if (i > 0 && (images[i].width != images[0].width || images[i].height != images[0].height))
      throw std::runtime_error("intrinsics calibration: image " + std::to_string(i) +
                               " differs in size from image 0");
    const auto corners = DetectChessboard(images[i], pattern);
    if (!corners) {
      e.rejected.push_back(static_cast<int>(i));
      continue;
    }
    std::vector<cv::Point2f> c;
    for (const auto& q : *corners) c.emplace_back(static_cast<float>(q.x()), static_cast<float>(q.y()));
    pixels.push_back(std::move(c));
    object.push_back(board);
    size = cv::Size(images[i].width, images[i].height);
  }
  e.images_used = static_cast<int>(pixels.size());
  if (e.images_used < 3)
    throw std::runtime_error(
        "intrinsics calibration: the " + std::to_string(pattern.columns) + "x" +
        std::to_string(pattern.rows) + " pattern was found in " + std::to_string(e.images_used) + " of " +
        std::to_string(images.size()) +
        " images; at least 3 are needed (move the pattern through varied, tilted poses)");
  cv::Mat K, dist;
  std::vector<cv::Mat> rvecs, tvecs;
  // k3 fixed at 0: webcams' lenses need k1, k2 (and p1, p2); a free k3 over-fits a few images.
  e.rms_px = cv::calibrateCamera(object, pixels, size, K, dist, rvecs, tvecs, cv::CALIB_FIX_K3);
  e.camera.width = size.width;
  e.camera.height = size.height;
  e.camera.fx = K.at<double>(0, 0);
  e.camera.fy = K.at<double>(1, 1);
  e.camera.cx = K.at<double>(0, 2);
  e.camera.cy = K.at<double>(1, 2);
  for (int i = 0; i < 5 && i < static_cast<int>(dist.total()); ++i)
    e.camera.distortion[i] = dist.at<double>(i);
  return e;
}

std::vector<PatternCapture> CapturePatternSweep(TurntableBoard& board, ImageCamera& camera,
                                                const std::vector<double>& angles_rad, int lasers,
                                                const CalibrationProgress& progress) {
  std::vector<PatternCapture> captures;
  for (int l = 0; l < lasers; ++l) board.SetLaser(l, false);
  board.EnableMotor(true);
  for (std::size_t k = 0; k < angles_rad.size(); ++k) {
    PatternCapture c;
    c.angle_rad = angles_rad[k];
    board.MoveTo(angles_rad[k] * 180.0 / M_PI);
    c.off = camera.Capture();
    for (int l = 0; l < lasers; ++l) {
      board.SetLaser(l, true);
      c.lasers.push_back(camera.Capture());
      board.SetLaser(l, false);
    }
    captures.push_back(std::move(c));
    if (progress)
      progress("pattern sweep: " + std::to_string(k + 1) + "/" + std::to_string(angles_rad.size()) + " at " +
               std::to_string(angles_rad[k] * 180.0 / M_PI) + " deg");
  }
  return captures;
}

std::vector<Image8> CaptureIntrinsicsImages(TurntableBoard& board, ImageCamera& camera, int count,
                                            const std::function<void(int)>& present_pose,
                                            const CalibrationProgress& progress) {
  board.SetLaser(0, false);
  board.SetLaser(1, false);
  std::vector<Image8> images;
  for (int k = 0; k < count; ++k) {
    if (present_pose) present_pose(k);
    images.push_back(camera.Capture());
    if (progress) progress("intrinsics: pattern pose " + std::to_string(k + 1) + "/" + std::to_string(count));
  }
  return images;
}

void WriteCalibrationImages(const std::filesystem::path& directory,
                            const std::vector<Image8>& intrinsics_images,
                            const std::vector<PatternCapture>& sweep, const ChessboardPattern& pattern) {
  std::error_code error;
  std::filesystem::create_directories(directory, error);
  if (error) throw std::runtime_error("cannot create '" + directory.string() + "': " + error.message());
  nlohmann::json j;
  j["format"] = "scan2model.horus_images/1";
  j["pattern"] = {{"columns", pattern.columns},
                  {"rows", pattern.rows},
                  {"square", pattern.square},
                  {"bottom_row_height", pattern.bottom_row_height}};
  j["intrinsics"] = nlohmann::json::array();
  char name[64];
  for (std::size_t k = 0; k < intrinsics_images.size(); ++k) {
    std::snprintf(name, sizeof name, "intrinsics_%03zu.png", k);
    WriteImagePng(intrinsics_images[k], directory / name);
    j["intrinsics"].push_back(name);
  }
  j["sweep"] = nlohmann::json::array();
  for (std::size_t k = 0; k < sweep.size(); ++k) {
    nlohmann::json stop = {{"angle_deg", sweep[k].angle_rad * 180.0 / M_PI}};
    std::snprintf(name, sizeof name, "sweep_%03zu_off.png", k);
    WriteImagePng(sweep[k].off, directory / name);
    stop["off"] = name;
    stop["lasers"] = nlohmann::json::array();
    for (std::size_t l = 0; l < sweep[k].lasers.size(); ++l) {
      std::snprintf(name, sizeof name, "sweep_%03zu_laser%zu.png", k, l);
      WriteImagePng(sweep[k].lasers[l], directory / name);
      stop["lasers"].push_back(name);
    }
    j["sweep"].push_back(stop);
  }
  const std::filesystem::path manifest = directory / "calibration_images.json";
  std::ofstream out(manifest);
  out << j.dump(2) << "\n";
  if (!out) throw std::runtime_error("cannot write '" + manifest.string() + "'");
}

CalibrationImages ReadCalibrationImages(const std::filesystem::path& directory) {
  const std::filesystem::path manifest = directory / "calibration_images.json";
  std::ifstream in(manifest);
  if (!in)
    throw std::runtime_error("'" + manifest.string() + "' does not exist (a calibration image set has one)");
  nlohmann::json j;
  try {
    j = nlohmann::json::parse(in);
  } catch (const nlohmann::json::exception& e) {
    throw std::runtime_error("'" + manifest.string() + "' is not JSON: " + e.what());
  }
  const std::string where = manifest.string();
  try {
    if (!j.is_object() || j.value("format", "") != "scan2model.horus_images/1")
      throw std::invalid_argument(where + ": not a scan2model.horus_images/1 document");
    CalibrationImages set;
    const nlohmann::json& p = Field(j, "pattern", where);
    set.pattern.columns = static_cast<int>(Number(p, "columns", where + ": pattern"));
    set.pattern.rows = static_cast<int>(Number(p, "rows", where + ": pattern"));
    set.pattern.square = Number(p, "square", where + ": pattern");
    set.pattern.bottom_row_height = Number(p, "bottom_row_height", where + ": pattern");
    auto image = [&](const nlohmann::json& name) {
      if (!name.is_string()) throw std::invalid_argument(where + ": an image name is not a string");
      return ReadImagePng(directory / name.get<std::string>());
    };
    for (const auto& name : Field(j, "intrinsics", where)) set.intrinsics_images.push_back(image(name));
    for (const auto& stop : Field(j, "sweep", where)) {
      PatternCapture c;
      c.angle_rad = Number(stop, "angle_deg", where + ": sweep") * M_PI / 180.0;
      c.off = image(Field(stop, "off", where + ": sweep"));
      for (const auto& name : Field(stop, "lasers", where + ": sweep")) c.lasers.push_back(image(name));
      set.sweep.push_back(std::move(c));
    }
    return set;
  } catch (const std::invalid_argument& e) {
    throw std::runtime_error(e.what());
  }
}

namespace {

// Per image row, the columns inside the pattern's board (its corners' grid grown by `margin` squares), from
// the projected quadrilateral: the extraction looks for the line only there.
void BoardColumns(const RigidMotion& camera_T_pattern, const CameraIntrinsics& camera,
                  const ChessboardPattern& pattern, double margin, int height, std::vector<int>& lo,
                  std::vector<int>& hi) {
  const double s = pattern.square, x1 = (pattern.columns - 1) * s, y1 = (pattern.rows - 1) * s;
  const double m = margin * s;
  std::vector<Eigen::Vector2d> poly;
  for (const Eigen::Vector3d& p : {Eigen::Vector3d(-m, -m, 0), Eigen::Vector3d(x1 + m, -m, 0),
                                   Eigen::Vector3d(x1 + m, y1 + m, 0), Eigen::Vector3d(-m, y1 + m, 0)})
    poly.push_back(ProjectToPixel(camera, camera_T_pattern * p));
  lo.assign(static_cast<std::size_t>(height), 1);
  hi.assign(static_cast<std::size_t>(height), 0);  // empty unless an edge crosses the row
  for (int row = 0; row < height; ++row) {
    double a = 1e300, b = -1e300;
    for (std::size_t e = 0; e < poly.size(); ++e) {
      const Eigen::Vector2d p = poly[e], q = poly[(e + 1) % poly.size()];
      if ((p.y() - row) * (q.y() - row) > 0 || p.y() == q.y()) continue;
      const double x = p.x() + (row - p.y()) / (q.y() - p.y()) * (q.x() - p.x());
      a = std::min(a, x);
      b = std::max(b, x);
    }
    if (a <= b) {
      lo[static_cast<std::size_t>(row)] = static_cast<int>(std::ceil(a));
      hi[static_cast<std::size_t>(row)] = static_cast<int>(std::floor(b));
    }
  }
}

}  // namespace

LaserPlanesEstimate CalibrateLaserPlanes(const std::vector<PatternCapture>& captures,
                                         const CameraIntrinsics& camera, const ChessboardPattern& pattern) {
  LaserPlanesEstimate e;
  const std::size_t lasers = captures.empty() ? 0 : captures.front().lasers.size();
  std::vector<std::vector<Eigen::Vector3d>> points(lasers);
  HorusCalibration on_pattern;
  on_pattern.camera = camera;
  for (const PatternCapture& c : captures) {
    const auto pose = PatternPose(c.off, camera, pattern);
    if (!pose) continue;
    ++e.poses_used;
    // The pattern's plane in the camera frame: normal R e_z, through t.
    LaserPlane plane;
    plane.normal = pose->rotation().col(2);
    plane.distance = plane.normal.dot(pose->translation());
    if (plane.distance < 0) plane.normal = -plane.normal, plane.distance = -plane.distance;
    on_pattern.lasers = {plane};
    LaserExtractionOptions options;
    BoardColumns(*pose, camera, pattern, 0.5, c.off.height, options.column_min, options.column_max);
    for (std::size_t l = 0; l < lasers && l < c.lasers.size(); ++l) {
      const Eigen::Matrix3Xd p =
          TriangulateLaserLine(ExtractLaserLine(c.lasers[l], c.off, options), on_pattern, 0);
      for (Eigen::Index i = 0; i < p.cols(); ++i) points[l].push_back(p.col(i));
    }
  }
  for (std::size_t l = 0; l < lasers; ++l) {
    const auto n = static_cast<Eigen::Index>(points[l].size());
    if (n < 10)
      throw std::runtime_error(
          "laser calibration: laser " + std::to_string(l) + " was seen on the pattern at " +
          std::to_string(n) + " points (the pattern was found in " + std::to_string(e.poses_used) + " of " +
          std::to_string(captures.size()) + " captures); check that the laser lights the pattern");
    Eigen::Matrix3Xd p(3, n);
    for (Eigen::Index i = 0; i < n; ++i) p.col(i) = points[l][static_cast<std::size_t>(i)];
    const PlaneFit fit = FitPlane(p);
    // Points on a single line do not fix a plane: the sweep must move the line across the pattern.
    if (fit.second_singular < 2.0)
      throw std::runtime_error("laser calibration: laser " + std::to_string(l) +
                               "'s points lie (nearly) on one line; turn the table through a wider range");
    LaserPlane plane{fit.normal, fit.normal.dot(fit.centroid)};
    if (plane.distance < 0) plane.normal = -plane.normal, plane.distance = -plane.distance;
    e.planes.push_back(plane);
    e.rms_mm.push_back(fit.rms);
    e.points.push_back(static_cast<int>(n));
  }
  return e;
}

TurntableAxisEstimate CalibrateTurntableAxis(const std::vector<PatternCapture>& captures,
                                             const CameraIntrinsics& camera,
                                             const ChessboardPattern& pattern) {
  TurntableAxisEstimate e;
  std::vector<RigidMotion> poses;
  for (const PatternCapture& c : captures)
    if (auto pose = PatternPose(c.off, camera, pattern)) poses.push_back(*pose);
  e.poses_used = static_cast<int>(poses.size());
  if (poses.size() < 3)
    throw std::runtime_error("turntable calibration: the pattern was found at " +
                             std::to_string(poses.size()) + " of " + std::to_string(captures.size()) +
                             " angles; at least 3 are needed");
  const std::vector<Eigen::Vector3d> object = pattern.ObjectPoints();
  const auto k = static_cast<Eigen::Index>(poses.size());
  std::vector<Eigen::Vector3d> centres, normals;
  std::vector<double> radii;
  double circle_sum = 0;
  Eigen::Index circle_count = 0;
  for (const Eigen::Vector3d& x : object) {
    Eigen::Matrix3Xd p(3, k);
    for (Eigen::Index i = 0; i < k; ++i) p.col(i) = poses[static_cast<std::size_t>(i)] * x;
    const PlaneFit plane = FitPlane(p);
    if (plane.second_singular < 1.0)
      throw std::runtime_error(
          "turntable calibration: the pattern hardly moved; turn the table through a wider range");
    // The circle in the plane: Kasa's algebraic fit (Kasa, IEEE Trans. Instrum. Meas. 25(1), 1976),
    // x^2 + y^2 + D x + E y + F = 0 solved in least squares; centre (-D/2, -E/2).
    Eigen::Vector3d u = plane.normal.unitOrthogonal(), v = plane.normal.cross(u);
    Eigen::MatrixXd A(k, 3);
    Eigen::VectorXd b(k);
    for (Eigen::Index i = 0; i < k; ++i) {
      const Eigen::Vector3d d = p.col(i) - plane.centroid;
      const double x2 = d.dot(u), y2 = d.dot(v);
      A.row(i) << x2, y2, 1.0;
      b(i) = -(x2 * x2 + y2 * y2);
    }
    const Eigen::Vector3d s = A.colPivHouseholderQr().solve(b);
    const Eigen::Vector3d centre = plane.centroid - 0.5 * s(0) * u - 0.5 * s(1) * v;
    const double radius = std::sqrt(std::max(0.0, 0.25 * (s(0) * s(0) + s(1) * s(1)) - s(2)));
    for (Eigen::Index i = 0; i < k; ++i) {
      const Eigen::Vector3d d = p.col(i) - centre;
      const double h = d.dot(plane.normal);
      const double r = (d - h * plane.normal).norm();
      circle_sum += h * h + (r - radius) * (r - radius);
      ++circle_count;
    }
    Eigen::Vector3d n = plane.normal;
    // z up: the camera's y axis points down in the image.
    if (n.y() > 0) n = -n;
    normals.push_back(n);
    centres.push_back(centre);
    radii.push_back(radius);
  }
  Eigen::Vector3d a = Eigen::Vector3d::Zero();
  for (const auto& n : normals) a += n;
  a.normalize();
  Eigen::Vector3d centre_mean = Eigen::Vector3d::Zero();
  for (const auto& c : centres) centre_mean += c;
  centre_mean /= static_cast<double>(centres.size());
  double centre_sum = 0;
  for (const auto& c : centres) {
    const Eigen::Vector3d d = c - centre_mean;
    centre_sum += (d - d.dot(a) * a).squaredNorm();
  }
  e.circle_rms_mm = std::sqrt(circle_sum / static_cast<double>(circle_count));
  e.centre_rms_mm = std::sqrt(centre_sum / static_cast<double>(centres.size()));
  // The table's surface: corner j (row r) stands bottom_row_height + (rows - 1 - r) square above it.
  Eigen::Vector3d origin = Eigen::Vector3d::Zero();
  for (std::size_t j = 0; j < centres.size(); ++j) {
    const int row = static_cast<int>(j) / pattern.columns;
    const double height = pattern.bottom_row_height + (pattern.rows - 1 - row) * pattern.square;
    const Eigen::Vector3d on_axis = centre_mean + (centres[j] - centre_mean).dot(a) * a;
    origin += on_axis - height * a;
  }
  origin /= static_cast<double>(centres.size());
  const Eigen::Vector3d x = (Eigen::Vector3d::UnitX() - a.x() * a).normalized();
  Eigen::Matrix3d camera_R_platform;
  camera_R_platform << x, a.cross(x), a;
  e.platform_T_camera = RigidMotion(camera_R_platform, origin).inverse();
  e.axis_direction_camera = a;
  e.axis_point_camera = origin;
  return e;
}

nlohmann::json HorusCalibrationReport::Summary() const {
  nlohmann::json j;
  j["intrinsics"] = {{"rms_px", intrinsics.rms_px},
                     {"images_used", intrinsics.images_used},
                     {"images_rejected", intrinsics.rejected}};
  j["lasers"] = nlohmann::json::array();
  for (std::size_t l = 0; l < lasers.planes.size(); ++l)
    j["lasers"].push_back({{"rms_mm", lasers.rms_mm[l]}, {"points", lasers.points[l]}});
  j["turntable"] = {{"circle_rms_mm", axis.circle_rms_mm},
                    {"centre_rms_mm", axis.centre_rms_mm},
                    {"poses_used", axis.poses_used}};
  return j;
}

HorusCalibrationReport CalibrateHorus(const std::vector<Image8>& intrinsics_images,
                                      const std::vector<PatternCapture>& sweep,
                                      const ChessboardPattern& pattern) {
  HorusCalibrationReport r;
  r.intrinsics = CalibrateIntrinsics(intrinsics_images, pattern);
  r.lasers = CalibrateLaserPlanes(sweep, r.intrinsics.camera, pattern);
  r.axis = CalibrateTurntableAxis(sweep, r.intrinsics.camera, pattern);
  r.calibration.camera = r.intrinsics.camera;
  r.calibration.lasers = r.lasers.planes;
  r.calibration.platform_T_camera = r.axis.platform_T_camera;
  return r;
}

}  // namespace s2m
