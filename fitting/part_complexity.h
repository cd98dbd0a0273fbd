#pragma once
// Automatic model complexity for the free-form spline patches of a constrained part (docs/method.md section
// 18, "Part spline patches"): the patch whose knot span holds the largest sum of squared residuals gets a
// knot there, in the direction (u or v) whose span is worse; the part, its named parameters and the views'
// poses are refitted jointly (FitPartJointly), and ChooseComplexity decides when to stop, as for every other
// spline.
#include <Eigen/Core>
#include <memory>
#include <string>
#include <vector>

#include "fitting/joint_fit.h"
#include "fitting/model_complexity.h"
#include "fitting/part_model.h"
#include "registration/rigid_motion.h"

namespace s2m {

// The part with spline patch `face`'s basis along `direction` (0: u, 1: v) refined by inserting `knot`
// (Boehm's insertion, docs/method.md eq. 69, through RefineBasis): at `values` the surface is unchanged. A
// patch with free displacements (SplinePatch::first_displacement) gets one per new control point, named
// "<face>[i,j]" and u-major as the part file makes them, in place of its old block; their values are the
// refined net's displacements (so the shape is kept), later parameters are renumbered, and every expression
// of the part follows. The returned definition's parameter values are the new values. Throws
// std::invalid_argument for a face that is not a spline patch, a direction other than 0 or 1, or a knot
// outside the patch's domain.
PartDefinition RefinePatch(const PartDefinition& part, const Eigen::VectorXd& values, std::size_t face,
                           int direction, double knot);

// The control-point counts of the part's spline patches, e.g. "top 5x4" or "top 5x4, side 4x4" ("" when
// the part has none).
std::string PatchControlPoints(const PartDefinition& part);

// The part's free-form patches (those with free displacements) grown by ChooseComplexity: each Fit is
// FitPartJointly from the current part and poses; Refine inserts one knot at the largest residual span
// (over the free-form patches and both directions) until a direction reaches `max_control_points`.
class RefinablePartFit final : public RefinableFit {
 public:
  RefinablePartFit(PartModel& part, std::vector<Eigen::Matrix3Xd> scans,
                   std::vector<RigidMotion> model_T_scan, JointFitOptions options, int max_control_points);
  // True when the part has at least one free-form patch (otherwise there is nothing to choose).
  static bool HasFreeFormPatches(const PartDefinition& part);

  Outcome Fit() override;
  std::string ControlPoints() const override { return PatchControlPoints(part_.definition()); }
  bool Refine() override;
  void Keep(std::size_t index) override;
  void Restore(std::size_t index) override;

  const JointFitResult& result() const { return result_; }
  int total_iterations() const { return total_iterations_; }

 private:
  // Feet of the registered points on the current part: per point the face, its parameter and squared
  // distance; points near an edge (the part's edge margin) are marked and count nowhere.
  void ComputeFeet();

  PartModel& part_;
  std::vector<Eigen::Matrix3Xd> scans_;
  std::vector<RigidMotion> model_T_scan_;
  JointFitOptions options_;
  int max_control_points_;
  JointFitResult result_;
  int total_iterations_ = 0;
  std::vector<ParamT> feet_;
  std::vector<double> feet_d2_;
  std::vector<bool> ambiguous_;
  struct KeptState {
    std::unique_ptr<ParametricModel> part;
    JointFitResult result;
    std::vector<RigidMotion> poses;
  };
  std::vector<KeptState> kept_;
};

}  // namespace s2m
