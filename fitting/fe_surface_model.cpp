#include "fitting/fe_surface_model.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <stdexcept>

namespace s2m {

FeSurfaceModel::FeSurfaceModel(FeSurface surface)
    : surface_(std::make_shared<FeSurface>(std::move(surface))) {
  BuildBuckets();
}

void FeSurfaceModel::BuildBuckets() {
  const Eigen::Matrix2Xd& uv = surface_->mesh().uv;
  lo_ = uv.rowwise().minCoeff();
  hi_ = uv.rowwise().maxCoeff();
  // About two triangles per bucket.
  const double cells = std::max(1.0, 0.5 * surface_->triangle_count());
  const Eigen::Vector2d extent = (hi_ - lo_).cwiseMax(1e-300);
  const double side = std::sqrt(extent.x() * extent.y() / cells);
  buckets_u_ = std::clamp(static_cast<int>(std::ceil(extent.x() / side)), 1, 4096);
  buckets_v_ = std::clamp(static_cast<int>(std::ceil(extent.y() / side)), 1, 4096);
  buckets_.assign(static_cast<std::size_t>(buckets_u_ * buckets_v_), {});
  const auto cell = [this, extent](double x, int count, int axis) {
    return std::clamp(static_cast<int>((x - lo_(axis)) / extent(axis) * count), 0, count - 1);
  };
  for (int t = 0; t < surface_->triangle_count(); ++t) {
    Eigen::Vector2d a = Eigen::Vector2d::Constant(std::numeric_limits<double>::infinity()), b = -a;
    for (int k = 0; k < 3; ++k) {
      a = a.cwiseMin(surface_->element(t).vertex(k));
      b = b.cwiseMax(surface_->element(t).vertex(k));
    }
    for (int i = cell(a.x(), buckets_u_, 0); i <= cell(b.x(), buckets_u_, 0); ++i)
      for (int j = cell(a.y(), buckets_v_, 1); j <= cell(b.y(), buckets_v_, 1); ++j)
        buckets_[static_cast<std::size_t>(i * buckets_v_ + j)].push_back(t);
  }
}

bool FeSurfaceModel::Find(const Eigen::Vector2d& uv, FeSurfacePoint& at) const {
  const Eigen::Vector2d extent = (hi_ - lo_).cwiseMax(1e-300);
  const int i = std::clamp(static_cast<int>((uv.x() - lo_.x()) / extent.x() * buckets_u_), 0, buckets_u_ - 1);
  const int j = std::clamp(static_cast<int>((uv.y() - lo_.y()) / extent.y() * buckets_v_), 0, buckets_v_ - 1);
  const std::vector<int>& candidates = buckets_[static_cast<std::size_t>(i * buckets_v_ + j)];
  for (int t : candidates) {
    const Eigen::Vector3d L = surface_->element(t).Barycentric(uv);
    if (L.minCoeff() >= -1e-12) {
      at.triangle = t;
      at.barycentric = L.cwiseMax(0.0) / L.cwiseMax(0.0).sum();
      return true;
    }
  }
  // Outside the domain (or in a bucket's corner no triangle covers): the walk from a nearby triangle finds
  // the host or the nearest boundary point.
  at.triangle = candidates.empty() ? 0 : candidates.front();
  return surface_->Locate(uv, at);
}

std::unique_ptr<ParametricModel> FeSurfaceModel::Clone() const {
  return std::make_unique<FeSurfaceModel>(*this);
}

void FeSurfaceModel::CopyFrom(const ParametricModel& other) {
  *this = dynamic_cast<const FeSurfaceModel&>(other);
}

ParameterDomain FeSurfaceModel::domain() const {
  ParameterDomain d;
  d.dimension = 2;
  d.lo = {lo_.x(), lo_.y()};
  d.hi = {hi_.x(), hi_.y()};
  return d;
}

std::string FeSurfaceModel::parameter_name(int index) const {
  static const char* kCoordinate[3] = {"x", "y", "z"};
  static const char* kWhich[3] = {"w", "w_u", "w_v"};
  const int dof = index / 3, c = index % 3;
  if (dof < 3 * surface_->vertex_count())
    return std::string("vertex ") + std::to_string(dof / 3) + " " + kWhich[dof % 3] + "." + kCoordinate[c];
  return "edge " + std::to_string(dof - 3 * surface_->vertex_count()) + " w_n." + kCoordinate[c];
}

Eigen::VectorXd FeSurfaceModel::parameters() const {
  const Eigen::MatrixX3d& q = surface_->dofs();
  Eigen::VectorXd p(3 * q.rows());
  for (Eigen::Index d = 0; d < q.rows(); ++d) p.segment<3>(3 * d) = q.row(d).transpose();
  return p;
}

void FeSurfaceModel::set_parameters(const Eigen::VectorXd& p) {
  if (p.size() != num_parameters())
    throw std::invalid_argument("finite-element surface: " + std::to_string(p.size()) +
                                " parameters given, " + std::to_string(num_parameters()) + " expected");
  Eigen::MatrixX3d q(surface_->dof_count(), 3);
  for (Eigen::Index d = 0; d < q.rows(); ++d) q.row(d) = p.segment<3>(3 * d).transpose();
  if (surface_.use_count() > 1) surface_ = std::make_shared<FeSurface>(*surface_);
  surface_->set_dofs(q);
}

void FeSurfaceModel::ApplySimilarity(double scale, const VecS& offset) {
  Eigen::MatrixX3d q = scale * surface_->dofs();
  for (int v = 0; v < surface_->vertex_count(); ++v)
    q.row(surface_->vertex_dof(v, 0)) += offset.head<3>().transpose();
  if (surface_.use_count() > 1) surface_ = std::make_shared<FeSurface>(*surface_);
  surface_->set_dofs(q);
}

void FeSurfaceModel::Evaluate(const ParamT& t, int derivatives, LocalGeometry& out) const {
  FeSurfacePoint at;
  Find(Eigen::Vector2d(t[0], t[1]), at);
  const FeSurfaceGeometry g = surface_->Evaluate(at);
  out.point = g.point;
  if (derivatives >= 1) out.d1 = g.d1;
  if (derivatives >= 2) out.d2 = g.d2;
}

void FeSurfaceModel::ShapeJacobian(const ParamT& t, bool with_dt, std::vector<JacobianEntry>& out) const {
  FeSurfacePoint at;
  Find(Eigen::Vector2d(t[0], t[1]), at);
  const TriangleShape s = surface_->element(at.triangle).Evaluate(at.barycentric);
  const auto& dofs = surface_->element_dofs(at.triangle);
  out.clear();
  for (int a = 0; a < 12; ++a)
    for (int c = 0; c < 3; ++c) {
      JacobianEntry e;
      e.index = 3 * dofs[static_cast<std::size_t>(a)] + c;
      e.column = s.value(a) * Eigen::Vector3d::Unit(c);
      if (with_dt) {
        e.dcolumn_dt[0] = s.du(a) * Eigen::Vector3d::Unit(c);
        e.dcolumn_dt[1] = s.dv(a) * Eigen::Vector3d::Unit(c);
      }
      out.push_back(e);
    }
}

Eigen::MatrixXd FeSurfaceModel::FairnessMatrix(const FairnessWeights& weights) const {
  const Eigen::SparseMatrix<double> k = surface_->EnergyMatrix(weights);
  Eigen::MatrixXd out = Eigen::MatrixXd::Zero(num_parameters(), num_parameters());
  for (int col = 0; col < k.outerSize(); ++col)
    for (Eigen::SparseMatrix<double>::InnerIterator it(k, col); it; ++it)
      for (int c = 0; c < 3; ++c) out(3 * it.row() + c, 3 * col + c) = it.value();
  return out;
}

std::vector<ParamT> FeSurfaceModel::SampleParameters() const {
  // Four points inside every triangle (its centroid and the points halfway from it to the vertices): the
  // element's second derivatives have no value at its vertices, and its edges join two elements.
  std::vector<ParamT> out;
  const std::array<Eigen::Vector3d, 4> barycentric = {
      Eigen::Vector3d(1, 1, 1) / 3.0, Eigen::Vector3d(4, 1, 1) / 6.0, Eigen::Vector3d(1, 4, 1) / 6.0,
      Eigen::Vector3d(1, 1, 4) / 6.0};
  for (int t = 0; t < surface_->triangle_count(); ++t)
    for (const Eigen::Vector3d& L : barycentric) {
      const Eigen::Vector2d uv = surface_->ParameterOf({t, L});
      out.push_back({uv.x(), uv.y(), 0.0});
    }
  return out;
}

bool FeSurfaceModel::InDomain(const ParamT& t) const {
  FeSurfacePoint at;
  return Find(Eigen::Vector2d(t[0], t[1]), at);
}

}  // namespace s2m
