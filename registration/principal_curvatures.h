#pragma once
// Principal curvatures of a surface from its first and second fundamental forms, in closed form. One routine
// for every caller: the fitting engine's principal frames, the model-registration SDM directions and the
// local quadrics of scan-to-scan registration (registration/ is the lowest layer that needs it).

#include <Eigen/Core>

namespace s2m {

// The generalized symmetric eigenproblem II v = kappa I v of the second (`second`) and first (`first`)
// fundamental forms (do Carmo, Differential Geometry of Curves and Surfaces, 1976, section 3-3: the
// eigenpairs of the shape operator I^-1 II), in closed form (the joint solver and the fits call it for every
// point of every iteration). `curvatures` ascending, `directions` their I-orthonormal eigenvectors in
// parameter space (columns). False when the metric is not positive definite.
bool SolvePrincipalCurvatures(const Eigen::Matrix2d& second, const Eigen::Matrix2d& first,
                              Eigen::Matrix2d& directions, Eigen::Vector2d& curvatures);

}  // namespace s2m
