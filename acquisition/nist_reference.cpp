#include "acquisition/nist_reference.h"

#include <cmath>

#include "acquisition/format_error.h"
#include "acquisition/formats/readers.h"
#include "acquisition/formats/text_util.h"

namespace s2m {
namespace {
constexpr double kDegree = M_PI / 180.0;
Eigen::Vector3d Vec(const std::vector<double>& v, std::size_t i) {
  return {v[i], v[i + 1], v[i + 2]};
}
}  // namespace

std::vector<double> ReadNistFitValues(const std::filesystem::path& path, std::size_t expected) {
  const std::string file = path.string();
  const std::string bytes = formats::ReadFileBytes(file);
  formats::LineReader lines(bytes);
  formats::Line line;
  std::vector<std::string_view> tok;
  std::vector<double> values;
  while (lines.Next(line)) {
    formats::Tokenize(line.text, tok);
    for (const auto t : tok) {
      double v;
      if (!formats::ParseDouble(t, v))
        throw FormatError(file, AtLine(line.number), "not a number: " + formats::Quoted(t));
      if (!std::isfinite(v)) throw FormatError(file, AtLine(line.number), "value is not finite");
      values.push_back(v);
    }
  }
  if (values.size() != expected) {
    throw FormatError(file, "",
                      "expected " + std::to_string(expected) + " numbers for this reference fit, found " +
                          std::to_string(values.size()));
  }
  return values;
}

Plane ReadNistPlaneFit(const std::filesystem::path& path) {
  const auto v = ReadNistFitValues(path, 6);
  return {Vec(v, 0), Vec(v, 3).normalized()};
}

Sphere ReadNistSphereFit(const std::filesystem::path& path) {
  const auto v = ReadNistFitValues(path, 4);
  return {Vec(v, 0), v[3] / 2.0};
}

Cylinder ReadNistCylinderFit(const std::filesystem::path& path) {
  const auto v = ReadNistFitValues(path, 7);
  return {Vec(v, 0), Vec(v, 3).normalized(), v[6] / 2.0};
}

Cone ReadNistConeFit(const std::filesystem::path& path) {
  const auto v = ReadNistFitValues(path, 8);
  const double half_angle = v[7] * kDegree / 2.0;
  return {Vec(v, 0), Vec(v, 3).normalized(), half_angle, v[6] / std::cos(half_angle)};
}

std::vector<double> ToNistLayout(const Plane& s) {
  return {s.point.x(), s.point.y(), s.point.z(), s.normal.x(), s.normal.y(), s.normal.z()};
}
std::vector<double> ToNistLayout(const Sphere& s) {
  return {s.center.x(), s.center.y(), s.center.z(), 2.0 * s.radius};
}
std::vector<double> ToNistLayout(const Cylinder& s) {
  return {s.axis_point.x(),     s.axis_point.y(),     s.axis_point.z(), s.axis_direction.x(),
          s.axis_direction.y(), s.axis_direction.z(), 2.0 * s.radius};
}
std::vector<double> ToNistLayout(const Cone& s) {
  return {s.axis_point.x(),
          s.axis_point.y(),
          s.axis_point.z(),
          s.axis_direction.x(),
          s.axis_direction.y(),
          s.axis_direction.z(),
          s.SurfaceDistanceFromAxisPoint(),
          2.0 * s.half_angle / kDegree};
}

std::vector<double> ToNistLayout(const Line3d& s) {
  return {s.point.x(), s.point.y(), s.point.z(), s.direction.x(), s.direction.y(), s.direction.z()};
}
std::vector<double> ToNistLayout(const Circle3d& s) {
  return {s.center.x(), s.center.y(), s.center.z(), s.normal.x(), s.normal.y(), s.normal.z(), 2.0 * s.radius};
}
std::vector<double> ToNistLayout(const Torus& s) {
  return {s.center.x(), s.center.y(), s.center.z(),         s.axis.x(),
          s.axis.y(),   s.axis.z(),   2.0 * s.major_radius, 2.0 * s.minor_radius};
}

}  // namespace s2m
