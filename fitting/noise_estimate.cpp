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

// The equivalent degrees of freedom of a median of m chi-square(k) / median estimates (noise_estimate.h):
// 8 m (x f(x))^2 at the median x, f the chi-square density x^(k/2 - 1) exp(-x/2) / (2^(k/2) Gamma(k/2)).
double MedianEstimateDof(int m, int k) {
  const double x = ChiSquareMedian(k), h = 0.5 * k;
  const double xf = std::exp(h * std::log(x) - 0.5 * x - h * std::log(2.0) - std::lgamma(h));
  return 8.0 * m * xf * xf;
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

double EstimateNoise(const ScanSet& set) {
  return EstimateNoiseWithDof(set).sigma;
}

NoiseEstimate EstimateCurveNoise(const Eigen::Ref<const Eigen::MatrixXd>& points) {
  // 7 neighbours, 1000 centres: the plane-curve estimate the automatic complexity was measured with
  // (docs/method.md section 18); the adequacy verdict's earlier 8 neighbours and 500 centres gave the same
  // noise within its spread (measured: tests/residual_structure_test.cpp, EstimateCurveNoise.CircleAndHelix).
  constexpr int kNeighbours = 7;
  constexpr Eigen::Index kCentres = 1000;
  NoiseEstimate out;
  out.sigma = std::numeric_limits<double>::quiet_NaN();
  const Eigen::Index rows = points.rows(), n = points.cols();
  if ((rows != 2 && rows != 3) || n < 2 * kNeighbours) return out;
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
  out.neighbourhoods = static_cast<int>(scaled_variances.size());
  if (scaled_variances.size() < 10) return out;
  auto middle = scaled_variances.begin() + static_cast<std::ptrdiff_t>(scaled_variances.size() / 2);
  std::nth_element(scaled_variances.begin(), middle, scaled_variances.end());
  out.sigma = std::sqrt(static_cast<double>(codim) * *middle);
  out.dof = MedianEstimateDof(out.neighbourhoods, dof);
  return out;
}

}  // namespace s2m
