#include "fitting/noise_estimate.h"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <vector>

#include "registration/local_quadric.h"
#include "registration/nearest_index.h"

namespace s2m {

double ChiSquareMedian(int dof) {
  if (dof == 2) return 2 * std::log(2.0);
  const double k = dof;
  return k * std::pow(1 - 2 / (9 * k), 3);
}

namespace {

// Eq. 50's degrees of freedom of a median of m chi-square(k) / median estimates: 8 m (x f(x))^2 at the median
// x, f the chi-square density (k = 2: x f = ln 2 / 2; k = 4: f(x) = x exp(-x / 2) / 4).
double MedianEstimateDof(int m, int k) {
  const double x = ChiSquareMedian(k);
  const double f = k == 2 ? std::exp(-x / 2) / 2 : x * std::exp(-x / 2) / 4;
  return 8.0 * m * (x * f) * (x * f);
}

}  // namespace

NoiseEstimate EstimateNoiseWithDof(const ScanSet& set) {
  // 8 neighbours (2 degrees of freedom each, hundreds of neighbourhoods per view): larger patches bias the
  // estimate upwards where the surface's third-order terms show (measured on the synthetic pots of
  // acquisition/synthetic_batch.h, noise 0.02, about 4 mm point spacing: 0.0226 with 8 neighbours, 0.0267
  // with 10, 0.058 with 20, pooled).
  constexpr int kNeighbours = 8;
  constexpr Eigen::Index kCentres = 500;
  // Per neighbourhood the variance estimate s^2 = SS / dof, scaled so that its median is sigma^2; the median
  // over all neighbourhoods ignores those straddling an edge of a part (measured on the demo block, noise
  // 0.02: the pooled mean gives 0.0297, the median 0.020).
  std::vector<double> scaled_variances;
  for (const Scan& scan : set.scans) {
    const Eigen::Index n = scan.points.cols();
    if (n < 2 * kNeighbours) continue;
    const NearestIndex index(scan.points);
    const Eigen::Index stride = std::max<Eigen::Index>(1, n / kCentres);
    Eigen::Matrix3Xd neighbours(3, kNeighbours);
    for (Eigen::Index c = 0; c < n; c += stride) {
      const Eigen::Vector3d centre = scan.points.col(c);
      const std::vector<Eigen::Index> near = index.KNearest(centre, kNeighbours);
      if (static_cast<int>(near.size()) < kNeighbours) continue;
      for (int k = 0; k < kNeighbours; ++k)
        neighbours.col(k) = scan.points.col(near[static_cast<std::size_t>(k)]);
      try {
        const LocalQuadric q = LocalQuadric::Fit(neighbours, centre);
        double sum_squares = 0.0;
        for (int k = 0; k < kNeighbours; ++k) {
          const Eigen::Vector3d local =
              q.frame().transpose() * (Eigen::Vector3d(neighbours.col(k)) - q.origin());
          const double r = local.z() - q.Height(local.x(), local.y());
          sum_squares += r * r;
        }
        const int dof = kNeighbours - (q.quadratic() ? 6 : 3);
        scaled_variances.push_back(sum_squares / ChiSquareMedian(dof));
      } catch (const std::invalid_argument&) {  // degenerate neighbourhood: no information
      }
    }
  }
  NoiseEstimate out;
  out.neighbourhoods = static_cast<int>(scaled_variances.size());
  if (scaled_variances.size() < 10) {
    out.sigma = std::numeric_limits<double>::quiet_NaN();
    return out;
  }
  auto middle = scaled_variances.begin() + static_cast<std::ptrdiff_t>(scaled_variances.size() / 2);
  std::nth_element(scaled_variances.begin(), middle, scaled_variances.end());
  out.sigma = std::sqrt(*middle);
  out.dof = MedianEstimateDof(out.neighbourhoods, 2);  // most neighbourhoods are quadrics: 2 dof
  return out;
}

NoiseEstimate EstimatePlaneCurveNoise(const Eigen::MatrixXd& points) {
  NoiseEstimate out;
  out.sigma = std::numeric_limits<double>::quiet_NaN();
  if (points.rows() != 2) return out;
  constexpr int kNeighbours = 7;
  constexpr int kDof = kNeighbours - 3;
  const Eigen::Index n = points.cols();
  if (n < 2 * kNeighbours) return out;
  Eigen::Matrix3Xd lifted = Eigen::Matrix3Xd::Zero(3, n);
  lifted.topRows(2) = points;
  const NearestIndex index(lifted);
  const Eigen::Index stride = std::max<Eigen::Index>(1, n / 1000);
  std::vector<double> scaled;
  for (Eigen::Index c = 0; c < n; c += stride) {
    const std::vector<Eigen::Index> near = index.KNearest(lifted.col(c), kNeighbours);
    if (static_cast<int>(near.size()) < kNeighbours) continue;
    Eigen::Matrix2Xd q(2, kNeighbours);
    for (int k = 0; k < kNeighbours; ++k) q.col(k) = points.col(near[static_cast<std::size_t>(k)]);
    const Eigen::Vector2d mean = q.rowwise().mean();
    q.colwise() -= mean;
    Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> eig(q * q.transpose());
    const Eigen::Vector2d along = eig.eigenvectors().col(1), across = eig.eigenvectors().col(0);
    Eigen::Matrix<double, kNeighbours, 3> a;
    Eigen::Matrix<double, kNeighbours, 1> y;
    for (int k = 0; k < kNeighbours; ++k) {
      const double x = along.dot(q.col(k));
      a.row(k) << x * x, x, 1.0;
      y[k] = across.dot(q.col(k));
    }
    const Eigen::ColPivHouseholderQR<Eigen::Matrix<double, kNeighbours, 3>> qr(a);
    if (qr.rank() < 3) continue;  // coincident points
    const Eigen::Vector3d coefficients = qr.solve(y);
    scaled.push_back((a * coefficients - y).squaredNorm() / ChiSquareMedian(kDof));
  }
  out.neighbourhoods = static_cast<int>(scaled.size());
  if (scaled.size() < 10) return out;
  auto middle = scaled.begin() + static_cast<std::ptrdiff_t>(scaled.size() / 2);
  std::nth_element(scaled.begin(), middle, scaled.end());
  out.sigma = std::sqrt(*middle);
  out.dof = MedianEstimateDof(out.neighbourhoods, kDof);
  return out;
}

double EstimateNoise(const ScanSet& set) {
  return EstimateNoiseWithDof(set).sigma;
}

double EstimateCurveNoise(const Eigen::Ref<const Eigen::MatrixXd>& points) {
  constexpr int kNeighbours = 8;  // as EstimateNoise: small patches keep the curve's cubic terms out
  constexpr Eigen::Index kCentres = 500;
  const Eigen::Index rows = points.rows(), n = points.cols();
  if ((rows != 2 && rows != 3) || n < 2 * kNeighbours) return std::numeric_limits<double>::quiet_NaN();
  Eigen::Matrix3Xd padded = Eigen::Matrix3Xd::Zero(3, n);
  padded.topRows(rows) = points;
  const NearestIndex index(padded);
  const Eigen::Index codim = rows - 1;
  const int dof = static_cast<int>(codim) * (kNeighbours - 3);  // 3 coefficients per normal coordinate
  const double median = ChiSquareMedian(dof);
  const Eigen::Index stride = std::max<Eigen::Index>(1, n / kCentres);
  std::vector<double> scaled_variances;
  Eigen::MatrixXd local(rows, kNeighbours);
  for (Eigen::Index c = 0; c < n; c += stride) {
    const std::vector<Eigen::Index> near = index.KNearest(padded.col(c), kNeighbours);
    if (static_cast<int>(near.size()) < kNeighbours) continue;
    for (int k = 0; k < kNeighbours; ++k) local.col(k) = points.col(near[static_cast<std::size_t>(k)]);
    const Eigen::VectorXd mean = local.rowwise().mean();
    local.colwise() -= mean;
    const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig(local * local.transpose());
    const Eigen::VectorXd tangent = eig.eigenvectors().col(rows - 1);
    const Eigen::VectorXd s = tangent.transpose() * local;
    Eigen::MatrixXd design(kNeighbours, 3);
    design.col(0).setOnes();
    design.col(1) = s;
    design.col(2) = s.array().square();
    const Eigen::ColPivHouseholderQR<Eigen::MatrixXd> qr(design);
    if (qr.rank() < 3) continue;  // coincident points: no information
    double sum_squares = 0.0;
    for (Eigen::Index e = 0; e < rows - 1; ++e) {
      const Eigen::VectorXd h = eig.eigenvectors().col(e).transpose() * local;
      sum_squares += (design * qr.solve(h) - h).squaredNorm();
    }
    scaled_variances.push_back(sum_squares / median);
  }
  if (scaled_variances.size() < 10) return std::numeric_limits<double>::quiet_NaN();
  auto middle = scaled_variances.begin() + static_cast<std::ptrdiff_t>(scaled_variances.size() / 2);
  std::nth_element(scaled_variances.begin(), middle, scaled_variances.end());
  return std::sqrt(static_cast<double>(codim) * *middle);
}

}  // namespace s2m
