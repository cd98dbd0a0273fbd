// Fits a sphere to points on a known sphere through the installed package; prints the centre and radius and
// exits 1 when they are not those of the sphere the points were sampled from.
#include <fitting/primitive_fit.h>

#include <cmath>
#include <cstdio>

int main() {
  const Eigen::Vector3d centre(1.0, -2.0, 0.5);
  const double radius = 3.0;
  Eigen::Matrix3Xd points(3, 200);
  for (int i = 0; i < points.cols(); ++i) {  // a Fibonacci spiral over the whole sphere
    const double z = 1.0 - 2.0 * (i + 0.5) / static_cast<double>(points.cols());
    const double phi = i * 2.399963229728653;
    const double rho = std::sqrt(1.0 - z * z);
    points.col(i) = centre + radius * Eigen::Vector3d(rho * std::cos(phi), rho * std::sin(phi), z);
  }
  const s2m::PrimitiveFit<s2m::Sphere> fit = s2m::FitSphere(points);
  std::printf("centre %.12g %.12g %.12g radius %.12g rms %.3g\n", fit.shape.center.x(), fit.shape.center.y(),
              fit.shape.center.z(), fit.shape.radius, fit.residuals.rms);
  const bool ok = (fit.shape.center - centre).norm() < 1e-9 && std::abs(fit.shape.radius - radius) < 1e-9;
  return ok ? 0 : 1;
}
