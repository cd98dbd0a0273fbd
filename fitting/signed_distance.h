#pragma once
// Signed orthogonal distances of points to a fitted model: the deviations the report colours and the batch
// summarizes. Only the sign convention is added to the foot points (fitting/foot_point.h).

#include <Eigen/Core>
#include <vector>

#include "fitting/foot_point.h"
#include "fitting/parametric_model.h"
#include "fitting/part_model.h"

namespace s2m {

// Signed orthogonal distances of points (model frame) to a model around the z axis (surface of revolution,
// helical, spiral): positive on the side away from the axis (outside a pot's wall, the convention of
// SampleAroundAxis).
// With `feet`, also the foot points (3 x n): where the residuals sit on the model (the residual structure's
// neighbours and orders, docs/method.md section 17). With `known`, the points' foot points on the model as
// ComputeFootPoints found them (one per point), used instead of searching them again.
Eigen::VectorXd SignedDistancesAroundAxis(const ParametricModel& model, const Eigen::Matrix3Xd& points,
                                          Eigen::Matrix3Xd* feet = nullptr,
                                          const std::vector<FootPoint>* known = nullptr);
// Signed distances of points (part frame) to their nearest faces: positive along the face's normal C_u x C_v
// at the foot point (planes: their normal; cylinders: away from the axis).
Eigen::VectorXd SignedDistancesToFaces(const PartModel& part, const Eigen::Matrix3Xd& points,
                                       Eigen::Matrix3Xd* feet = nullptr);

}  // namespace s2m
