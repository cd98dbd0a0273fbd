#pragma once
// The parameter domain of an n-sided patch (L. Fang, MIT PhD thesis 1994, section 4.3.1; docs/fe-surfaces.md
// eq. P13): a polygon whose sides have the boundary curves' arc lengths and whose turning angles are as close
// as possible to the angles between the curves where they meet, closed exactly by the method of multipliers
// (thesis 5.1.12-5.1.15).

#include <Eigen/Core>
#include <string>
#include <vector>

namespace s2m {

struct PolygonClosureOptions {
  double penalty = 1e4;            // R of the augmented objective (the same for every constraint)
  int max_outer_iterations = 100;  // multiplier updates
  double tolerance = 1e-12;        // on the closure error relative to the perimeter and on sum(theta) - 2 pi
  bool IsValid(std::string* why = nullptr) const;
};

struct PolygonClosure {
  Eigen::Matrix2Xd vertices;     // counter-clockwise from (0, 0), side 0 along +u; vertex i starts side i
  std::vector<double> turning;   // theta_i: the turn from side i to side i + 1 (radians, left positive)
  double closure_error = 0.0;    // |sum of the sides' vectors| / perimeter at the solution
  double angle_sum_error = 0.0;  // sum(theta) - 2 pi
  int outer_iterations = 0;
  bool converged = false;
};

// sides: the lengths s_i (> 0); turning: the initial turns theta_i^0 after each side (the exterior angles
// between consecutive curves' tangents, left positive). Minimizes sum ((theta_i - theta_i^0) / w_i)^2, w_i =
// max(|theta_i^0|, 0.05), subject to the polygon closing and sum(theta_i) = 2 pi. Throws
// std::invalid_argument for fewer than 3 sides, a side that is not positive and finite or not shorter than
// the others together (no polygon has it), a non-finite turn, or invalid options.
PolygonClosure ClosePolygon(const std::vector<double>& sides, const std::vector<double>& turning,
                            const PolygonClosureOptions& options = {});

}  // namespace s2m
