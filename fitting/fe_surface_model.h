#pragma once
// A fair finite-element surface (fitting/fe_surface.h) as a model of the engine (fitting/parametric_model.h):
// parameters are the dofs (3 per vector dof, index 3 dof + coordinate), the parameter t = (u, v) of the
// triangulated domain, whose bounding box is domain(); InDomain tells the points of the box that are not on
// the surface. Point location is by a grid of buckets (thread-safe: Evaluate may run in parallel). Used by
// the surface interrogation and the report (docs/interrogation.md) and open to the engine's fits and
// registrations (docs/fe-surfaces.md section 8).

#include <memory>
#include <string>
#include <vector>

#include "fitting/fe_surface.h"
#include "fitting/parametric_model.h"

namespace s2m {

class FeSurfaceModel final : public ParametricModel {
 public:
  explicit FeSurfaceModel(FeSurface surface);

  const FeSurface& surface() const { return *surface_; }
  // The host triangle of uv, or (false) the nearest point of the domain's boundary.
  bool Find(const Eigen::Vector2d& uv, FeSurfacePoint& at) const;

  std::unique_ptr<ParametricModel> Clone() const override;
  void CopyFrom(const ParametricModel& other) override;
  std::string name() const override { return "finite-element surface"; }
  int ambient_dimension() const override { return 3; }
  ParameterDomain domain() const override;
  int num_parameters() const override { return 3 * surface_->dof_count(); }
  std::string parameter_name(int index) const override;
  Eigen::VectorXd parameters() const override;
  void set_parameters(const Eigen::VectorXd& p) override;
  // Positions scale and move; the slopes (w_u, w_v, w_n) only scale.
  void ApplySimilarity(double scale, const VecS& offset) override;
  void Evaluate(const ParamT& t, int derivatives, LocalGeometry& out) const override;
  void ShapeJacobian(const ParamT& t, bool with_dt, std::vector<JacobianEntry>& out) const override;
  // K (x) I3 of docs/fe-surfaces.md eq. P3 with FairnessWeights' stretch, bending and jump2, dense.
  Eigen::MatrixXd FairnessMatrix(const FairnessWeights& weights) const override;
  std::vector<ParamT> SampleParameters() const override;
  bool InDomain(const ParamT& t) const override;

 private:
  void BuildBuckets();

  std::shared_ptr<FeSurface> surface_;  // copied on write: the mesh and elements are shared by clones
  Eigen::Vector2d lo_, hi_;
  int buckets_u_ = 1, buckets_v_ = 1;
  std::vector<std::vector<int>> buckets_;  // triangles whose bounding box meets each cell
};

}  // namespace s2m
