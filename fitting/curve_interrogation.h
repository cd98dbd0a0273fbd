#pragma once
// Interrogation of a fitted curve's fairness (docs/fair-curves.md section 6; L. Fang's thesis, section 3.4
// and the appendix; N. Sapidis and G. Farin, "Automatic fairing algorithm for B-spline curves", CAD 22(2),
// 1990): curvature and its arc-length derivative against normalized arc length, the curvature comb, torsion
// of space curves, G1/G2/G3 breaks at junctions with their jump sizes, inflections, and Sapidis' local and
// global fairness figures z_i and zeta. Everything from the curve's exact derivatives (up to the third),
// sampled uniformly in arc length.

#include <Eigen/Core>
#include <functional>
#include <string>
#include <vector>

#include "fitting/bspline_models.h"
#include "fitting/hermite_curve.h"

namespace s2m {

// A curve to interrogate: its exact derivatives w, w', w'', w''' (s x 4) at a parameter u, on the side `side`
// (-1: the limit from below, +1: from above, 0: either) of a junction, and its pieces.
struct InterrogatedCurve {
  int dimension = 2;
  double lo = 0.0, hi = 1.0;
  bool closed = false;
  // Parameters where polynomial pieces meet (interior ones; a closed curve's lo counts as its seam).
  std::vector<double> junctions;
  std::function<void(double u, int side, Eigen::Matrix<double, Eigen::Dynamic, 4>& jet)> jet;
};

// The adapters keep a reference: the curve must outlive the result.
InterrogatedCurve ToInterrogated(const HermiteCurve& curve);
// B-spline curves and, as BSplineCurve(basis, profile), generatrices of kinematic surfaces.
InterrogatedCurve ToInterrogated(const BSplineCurve& curve);

struct InterrogationOptions {
  int samples = 512;        // uniform in arc length, ends included
  double comb_scale = 0.0;  // tooth length per unit curvature; 0: automatic, 0.5 x length / max |kappa|
  bool IsValid(std::string* why) const;
};

struct CurvatureSample {
  double s = 0.0;  // normalized arc length in [0, 1]
  double u = 0.0;
  Eigen::Vector3d point = Eigen::Vector3d::Zero();
  double kappa = 0.0;  // signed for plane curves (positive: turning left), >= 0 in space
  double dkappa_ds = 0.0;
  double torsion = 0.0;                                // space curves (0 in the plane)
  Eigen::Vector3d normal = Eigen::Vector3d::Zero();    // unit principal normal (plane: the left normal)
  Eigen::Vector3d comb_tip = Eigen::Vector3d::Zero();  // point - comb_scale kappa normal (outside the bend)
};

// The jumps at one junction: G1 the angle between the one-sided unit tangents (radians), G2 the jump of the
// curvature (vector, for space curves), G3 the jump of dkappa/ds, i.e. Sapidis' local fairness z_i.
struct JunctionJump {
  double u = 0.0, s = 0.0;
  double g1 = 0.0, g2 = 0.0, g3 = 0.0;
};

struct CurveInterrogation {
  double length = 0.0;
  double comb_scale = 0.0;
  std::vector<CurvatureSample> samples;
  std::vector<JunctionJump> junctions;
  std::vector<double> inflections;  // normalized arc length of each sign change of kappa (plane curves)
  double max_abs_kappa = 0.0;
  double zeta = 0.0;               // Sapidis' global fairness: sum of z_i over the junctions
  double dkappa_ds_squared = 0.0;  // integral (dkappa/ds)^2 ds (Gauss-Legendre on every piece)
  double kappa_squared = 0.0;      // integral kappa^2 ds, the bending energy (the same quadrature)
  // Local extrema of the curvature: sign changes of dkappa/ds between samples (|dkappa/ds| below 1e-6 of
  // its largest value counts as zero), across a closed curve's seam too; plane curves use the signed kappa.
  int curvature_extrema = 0;
  double max_g1 = 0.0, max_g2 = 0.0;  // largest jumps
};

// Curvature and its derivative from derivatives w', w'', w''' (docs/fair-curves.md eqs. F20-F21).
void CurvatureOf(const Eigen::Ref<const Eigen::VectorXd>& d1, const Eigen::Ref<const Eigen::VectorXd>& d2,
                 const Eigen::Ref<const Eigen::VectorXd>& d3, double& kappa, double& dkappa_ds,
                 double& torsion);

CurveInterrogation InterrogateCurve(const InterrogatedCurve& curve, const InterrogationOptions& options = {});

}  // namespace s2m
