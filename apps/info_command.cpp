#include <iostream>

#include "acquisition/format_error.h"
#include "acquisition/point_cloud_io.h"
#include "apps/commands.h"
#include "apps/output.h"

namespace s2m::app {

Runner AddInfoCommand(CLI::App& app) {
  struct Options {
    std::string file;
    bool json = false;
  };
  auto options = std::make_shared<Options>();
  CLI::App* cmd = app.add_subcommand("info", "Describe a point-cloud file: points, bounds, units, normals");
  cmd->add_option("file", options->file, "Input: .ply, .ply.gz, .pcd, .xyz/.txt/.csv/.pts, .ds")->required();
  cmd->add_flag("--json", options->json, "Machine-readable output (schema scan2model.info/1, docs/cli.md)");
  return [options]() {
    try {
      const PointCloudFormat format = DetectFormat(options->file);
      const Scan scan = ReadPointCloud(options->file, format);
      nlohmann::json j = DescribeScan(scan, options->file, ToString(format));
      if (options->json) {
        j["schema"] = "scan2model.info/1";
        std::cout << j.dump(2) << "\n";
        return int{kOk};
      }
      const Bounds b = ComputeBounds(scan.points);
      std::cout << options->file << "\n"
                << "  format    " << ToString(format) << "\n"
                << "  points    " << scan.size() << "\n"
                << "  normals   " << (scan.has_normals() ? "yes" : "no") << "\n"
                << "  weights   " << (scan.has_weights() ? "yes" : "no") << "\n"
                << "  units     " << scan.units << "\n"
                << "  min       " << Format(b.min, 8) << "\n"
                << "  max       " << Format(b.max, 8) << "\n"
                << "  extent    " << Format(b.extent(), 8) << "  (diagonal " << Format(b.diagonal(), 8)
                << ")\n";
      if (!scan.world_T_scan.matrix().isIdentity(0.0)) {
        std::cout << "  world_T_scan\n" << scan.world_T_scan.matrix() << "\n";
      }
      for (const std::string& note : scan.metadata.notes) std::cout << "  note      " << note << "\n";
      return int{kOk};
    } catch (const FormatError& e) {
      return ReportError("info", e.what(), kInputError, options->json);
    }
  };
}

}  // namespace s2m::app
