#include "registration/local_quadric.h"

#include <Eigen/Dense>
#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

#include "registration/nearest_index.h"
#include "registration/principal_curvatures.h"

namespace s2m {

namespace {

// Pivots of the column-scaled design matrix below this fraction of the largest mean that the neighbours do
// not determine those coefficients to better than about half of double precision (columns are O(1) after
// scaling by the neighbourhood radius, so the ratio is a conditioning measure, not a length).
constexpr double kRankThreshold = 1e-8;

}  // namespace

SurfacePoint SurfacePoint::Flipped() const {
  SurfacePoint out = *this;
  out.normal = -normal;
  out.kappa1 = -kappa2;
  out.kappa2 = -kappa1;
  out.direction1 = direction2;
  out.direction2 = direction1;
  return out;
}

LocalQuadric::LocalQuadric(const Eigen::Vector3d& origin, const Eigen::Matrix3d& frame,
                           const Eigen::Matrix<double, 6, 1>& coefficients, double radius, bool quadratic)
    : origin_(origin), frame_(frame), coefficients_(coefficients), radius_(radius), quadratic_(quadratic) {}

LocalQuadric LocalQuadric::Fit(const Eigen::Matrix3Xd& neighbours, const Eigen::Vector3d& centre) {
  const Eigen::Index k = neighbours.cols();
  if (k < 6) throw std::invalid_argument("a local quadric fit needs at least 6 neighbours");
  if (!neighbours.allFinite() || !centre.allFinite())
    throw std::invalid_argument("a local quadric fit got NaN or inf coordinates");
  // Tangent-plane frame from the neighbours' principal components (least spread: the normal).
  const Eigen::Vector3d mean = neighbours.rowwise().mean();
  const Eigen::Matrix3Xd centred = neighbours.colwise() - mean;
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(centred * centred.transpose());
  Eigen::Matrix3d frame;
  frame.col(2) = eig.eigenvectors().col(0);
  frame.col(0) = eig.eigenvectors().col(2);
  frame.col(1) = frame.col(2).cross(frame.col(0));  // t1 x t2 = n: right-handed
  const Eigen::Matrix3Xd local = frame.transpose() * (neighbours.colwise() - centre);
  const double radius = local.colwise().norm().maxCoeff();
  Eigen::Matrix<double, 6, 1> coefficients = Eigen::Matrix<double, 6, 1>::Zero();
  if (!(radius > 0.0)) return {centre, frame, coefficients, 0.0, false};  // all neighbours at the centre
  // Work in units of the radius so that the six columns are O(1): z/r = a' (x/r)^2 + ... + f', hence
  // a = a'/r (same for b, c), d = d', e = e', f = f' r.
  Eigen::MatrixXd design(k, 6);
  Eigen::VectorXd rhs(k);
  for (Eigen::Index i = 0; i < k; ++i) {
    const double x = local(0, i) / radius, y = local(1, i) / radius;
    design.row(i) << x * x, x * y, y * y, x, y, 1.0;
    rhs[i] = local(2, i) / radius;
  }
  Eigen::ColPivHouseholderQR<Eigen::MatrixXd> qr(design);
  qr.setThreshold(kRankThreshold);
  bool quadratic = qr.rank() == 6;
  if (quadratic) {
    coefficients = qr.solve(rhs);
  } else {
    // The quadratic terms are not determined (e.g. the neighbours lie on one scan line): a plane, zero
    // curvature; the minimum-norm solution keeps an undetermined slope at 0 (the PCA plane).
    const Eigen::CompleteOrthogonalDecomposition<Eigen::MatrixXd> cod(design.rightCols(3));
    coefficients.tail<3>() = cod.solve(rhs);
  }
  coefficients.head<3>() /= radius;
  coefficients[5] *= radius;
  return {centre, frame, coefficients, radius, quadratic};
}

double LocalQuadric::Height(double x, double y) const {
  const auto& q = coefficients_;
  return q[0] * x * x + q[1] * x * y + q[2] * y * y + q[3] * x + q[4] * y + q[5];
}

SurfacePoint LocalQuadric::At(double x, double y) const {
  const auto& q = coefficients_;
  // The graph X(x, y) = (x, y, h(x, y)) (do Carmo, Differential Geometry of Curves and Surfaces, 1976,
  // section 3-3, the Gauss map in local coordinates, applied to a graph; Cazals & Pouget 2005): X_x = (1, 0,
  // h_x), X_y = (0, 1, h_y), N = (-h_x, -h_y, 1)/W with W = sqrt(1 + h_x^2 + h_y^2),
  //   first fundamental form  I = [[1 + h_x^2, h_x h_y], [h_x h_y, 1 + h_y^2]],
  //   second fundamental form II = [[h_xx, h_xy], [h_xy, h_yy]] / W = [[2a, b], [b, 2c]] / W.
  // The shape operator is I^{-1} II; its eigenvalues are the principal curvatures and its eigenvectors w the
  // principal directions X_x w_1 + X_y w_2. At a point with zero slope (h_x = h_y = 0) this is the
  // eigen-decomposition of [[2a, b], [b, 2c]]. II = X_ij . N, so kappa > 0 where the surface bends towards N
  // (docs/method.md section 2's convention).
  const double hx = 2.0 * q[0] * x + q[1] * y + q[3];
  const double hy = q[1] * x + 2.0 * q[2] * y + q[4];
  const double w = std::sqrt(1.0 + hx * hx + hy * hy);
  Eigen::Matrix2d first, second;
  first << 1.0 + hx * hx, hx * hy, hx * hy, 1.0 + hy * hy;
  second << 2.0 * q[0], q[1], q[1], 2.0 * q[2];
  second /= w;
  // II w = kappa I w: symmetric-definite, so the eigenvectors come I-orthonormal, i.e. X_x w_1 + X_y w_2 are
  // orthonormal 3D tangents (the principal directions are orthogonal). A graph's metric I = Id + grad h grad
  // h^T is positive definite, so the solver fails only on non-finite coefficients: then NaN, as before.
  const double nan = std::numeric_limits<double>::quiet_NaN();
  Eigen::Matrix2d directions = Eigen::Matrix2d::Constant(nan);
  Eigen::Vector2d curvatures = Eigen::Vector2d::Constant(nan);
  SolvePrincipalCurvatures(second, first, directions, curvatures);
  const Eigen::Vector3d xx(1.0, 0.0, hx), xy(0.0, 1.0, hy);
  SurfacePoint out;
  out.point = origin_ + frame_ * Eigen::Vector3d(x, y, Height(x, y));
  out.normal = frame_ * Eigen::Vector3d(-hx, -hy, 1.0) / w;
  out.kappa1 = curvatures[0];
  out.kappa2 = curvatures[1];
  out.direction1 = (frame_ * (xx * directions(0, 0) + xy * directions(1, 0))).normalized();
  out.direction2 = (frame_ * (xx * directions(0, 1) + xy * directions(1, 1))).normalized();
  if (out.direction1.cross(out.direction2).dot(out.normal) < 0.0) out.direction2 = -out.direction2;
  return out;
}

SurfacePoint LocalQuadric::FootPoint(const Eigen::Vector3d& q) const {
  const Eigen::Vector3d l = frame_.transpose() * (q - origin_);
  const auto& c = coefficients_;
  Eigen::Matrix2d hessian_h;
  hessian_h << 2.0 * c[0], c[1], c[1], 2.0 * c[2];
  // Newton on phi(x, y) = |X(x, y) - l|^2 / 2: gradient J^T r with J = [X_x X_y], Hessian J^T J + r_z H(h)
  // (only h has second derivatives). Far beyond a curvature centre the Hessian may be indefinite; then the
  // Gauss-Newton part J^T J alone still descends.
  Eigen::Vector2d uv(l.x(), l.y());
  const double scale = std::max(radius_, l.norm());
  for (int iteration = 0; iteration < 30; ++iteration) {
    const double hx = 2.0 * c[0] * uv.x() + c[1] * uv.y() + c[3];
    const double hy = c[1] * uv.x() + 2.0 * c[2] * uv.y() + c[4];
    const Eigen::Vector3d r(uv.x() - l.x(), uv.y() - l.y(), Height(uv.x(), uv.y()) - l.z());
    const Eigen::Vector2d gradient(r.x() + r.z() * hx, r.y() + r.z() * hy);
    Eigen::Matrix2d jtj;
    jtj << 1.0 + hx * hx, hx * hy, hx * hy, 1.0 + hy * hy;
    Eigen::Matrix2d hessian = jtj + r.z() * hessian_h;
    if (!(hessian.determinant() > 0.0 && hessian.trace() > 0.0)) hessian = jtj;
    const Eigen::Vector2d step = -hessian.ldlt().solve(gradient);
    uv += step;
    if (!(step.norm() > 1e-15 * scale)) break;
  }
  return At(uv.x(), uv.y());
}

std::vector<SurfacePoint> EstimatePrincipalCurvatures(const Eigen::Matrix3Xd& points, int neighbours) {
  if (neighbours < 6) throw std::invalid_argument("curvature estimation needs at least 6 neighbours");
  if (points.cols() < neighbours) throw std::invalid_argument("fewer points than neighbours per fit");
  if (!points.allFinite()) throw std::invalid_argument("curvature estimation got NaN or inf coordinates");
  const NearestIndex index(points);
  std::vector<SurfacePoint> out(static_cast<std::size_t>(points.cols()));
#pragma omp parallel for schedule(static)
  for (Eigen::Index i = 0; i < points.cols(); ++i) {
    const std::vector<Eigen::Index> nn = index.KNearest(points.col(i), neighbours);
    Eigen::Matrix3Xd hood(3, static_cast<Eigen::Index>(nn.size()));
    for (std::size_t j = 0; j < nn.size(); ++j) hood.col(static_cast<Eigen::Index>(j)) = points.col(nn[j]);
    out[static_cast<std::size_t>(i)] = LocalQuadric::Fit(hood, points.col(i)).FootPoint(points.col(i));
  }
  return out;
}

Eigen::Matrix3d SdmErrorMatrix(const SurfacePoint& foot, const Eigen::Vector3d& x) {
  const SurfacePoint f = foot.normal.dot(x - foot.point) >= 0.0 ? foot : foot.Flipped();
  const double delta = f.normal.dot(x - f.point);
  return SdmWeight(delta, f.kappa1) * f.direction1 * f.direction1.transpose() +
         SdmWeight(delta, f.kappa2) * f.direction2 * f.direction2.transpose() +
         f.normal * f.normal.transpose();
}

}  // namespace s2m
