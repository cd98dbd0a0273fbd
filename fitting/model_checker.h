#pragma once
// A checker for ParametricModel implementations, in the role of Ceres' GradientChecker and manif's per-group
// test macro: every virtual function a fit relies on is compared against what it must equal by definition
// (central differences of the positions, the fundamental forms of the finite-difference surface, the
// generic Newton foot points of foot_point.h), at sample parameters spread over the domain and at random
// perturbations of the shape. A new model is registered with one line in the model checker's test
// (docs/adding-a-model.md).

#include <cstdint>
#include <string>
#include <vector>

#include "fitting/parametric_model.h"

namespace s2m {

struct ModelCheckOptions {
  // Sample parameters: `sample_count` of the model's SampleParameters(), each moved by a random amount of
  // between 1/2 and 1 times `sample_jitter` of the parameter's scale (the domain's width when it is finite,
  // else 1 + |t|), so that samples placed on knots (where a B-spline's higher derivatives jump) leave them
  // by more than the finite-difference stencils reach.
  int sample_count = 24;
  double sample_jitter = 1e-2;
  // The checks run at the model as given and at this many random perturbations of its shape parameters
  // (each parameter moved by `parameter_perturbation` x max(|p_i|, 0.1), normally distributed).
  int perturbation_count = 2;
  double parameter_perturbation = 1e-2;
  std::uint32_t seed = 20240611u;

  // Central-difference steps, relative to the parameter's scale (t: as above; shape parameters max(1, |p|)).
  // First derivatives in t use `derivative_step`; second ones the three-point second difference with steps
  // h and h / 2, combined by Richardson extrapolation (truncation O(h^4)), h = `second_derivative_step`.
  double derivative_step = 1e-5;
  double second_derivative_step = 2e-3;
  double parameter_step = 1e-5;

  // Tolerances on relative errors |analytic - numeric| / (|analytic| + floor), the floor 1e-3 x the model's
  // size per unit scale of the parameters differentiated in (a derivative below it counts as zero).
  double derivative_tolerance = 1e-6;
  double second_derivative_tolerance = 1e-5;
  double jacobian_tolerance = 1e-6;
  double curvature_tolerance = 1e-5;  // relative to |kappa| + 1 / size; frames: unit-vector differences
  // Exact identities (Clone/CopyFrom, round trips, factored Jacobian, invariance, similarity, step
  // consistency, foot points), relative to the model's size.
  double identity_tolerance = 1e-9;
  // ApplyStep of a small step D (this fraction of the parameters' scales) against C + J D: the
  // linearization error is second order in D.
  double step_fraction = 1e-6;
  double step_tolerance = 1e-4;
  // Foot points: test points at this fraction of the model's size (at most half the smallest radius of
  // curvature) off the model along its normal.
  double foot_offset = 0.02;

  // False (with the reason in `why`) when an option is out of range.
  bool IsValid(std::string* why) const;
};

// One property checked: the worst error over all samples and perturbations, and whether it stayed within the
// tolerance. Checks that do not apply to a model (no closed-form feet, no declared motions) are listed with
// applicable == false and count as passed.
struct ModelCheck {
  std::string name;
  bool applicable = false;
  bool passed = true;
  double worst_error = 0.0;
  double tolerance = 0.0;
  int evaluations = 0;
  std::string worst_at;  // where the worst error occurred (parameter t, column, perturbation)
};

struct ModelCheckReport {
  std::string model_name;
  int num_parameters = 0;
  double model_size = 0.0;  // the diagonal of the bounding box of the model's sample points
  std::vector<ModelCheck> checks;

  bool ok() const;
  // The check named `name`; null when there is none.
  const ModelCheck* Find(const std::string& name) const;
  // One line per check: name, pass/fail/n.a., worst error, tolerance, where.
  std::string ToString() const;
};

// Names of the checks, in the order of the report.
inline constexpr const char* kCheckFirstDerivatives = "first derivatives";
inline constexpr const char* kCheckSecondDerivatives = "second derivatives";
inline constexpr const char* kCheckShapeJacobian = "shape Jacobian";
inline constexpr const char* kCheckShapeJacobianDt = "shape Jacobian t-derivatives";
inline constexpr const char* kCheckFactoredJacobian = "factored shape Jacobian";
inline constexpr const char* kCheckPrincipalFrame = "principal frame";
inline constexpr const char* kCheckInvariantMotions = "invariant motions";
inline constexpr const char* kCheckCommonMotions = "common motions absorbed by shape";
inline constexpr const char* kCheckSimilarity = "similarity";
inline constexpr const char* kCheckCloneCopy = "clone and copy";
inline constexpr const char* kCheckParameterRoundTrip = "parameter round trip";
inline constexpr const char* kCheckApplyStep = "apply step";
inline constexpr const char* kCheckClosedFormFeet = "closed-form feet";

// Checks `model` (left unchanged: the checker works on clones). Throws std::invalid_argument for invalid
// options.
ModelCheckReport CheckModel(const ParametricModel& model, const ModelCheckOptions& options = {});

}  // namespace s2m
