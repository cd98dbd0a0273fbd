#include "pipeline/output.h"

#include <fcntl.h>
#include <unistd.h>

#include <cerrno>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <iostream>
#include <sstream>

#include "acquisition/format_error.h"

namespace s2m::pipeline {

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

nlohmann::json LossJson(const RobustLoss& loss, double scale, const Eigen::VectorXd& weights) {
  nlohmann::json j = {{"kind", ToString(loss.kind)}};
  if (!loss.is_robust()) return j;
  j["scale"] = scale;
  j["scale_from_data"] = loss.scale_from_data();
  if (weights.size() == 0) return j;  // a fit that reports no per-point weights
  j["down_weighted"] = (weights.array() < 0.5).count();
  j["rejected"] = (weights.array() == 0.0).count();
  return j;
}

nlohmann::json HistoryJson(const std::vector<IterationRecord>& history) {
  nlohmann::json out = nlohmann::json::array();
  for (const IterationRecord& r : history) {
    out.push_back({{"iteration", r.iteration},
                   {"rms", r.rms},
                   {"max_distance", r.max_distance},
                   {"objective", r.objective},
                   {"damping", r.damping},
                   {"step_norm", r.step_norm},
                   {"seconds", r.seconds}});
  }
  return out;
}

std::string HistoryCsv(const std::vector<IterationRecord>& history) {
  std::ostringstream csv;
  csv.precision(17);
  csv << "iteration,rms,max_distance,objective,damping,step_norm,seconds\n";
  for (const IterationRecord& r : history) {
    csv << r.iteration << ',' << r.rms << ',' << r.max_distance << ',' << r.objective << ',' << r.damping
        << ',' << r.step_norm << ',' << r.seconds << '\n';
  }
  return csv.str();
}

std::string HistoryTable(const std::vector<IterationRecord>& history) {
  std::ostringstream t;
  t << "\n  iteration           RMS   max distance    damping       step    time (ms)\n";
  for (const IterationRecord& r : history) {
    t << "  " << std::setw(9) << r.iteration << std::setw(14) << Format(r.rms, 6) << std::setw(15)
      << Format(r.max_distance, 6) << std::setw(11) << Format(r.damping, 2) << std::setw(11)
      << Format(r.step_norm, 3) << std::setw(13) << Format(r.seconds * 1e3, 4) << "\n";
  }
  return t.str();
}

void WriteTextAtomically(const std::string& path, const std::string& text) {
  // Written beside the target, flushed to the device (fsync), then renamed over it, and the folder flushed:
  // after a crash, a full disk or a power cut the file under its final name is either the old one or the
  // complete new one (docs/reliability.md). A failed write removes its partial file.
  const std::string tmp = path + ".partial";
  const auto fail = [&](const std::string& what, int error) {
    ::unlink(tmp.c_str());
    throw FormatError(path, "", what + ": " + std::strerror(error));
  };
  const int fd = ::open(tmp.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  if (fd < 0) {
    const int error = errno;
    throw FormatError(path, "", std::string("cannot create the file: ") + std::strerror(error));
  }
  std::size_t written = 0;
  while (written < text.size()) {
    const ssize_t n = ::write(fd, text.data() + written, text.size() - written);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) {
      const int error = n < 0 ? errno : ENOSPC;
      ::close(fd);
      fail("cannot write (" + std::to_string(written) + " of " + std::to_string(text.size()) +
               " bytes written)",
           error);
    }
    written += static_cast<std::size_t>(n);
  }
  if (::fsync(fd) != 0) {
    const int error = errno;
    ::close(fd);
    fail("cannot flush to disk", error);
  }
  if (::close(fd) != 0) fail("cannot close", errno);
  if (::rename(tmp.c_str(), path.c_str()) != 0) fail("cannot move the finished file into place", errno);
  const std::string folder = std::filesystem::path(path).parent_path().string();
  const int dir = ::open(folder.empty() ? "." : folder.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  if (dir >= 0) {
    ::fsync(dir);  // the rename itself durable; a folder that cannot be opened still holds the renamed file
    ::close(dir);
  }
}

int ReportError(const std::string& command, const std::string& message, int exit_code, bool json) {
  std::cerr << "scan2model " << command << ": error: " << message << "\n";
  if (json) {
    std::cout << nlohmann::json{{"schema", "scan2model.error/1"},
                                {"error", message},
                                {"exit_code", exit_code}}
                     .dump(2)
              << "\n";
  }
  return exit_code;
}

nlohmann::json NumberOrNull(double v) {
  return std::isfinite(v) ? nlohmann::json(v) : nlohmann::json(nullptr);
}

nlohmann::json MeasurandJson(const std::string& name, double value, const std::string& unit,
                             const UncertaintyMethod& method, double linear_standard_uncertainty,
                             const MonteCarloSummary* monte_carlo) {
  ExpandedUncertainty e = ExpandLinear(linear_standard_uncertainty);
  nlohmann::json m = {{"name", name}, {"value", value}, {"unit", unit}, {"method", method.ToString()}};
  if (monte_carlo) {
    e = ExpandMonteCarlo(*monte_carlo);
    m["monte_carlo"] = {{"trials", monte_carlo->trials},
                        {"failed_trials", monte_carlo->failed_trials},
                        {"mean", NumberOrNull(monte_carlo->mean)},
                        {"interval_low", NumberOrNull(monte_carlo->interval_low)},
                        {"interval_high", NumberOrNull(monte_carlo->interval_high)}};
  }
  m["standard_uncertainty"] = NumberOrNull(e.standard_uncertainty);
  m["expanded_uncertainty"] = NumberOrNull(e.expanded);
  m["coverage_factor"] = NumberOrNull(e.coverage_factor);
  m["coverage_probability"] = e.coverage_probability;
  return m;
}

std::string MeasurandsText(const nlohmann::json& measurands) {
  std::ostringstream text;
  text << "\n  derived quantities (value, standard uncertainty u, expanded U = k u)\n";
  for (const auto& m : measurands) {
    // An inadequate model's uncertainties in brackets (MarkUncertainties, as every other figure).
    const bool untrusted = m.value("uncertainty_trusted", nlohmann::json(true)) == false;
    auto shown = [&](const nlohmann::json& u) {
      if (u.is_null()) return std::string("-");
      return untrusted ? "[" + Format(u.get<double>(), 3) + "]" : Format(u.get<double>(), 3);
    };
    text << "  " << std::left << std::setw(28) << m["name"].get<std::string>()
         << Format(m["value"].get<double>(), 8) << "  u " << shown(m["standard_uncertainty"]) << "  U "
         << shown(m["expanded_uncertainty"])
         << " (k = " << (m["coverage_factor"].is_null() ? "-" : Format(m["coverage_factor"].get<double>(), 3))
         << ", " << m["method"].get<std::string>() << ")\n";
  }
  return text.str();
}

}  // namespace s2m::pipeline
