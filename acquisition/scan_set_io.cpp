#include "acquisition/scan_set_io.h"

#include <Eigen/Geometry>
#include <cmath>
#include <fstream>
#include <iomanip>
#include <nlohmann/json.hpp>
#include <sstream>
#include <stdexcept>

#include "acquisition/format_error.h"
#include "acquisition/formats/readers.h"
#include "acquisition/formats/text_util.h"
#include "acquisition/point_cloud_io.h"

namespace s2m {
namespace {

namespace fs = std::filesystem;

Scan ReadView(const fs::path& manifest, const std::string& where, const fs::path& file) {
  fs::path path = file.is_absolute() ? file : manifest.parent_path() / file;
  // Stanford .conf files name bunNNN.ply where the distribution ships bunNNN.ply.gz.
  if (!fs::exists(path) && fs::exists(path.string() + ".gz")) path = path.string() + ".gz";
  if (!fs::exists(path))
    throw FormatError(manifest.string(), where, "view file " + path.string() + " does not exist");
  return ReadPointCloud(path);  // its own errors name the view file
}

ScanSet ReadConf(const fs::path& conf) {
  const std::string text = formats::ReadFileBytes(conf.string());
  formats::LineReader lines(text);
  formats::Line line;
  std::vector<std::string_view> tok;
  ScanSet set;
  set.name = conf.stem().string();
  while (lines.Next(line)) {
    formats::Tokenize(line.text, tok);
    if (tok.empty() || tok[0] != "bmesh") continue;  // "camera" lines and blanks
    const std::string where = AtLine(line.number);
    if (tok.size() != 9)
      throw FormatError(conf.string(), where, "expected 'bmesh <file> tx ty tz qx qy qz qw'");
    double v[7];
    for (int i = 0; i < 7; ++i) {
      if (!formats::ParseDouble(tok[static_cast<std::size_t>(2 + i)], v[i]) || !std::isfinite(v[i])) {
        throw FormatError(conf.string(), where,
                          "not a number: " + formats::Quoted(tok[static_cast<std::size_t>(2 + i)]));
      }
    }
    Scan scan = ReadView(conf, where, std::string(tok[1]));
    // The Stanford convention that aligns the views: p_world = R(q)^T p_scan + t (the conjugate quaternion).
    const Eigen::Quaterniond q(v[6], v[3], v[4], v[5]);
    if (!(q.norm() > 0)) throw FormatError(conf.string(), where, "zero quaternion");
    scan.world_T_scan =
        RigidMotion(q.normalized().toRotationMatrix().transpose(), Eigen::Vector3d(v[0], v[1], v[2]));
    scan.metadata.source = std::string(tok[1]) + " (" + conf.filename().string() + ")";
    set.scans.push_back(std::move(scan));
  }
  if (set.scans.empty()) throw FormatError(conf.string(), "", "no 'bmesh' line: the file lists no views");
  return set;
}

RigidMotion PoseFromJson(const nlohmann::json& m, const std::string& file, const std::string& where) {
  if (!m.is_array() || m.size() != 4)
    throw FormatError(file, where, "world_T_scan must be a 4x4 row-major matrix");
  Eigen::Matrix4d pose;
  for (int r = 0; r < 4; ++r) {
    if (!m[static_cast<std::size_t>(r)].is_array() || m[static_cast<std::size_t>(r)].size() != 4) {
      throw FormatError(file, where, "world_T_scan must be a 4x4 row-major matrix");
    }
    for (int c = 0; c < 4; ++c)
      pose(r, c) = m[static_cast<std::size_t>(r)][static_cast<std::size_t>(c)].get<double>();
  }
  if (!pose.allFinite()) throw FormatError(file, where, "world_T_scan is not finite");
  const Eigen::Matrix3d rot = pose.topLeftCorner<3, 3>();
  if ((rot.transpose() * rot - Eigen::Matrix3d::Identity()).norm() > 1e-6 || rot.determinant() < 0) {
    throw FormatError(file, where,
                      "world_T_scan is not a rigid motion (its rotation part is not orthonormal)");
  }
  RigidMotion motion = RigidMotion::FromMatrix(pose);
  motion.normalize();
  return motion;
}

ScanSet ReadManifest(const fs::path& manifest) {
  const std::string file = manifest.string();
  nlohmann::json j;
  try {
    j = nlohmann::json::parse(formats::ReadFileBytes(file));
  } catch (const nlohmann::json::parse_error& e) {
    throw FormatError(file, AtByte(e.byte), "invalid JSON");
  } catch (const nlohmann::json::out_of_range& e) {  // a number beyond double's range
    throw FormatError(file, "", std::string("invalid JSON: ") + e.what());
  }
  // A string member or the fallback; a member of another type is the file's error, not a crash (found by
  // fuzzing: a document that is a bare string, tests/data/fuzz/scan_set/).
  const auto text = [&j, &file](const char* key, const std::string& fallback) {
    if (!j.contains(key)) return fallback;
    if (!j[key].is_string()) throw FormatError(file, "", std::string("'") + key + "' is not a string");
    return j[key].get<std::string>();
  };
  if (!j.is_object() || text("schema", "") != "scan2model.views/1")
    throw FormatError(file, "", "not a scan2model.views/1 manifest");
  if (!j.contains("views") || !j["views"].is_array() || j["views"].empty())
    throw FormatError(file, "", "no views");
  ScanSet set;
  set.name = text("name", manifest.stem().string());
  const std::string units = text("units", "unknown");
  for (std::size_t i = 0; i < j["views"].size(); ++i) {
    const nlohmann::json& v = j["views"][i];
    const std::string where = "view " + std::to_string(i);
    try {
      if (!v.contains("file") || !v["file"].is_string()) throw FormatError(file, where, "no 'file'");
      Scan scan = ReadView(manifest, where, v["file"].get<std::string>());
      if (v.contains("world_T_scan")) scan.world_T_scan = PoseFromJson(v["world_T_scan"], file, where);
      if (scan.units == "unknown") scan.units = units;
      if (v.contains("turntable_angle_rad"))
        scan.metadata.turntable_angle_rad = v["turntable_angle_rad"].get<double>();
      set.scans.push_back(std::move(scan));
    } catch (const nlohmann::json::exception& e) {
      throw FormatError(file, where, std::string("malformed view: ") + e.what());
    }
  }
  return set;
}

}  // namespace

ScanSet ReadScanSet(const fs::path& manifest) {
  const std::string ext = manifest.extension().string();
  if (ext == ".conf") return ReadConf(manifest);
  if (ext == ".json") return ReadManifest(manifest);
  throw FormatError(manifest.string(), "",
                    "unknown multi-view format '" + ext + "' (.json manifest or Stanford .conf)");
}

void WriteScanSet(const fs::path& manifest, const ScanSet& set, const nlohmann::json& document_extra,
                  const std::vector<nlohmann::json>& view_extra) {
  if (!view_extra.empty() && view_extra.size() != set.scans.size())
    throw std::invalid_argument("WriteScanSet: one extra entry per view is needed");
  if (manifest.has_parent_path()) {
    std::error_code error;
    fs::create_directories(manifest.parent_path(), error);
    if (error) throw FormatError(manifest.string(), "", "cannot create its folder: " + error.message());
  }
  nlohmann::json j;
  j["schema"] = "scan2model.views/1";
  j["name"] = set.name;
  j["units"] = set.scans.empty() ? "unknown" : set.scans.front().units;
  j["views"] = nlohmann::json::array();
  for (std::size_t i = 0; i < set.scans.size(); ++i) {
    std::ostringstream name;
    name << "view_" << std::setw(3) << std::setfill('0') << i << ".ply";
    WritePly(manifest.parent_path() / name.str(), set.scans[i]);
    const Eigen::Matrix4d m = set.scans[i].world_T_scan.matrix();
    nlohmann::json rows = nlohmann::json::array();
    for (int r = 0; r < 4; ++r) rows.push_back({m(r, 0), m(r, 1), m(r, 2), m(r, 3)});
    nlohmann::json view{{"file", name.str()}, {"world_T_scan", rows}};
    if (set.scans[i].metadata.turntable_angle_rad)
      view["turntable_angle_rad"] = *set.scans[i].metadata.turntable_angle_rad;
    if (!view_extra.empty()) view.update(view_extra[i]);
    j["views"].push_back(view);
  }
  j.update(document_extra);
  const std::string tmp = manifest.string() + ".partial";
  {
    std::ofstream out(tmp);
    out << std::setprecision(17) << j.dump(2) << "\n";
    if (!out) throw FormatError(manifest.string(), "", "cannot write");
  }
  fs::rename(tmp, manifest);
}

}  // namespace s2m
