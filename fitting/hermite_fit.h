#pragma once
// Fitting Hermite finite-element curves (fitting/hermite_curve.h) to points with L. Fang's fairness energy
// (docs/fair-curves.md): approximation of unorganized points with exact closest points, by Fang's sliding
// springs (his successive quadratic programming with the geometric Hessian and the spring forces resolved
// over elements) or by the engine's PDM / TDM / SDM error terms with the fairness as regularizer; or
// interpolation of ordered points (the points become the nodes, the derivatives are free). Element counts
// given or adaptive; weights given raw, or scaled to meet a target RMS distance.

#include <Eigen/Core>
#include <limits>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "fitting/fit_result.h"
#include "fitting/foot_point.h"
#include "fitting/hermite_curve.h"
#include "fitting/optimizer_options.h"

namespace s2m {

enum class HermiteMethod {
  kSpring,  // Fang's sliding springs: SQP with the fairness Hessian only, forces resolved over elements
  kSdm,     // the engine's squared-distance minimization (geometric_fit.h) with the fairness as regularizer
  kTdm,
  kPdm,
};
const char* ToString(HermiteMethod method);
HermiteMethod HermiteMethodFromString(const std::string& name);  // throws std::invalid_argument

struct HermiteFitOptions {
  int degree = 5;
  bool closed = false;
  bool c2 = false;  // cubic only: C2 by the reduced transformation
  // Elements: > 0 given; 0 adaptive (split where the local error is largest until the tolerance, or the
  // data's own noise, is met; at most max_elements).
  int elements = 0;
  int max_elements = 64;
  // Interpolation of ordered points (each point a node, uniform knots); otherwise approximation.
  bool interpolate = false;
  // Fang's raw weights on u in [0, 1] with the closeness 1/2 sum d_j^2 (docs/fair-curves.md eq. F1).
  HermiteFairness fairness{0.0, 0.0, 1e-8, 0.0, 0.0};
  HermiteMethod method = HermiteMethod::kSdm;
  // > 0: the target RMS distance in data units. The weights are multiplied by the one factor that makes the
  // fit's RMS equal to it (the fairest curve within the tolerance, a 1-D search); with adaptive elements,
  // elements are added until the RMS can go below it.
  double tolerance = 0.0;
  // In (0, 1): the fairness fraction phi, a scale-free control (docs/fair-curves.md eq. F27). The given
  // weights are then the mix of the terms, and the fit minimizes (1 - phi) C / C0 + phi F / F0: the closeness
  // C = 1/2 sum d^2 relative to C0 = 1/2 N sigma^2 (sigma the data's noise estimate), and the fairness
  // F = Q^T K Q relative to F0, the alpha terms' energy of a circle as long as the data traversed at constant
  // speed. 0: not used. Exclusive with the tolerance.
  double fairness_fraction = 0.0;
  // The spring method as printed in the thesis (Fang eq. 5.1.4): the fairness Hessian 2K alone and the
  // resolved forces throughout. It crawls where the data dominate (docs/fair-curves.md section 7). Default
  // (false): the Hessian adds the sliding springs' stiffness across the curve (eq. F28), and the iteration
  // finishes with the exact point forces where the resolved ones stop decreasing the energy (eq. F29).
  bool spring_as_in_thesis = false;
  // In [0, 1): the share g of the alpha3 weight measured geometrically (docs/fair-curves.md eq. F30): the
  // fairness has g alpha3 L0^5 integral (dkappa/ds)^2 ds (L0 the initial curve's length; the curvature
  // variation along the arc, independent of the parametrization) plus the parametric (1 - g) alpha3
  // integral |w'''|^2 du, which keeps the parametrization regular. Plane curves only; the fit is then the
  // sliding springs with exact point forces (eqs. F28-F29) and the geometric term's Gauss-Newton model,
  // whatever the method, started from the parametric fit at the same weights. 0: the parametric energy alone
  // (Fang's). Measured (docs/fair-curves.md section 7): fairer than the parametric energy and OpenCASCADE on
  // a sine and on glyphs, but not convex on the airfoil (see relative_variation).
  double geometric_variation = 0.0;
  // With geometric_variation > 0: measure the variation relative to the curvature (docs/fair-curves.md eq.
  // F34), integral (dkappa/ds)^2 / (1 + (kappa L0 / pi)^2) ds: the absolute form where the curve is flatter
  // than a half circle as long as the data, the variation of log kappa where it is much sharper, so that
  // a sharp end (an airfoil's trailing edge) does not cost kappa^3 and is not rounded off at the expense of
  // dents elsewhere.
  bool relative_variation = false;
  // Of each fit (the spring method: at most optimizer.max_iterations steps). The relative decrease tolerance
  // is 1e-8 rather than the engine's 1e-10: the nodal derivatives' tangential parts (the parametrization) are
  // held only by the fairness, and the last digits of E they still gain are not worth a hundred iterations.
  OptimizerOptions optimizer = [] {
    OptimizerOptions o;
    o.objective_tolerance = 1e-8;
    return o;
  }();

  bool IsValid(std::string* why) const;
};

struct HermiteFitResult {
  explicit HermiteFitResult(HermiteCurve c) : curve(std::move(c)) {}
  HermiteCurve curve;
  HermiteFairness weights;    // the weights used (after the tolerance's scaling)
  double weight_scale = 1.0;  // the tolerance search's or the fairness fraction's factor (else 1)
  HermiteFairness energy;     // each fairness term's value at the result (alpha3: its parametric share)
  // With geometric_variation g > 0: g alpha3 L0^5 integral (dkappa/ds)^2 ds at the result (eq. F30), the
  // part of alpha3 measured along the arc; energy.alpha3 is then the parametric (1 - g) share. Else 0.
  double geometric_energy = 0.0;
  double closeness = 0.0;  // 1/2 sum d_j^2, data units
  ResidualStatistics residuals;
  std::vector<FootPoint> foot_points;
  int iterations = 0;        // of the last fit (the spring method's SQP steps or the engine's iterations)
  int total_iterations = 0;  // over all fits (adaptive elements, tolerance search)
  int fits = 0;
  StopReason stop_reason = StopReason::kMaxIterations;
  std::vector<IterationRecord> history;  // of the last fit
  double seconds = 0.0;
  bool tolerance_met = true;  // false when the tolerance could not be reached (the note says why)
  std::string note;
  double noise = 0.0;  // the data's noise estimate used by adaptive elements (NaN when none)
  // The fairness fraction's normalization (eq. F27; NaN without a fraction): the noise and length it used,
  // C0 and F0, and the result's normalized terms C / C0 and F / F0.
  struct Fraction {
    double fraction = 0.0;
    double sigma = std::numeric_limits<double>::quiet_NaN();
    double length = std::numeric_limits<double>::quiet_NaN();
    double closeness_reference = std::numeric_limits<double>::quiet_NaN();
    double fairness_reference = std::numeric_limits<double>::quiet_NaN();
    double closeness = std::numeric_limits<double>::quiet_NaN();
    double fairness = std::numeric_limits<double>::quiet_NaN();
  } fraction;
};

// The weight factor k of the fairness fraction (docs/fair-curves.md eq. F27): the minimizer of
// (1 - phi) C / C0 + phi F / F0 is that of C + k F with k = phi / (1 - phi) C0 / F0, C0 = 1/2 N sigma^2,
// F0 = length^2 sum_p alpha_p (2 pi)^(2p - 2) (the alpha terms of `mix`).
double FairnessFractionScale(double fraction, int points, double sigma, double length,
                             const HermiteFairness& mix, double* closeness_reference = nullptr,
                             double* fairness_reference = nullptr);

// Fits a Hermite curve to the points (s x n, s = 2 or 3; ordered when interpolating). Throws
// std::invalid_argument for invalid options or unusable data (fewer than 3 distinct points for an
// approximation, fewer than 2 for an interpolation, NaN).
HermiteFitResult FitHermiteCurve(const Eigen::MatrixXd& points, const HermiteFitOptions& options);

// The initial curve of an approximation: a Hermite curve with `elements` uniform elements sampled from a
// B-spline chain through the data (fitting/initial_models.h), positions and derivatives at the nodes.
HermiteCurve InitialHermiteCurve(const Eigen::MatrixXd& points, int degree, int elements, bool closed,
                                 bool c2);

// Generalized force vector of the load density q_a (1 - t) + q_b t over one element of length h, integrated
// exactly against its shape functions (Fang eq. 5.1.10, Table 5.1): F_k = integral phi_k(u) q(u) du.
Eigen::VectorXd LinearLoadVector(int degree, double h, double q_a, double q_b);

// The generalized forces on the curve's dofs (per coordinate, all nodal dofs) of a unit spring force at u,
// resolved as a linear load over its element and the two neighbours (Fang's Method 2, eq. 5.1.9b;
// docs/fair-curves.md eq. F15); at an open curve's end elements, over the host element alone (Method 1).
Eigen::VectorXd ResolvedUnitForce(const HermiteCurve& curve, double u);

// The geometric curvature variation integral (dkappa/ds)^2 ds of a plane curve (docs/fair-curves.md eq. F30)
// as a sum of squares |r|^2: r_q = kappa_s(u_q) sqrt(|w'(u_q)| W_q) at 5-point Gauss-Legendre nodes on 8
// sub-intervals of every element (W_q the rule's weight times the sub-interval's length in u). With
// `jacobian`, also dr/dQ (rows: residuals, columns: the curve's parameters), the Gauss-Newton model of the
// fit. reference_curvature kappa_r > 0: the curvature-relative form (eq. F34), every residual times
// (1 + (kappa / kappa_r)^2)^(-1/2), so that |r|^2 is integral (dkappa/ds)^2 / (1 + (kappa / kappa_r)^2) ds.
// Throws std::invalid_argument for space curves.
void GeometricCurvatureVariation(const HermiteCurve& curve, Eigen::VectorXd& r, Eigen::MatrixXd* jacobian,
                                 double reference_curvature = 0.0);

}  // namespace s2m
