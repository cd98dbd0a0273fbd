#pragma once
// Shared output helpers for the command line: JSON documents and readable text.

#include <Eigen/Core>
#include <nlohmann/json.hpp>
#include <string>

#include "registration/scan.h"

namespace s2m::app {

nlohmann::json ToJson(const Eigen::Vector3d& v);
nlohmann::json ToJson(const Eigen::Matrix4d& m);
// Three numbers in parentheses with `digits` significant digits.
std::string Format(const Eigen::Vector3d& v, int digits = 12);
std::string Format(double value, int digits = 12);
// Describes the input file: points, normals, units, bounds.
nlohmann::json DescribeScan(const Scan& scan, const std::string& file, const std::string& format);

}  // namespace s2m::app
