#pragma once
// A synthetic batch for `scan2model batch` (docs/batch.md): pots (surfaces of revolution seen all round),
// sherds (pots with an angular part missing), shells (spiral surfaces) and, on request, one object whose view
// file is corrupt; each object a scan2model.views/1 manifest with its PLY views, all listed in one CSV batch
// manifest. Small objects (a few hundred points per view), deterministic for a seed.

#include <cstdint>
#include <filesystem>

namespace s2m {

struct SyntheticBatchOptions {
  int pots = 10;
  int sherds = 6;
  int shells = 3;
  bool corrupt = true;            // one more pot whose first view's PLY is truncated
  int samples_per_object = 1600;  // surface samples before visibility (each view sees part of them)
  double noise = 0.02;            // mm, along the normal
  double rotation_error = 1.0 * 3.14159265358979323846 / 180.0;  // recorded device poses off by this
  double translation_error = 1.0;                                // and this (mm)
  // Shells on a turntable: their recorded poses are this fraction of the errors above off (from 1 degree and
  // 1 mm the spiral fit creeps for hundreds of iterations).
  double shell_pose_error_scale = 0.25;
  int shell_samples = 1000;  // shells: the spiral's foot points are the costly ones
  // Measured: the shells reach the noise within 25 iterations (RMS 0.0202 for noise 0.02), then creep.
  int shell_max_iterations = 25;
  std::uint64_t seed = 7;
};

// Writes DIR/<id>/views.json (+ view_NNN.ply) per object and DIR/batch.csv (columns id,input,model,
// max_iterations); returns the batch manifest's path. Ids: pot_NN, sherd_NN, shell_NN, corrupt_pot.
std::filesystem::path WriteSyntheticBatch(const std::filesystem::path& dir,
                                          const SyntheticBatchOptions& options = {});

}  // namespace s2m
