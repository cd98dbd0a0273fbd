// `scan2model detect`: the command line of ComputeDetect (pipeline/detect.h, docs/cli.md).
#include <iostream>

#include "apps/commands.h"
#include "pipeline/detect.h"
#include "pipeline/output.h"

namespace s2m::app {

Runner AddDetectCommand(CLI::App& app) {
  auto o = std::make_shared<DetectOptions>();
  CLI::App* cmd = app.add_subcommand(
      "detect", "Find instances of primitives in a raw scan with clutter (efficient RANSAC, robust refit)");
  cmd->add_option("file", o->file, "Input point cloud (.ply, .ply.gz, .pcd, .xyz/.txt/.csv/.pts, .ds)")
      ->required();
  cmd->add_option("--model,-m", o->models,
                  "Model to detect: plane, sphere, cylinder, cone or torus (repeat for several)")
      ->required()
      ->expected(1)  // one name per --model, so that the input file is not taken for a model
      ->multi_option_policy(CLI::MultiOptionPolicy::TakeAll);
  cmd->add_option("--max-instances", o->max_instances, "Instances at most (default 10)")
      ->check(CLI::Range(1, 100000));
  cmd->add_option("--min-support", o->min_support,
                  "Smallest instance in points (default 0: max(30, points / 1000))")
      ->check(CLI::Range(0, 2000000000));
  cmd->add_option("--seed", o->seed, "Seed of the sampling (default 1; the same seed, the same result)");
  cmd->add_option("--epsilon", o->epsilon,
                  "Inlier distance in input units (default 0: 3 x the noise estimated from the points)")
      ->check(CLI::NonNegativeNumber);
  cmd->add_option("--alpha", o->alpha, "Normal-angle threshold in radians (default 0: from the noise)")
      ->check(CLI::Range(0.0, 1.5));
  cmd->add_option("--units", o->units, "Units of the input when the file does not declare them");
  cmd->add_flag("--json", o->json, "Write the scan2model.detect/1 document on standard output");
  cmd->add_option("-o,--output", o->output,
                  "Write PREFIX_inliers.ply (coloured per instance) and PREFIX_rejected.ply");
  return [o]() {
    try {
      const DetectOutcome outcome = ComputeDetect(*o);
      for (const std::string& note : outcome.notes) std::cerr << "scan2model detect: note: " << note << "\n";
      if (o->json) {
        std::cout << outcome.document.dump(2) << "\n";
      } else {
        std::cout << outcome.text;
      }
      return static_cast<int>(kOk);
    } catch (const FitFailure& e) {
      return ReportError("detect", e.what(), e.exit_code(), o->json);
    }
  };
}

}  // namespace s2m::app
