#include "apps/output.h"

#include <sstream>

namespace s2m::app {

nlohmann::json ToJson(const Eigen::Vector3d& v) {
  return nlohmann::json::array({v.x(), v.y(), v.z()});
}

nlohmann::json ToJson(const Eigen::Matrix4d& m) {
  nlohmann::json rows = nlohmann::json::array();
  for (int r = 0; r < 4; ++r) rows.push_back({m(r, 0), m(r, 1), m(r, 2), m(r, 3)});
  return rows;
}

std::string Format(double value, int digits) {
  std::ostringstream s;
  s.precision(digits);
  s << value;
  return s.str();
}

std::string Format(const Eigen::Vector3d& v, int digits) {
  return "(" + Format(v.x(), digits) + ", " + Format(v.y(), digits) + ", " + Format(v.z(), digits) + ")";
}

nlohmann::json DescribeScan(const Scan& scan, const std::string& file, const std::string& format) {
  const Bounds b = ComputeBounds(scan.points);
  nlohmann::json j;
  j["file"] = file;
  j["format"] = format;
  j["points"] = scan.size();
  j["has_normals"] = scan.has_normals();
  j["has_weights"] = scan.has_weights();
  j["units"] = scan.units;
  j["bounds"] = {{"min", ToJson(b.min)},
                 {"max", ToJson(b.max)},
                 {"extent", ToJson(b.extent())},
                 {"diagonal", b.diagonal()}};
  j["centroid"] = ToJson(Eigen::Vector3d(scan.points.rowwise().mean()));
  j["world_T_scan"] = ToJson(scan.world_T_scan.matrix());
  j["notes"] = scan.metadata.notes;
  return j;
}

}  // namespace s2m::app
