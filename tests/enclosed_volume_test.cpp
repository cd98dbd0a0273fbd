// KinematicSurface::EnclosedVolume (docs/archaeology.md eqs. A1-A4): exact volumes of a cylinder and a cone
// frustum written as B-spline generatrices, a generatrix that turns back in height against an independent
// polyline integration, slabs between planes, the gradient with the planes held against central differences,
// and the errors. The propagated uncertainty against its spread over simulated pots is checked through the
// command's path (tests/vessel_measures_test.cpp).

#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <stdexcept>
#include <utility>
#include <vector>

#include "fitting/kinematic_surfaces.h"

namespace s2m {
namespace {

// A clamped cubic generatrix whose control points lie on the segment from (r0, z0) to (r1, z1), unevenly
// spaced along it: the surface is the cone frustum (or cylinder) whatever the parametrization.
KinematicSurface Frustum(double r0, double z0, double r1, double z1, int n = 7) {
  Eigen::Matrix2Xd profile(2, n);
  for (int k = 0; k < n; ++k) {
    const double t = std::pow(static_cast<double>(k) / (n - 1), 1.7);
    profile.col(k) << r0 + t * (r1 - r0), z0 + t * (z1 - z0);
  }
  return KinematicSurface::Revolution(BSplineBasis::ClampedUniform(4, n), profile);
}

constexpr double kInf = std::numeric_limits<double>::infinity();

// The volume by the polyline through `samples` points of the generatrix: pi |sum (z1 - z0) (r0^2 + r0 r1 +
// r1^2) / 3| over its segments (each a cone frustum), each segment clipped to z_lo <= z <= z_hi.
// Second-order accurate: an independent check of the Gauss-Legendre integration and of the crossings.
double PolylineVolume(const KinematicSurface& s, double z_lo, double z_hi, int samples) {
  const double lo = s.basis().lo(), hi = s.basis().hi();
  double sum = 0.0;
  Eigen::Vector2d a = s.ProfilePoint(lo);
  for (int i = 1; i <= samples; ++i) {
    const Eigen::Vector2d b = s.ProfilePoint(lo + (hi - lo) * i / samples);
    // Clip the segment's parameter range [t0, t1] of p(t) = a + t (b - a) to the slab.
    double t0 = 0.0, t1 = 1.0;
    const double dz = b.y() - a.y();
    if (dz != 0) {
      const double ta = (z_lo - a.y()) / dz, tb = (z_hi - a.y()) / dz;
      t0 = std::max(t0, std::min(ta, tb));
      t1 = std::min(t1, std::max(ta, tb));
    } else if (a.y() < z_lo || a.y() > z_hi) {
      t1 = t0;
    }
    if (t1 > t0) {
      const Eigen::Vector2d p = a + t0 * (b - a), q = a + t1 * (b - a);
      sum += (q.y() - p.y()) * (p.x() * p.x() + p.x() * q.x() + q.x() * q.x()) / 3.0;
    }
    a = b;
  }
  return M_PI * std::abs(sum);
}

TEST(EnclosedVolume, CylinderAndFrustumAreExact) {
  const KinematicSurface cylinder = Frustum(2.5, -1.0, 2.5, 3.0);
  const double whole = M_PI * 6.25 * 4.0;
  EXPECT_NEAR(cylinder.EnclosedVolume(-kInf, kInf), whole, 1e-12 * whole);
  EXPECT_NEAR(cylinder.EnclosedVolume(-1.0, 3.0), whole, 1e-12 * whole);
  EXPECT_NEAR(cylinder.EnclosedVolume(-kInf, 0.5), M_PI * 6.25 * 1.5, 1e-12 * whole);
  EXPECT_NEAR(cylinder.EnclosedVolume(0.0, 1.0), M_PI * 6.25, 1e-12 * whole);
  // A frustum r = 1 at z = 0 to r = 3 at z = 2 (a bowl): pi h (r^2 + r R + R^2) / 3.
  const KinematicSurface bowl = Frustum(1.0, 0.0, 3.0, 2.0);
  auto frustum = [](double r, double big_r, double h) {
    return M_PI * h * (r * r + r * big_r + big_r * big_r) / 3;
  };
  const double bowl_volume = frustum(1, 3, 2);
  EXPECT_NEAR(bowl.EnclosedVolume(-kInf, kInf), bowl_volume, 1e-12 * bowl_volume);
  // Up to 0.5 above the narrow end (radius 1.5 there), and the top 0.5 (radius 2.5 to 3).
  EXPECT_NEAR(bowl.EnclosedVolume(-kInf, 0.5), frustum(1, 1.5, 0.5), 1e-12 * bowl_volume);
  EXPECT_NEAR(bowl.EnclosedVolume(1.5, kInf), frustum(2.5, 3, 0.5), 1e-12 * bowl_volume);
  // Planes beyond the ends change nothing.
  EXPECT_NEAR(bowl.EnclosedVolume(-10.0, 10.0), bowl_volume, 1e-12 * bowl_volume);
  // The generatrix running down the axis (z decreasing along it): the same solid.
  const KinematicSurface down = Frustum(1.0, 0.0, 3.0, -2.0);
  EXPECT_NEAR(down.EnclosedVolume(-0.5, kInf), frustum(1, 1.5, 0.5), 1e-12 * bowl_volume);
  EXPECT_NEAR(down.EnclosedVolume(-kInf, kInf), bowl_volume, 1e-12 * bowl_volume);
}

TEST(EnclosedVolume, ProfileThatTurnsBackAgreesWithThePolyline) {
  // A pot whose rim curls inwards and down (z rises to about 4.3, then falls back to 3.9 at the rim): the
  // disc integration along the generatrix counts the overhang once, and a plane through the curl cuts the
  // generatrix twice.
  Eigen::Matrix2Xd profile(2, 9);
  profile << 0.8, 2.0, 3.2, 3.4, 2.8, 2.2, 2.0, 1.9, 1.7,  //
      0.0, 0.1, 1.0, 2.5, 3.6, 4.2, 4.5, 4.2, 3.9;
  const KinematicSurface pot = KinematicSurface::Revolution(BSplineBasis::ClampedUniform(4, 9), profile);
  const std::vector<std::pair<double, double>> slabs = {{-kInf, kInf}, {-kInf, 1.0}, {-kInf, 3.95},
                                                        {-kInf, 4.0},  {-kInf, 4.2}, {1.0, 4.0},
                                                        {4.0, kInf},   {2.0, 2.5}};
  for (const auto& [z_lo, z_hi] : slabs) {
    const double exact = pot.EnclosedVolume(z_lo, z_hi);
    const double reference = PolylineVolume(pot, z_lo, z_hi, 200000);
    EXPECT_NEAR(exact, reference, 1e-8 * reference) << "planes " << z_lo << " " << z_hi;
  }
  // A fill plane above the rim's end but below the top of the curl adds the solid between.
  EXPECT_GT(pot.EnclosedVolume(-kInf, 4.2), pot.EnclosedVolume(-kInf, 3.9));
}

TEST(EnclosedVolume, GradientHoldsThePlanesAndMatchesCentralDifferences) {
  // Planes strictly inside the generatrix's heights: every parameter's central difference is the gradient.
  // Planes at +-infinity (the solid closed at the generatrix's ends): the ends' heights z_0 and z_(n-1) also
  // move the closing planes, which the gradient holds fixed (eq. A3); their central differences then exceed
  // the gradient by exactly the end discs, pi r(end)^2 (signed by the direction of the generatrix).
  std::mt19937_64 rng(3u);
  std::uniform_real_distribution<double> radius(0.5, 3.0), rise(0.2, 1.0);
  for (int trial = 0; trial < 6; ++trial) {
    const int n = 6 + trial % 3;
    Eigen::Matrix2Xd profile(2, n);
    double z = 0.0;
    for (int k = 0; k < n; ++k) {
      profile.col(k) << radius(rng), z;
      z += (trial % 2 ? -1.0 : 1.0) * rise(rng);
    }
    const KinematicSurface surface =
        KinematicSurface::Revolution(BSplineBasis::ClampedUniform(3 + trial % 3, n), profile);
    const double z_first = profile(1, 0), z_last = profile(1, n - 1);
    const double bottom = std::min(z_first, z_last), span = std::abs(z_last - z_first);
    const std::vector<std::pair<double, double>> slabs = {
        {bottom + 0.2 * span, bottom + 0.7 * span}, {-kInf, bottom + 0.37 * span}, {-kInf, kInf}};
    for (const auto& [z_lo, z_hi] : slabs) {
      Eigen::VectorXd gradient;
      surface.EnclosedVolume(z_lo, z_hi, &gradient);
      ASSERT_EQ(gradient.size(), surface.num_parameters());
      const Eigen::VectorXd p = surface.parameters();
      for (int k = 0; k < p.size(); ++k) {
        const double step = 1e-6;
        KinematicSurface plus = surface, minus = surface;
        Eigen::VectorXd pp = p, pm = p;
        pp[k] += step;
        pm[k] -= step;
        plus.set_parameters(pp);
        minus.set_parameters(pm);
        const double numeric =
            (plus.EnclosedVolume(z_lo, z_hi) - minus.EnclosedVolume(z_lo, z_hi)) / (2 * step);
        // The end discs where a closing plane goes with an end (z entries 1 and 2n - 1; the generatrix
        // runs up when z_last > z_first).
        double disc = 0.0;
        const double up = z_last > z_first ? 1.0 : -1.0;
        const bool first_end_inside = z_first >= z_lo && z_first <= z_hi && std::isinf(up > 0 ? z_lo : z_hi);
        const bool last_end_inside = z_last >= z_lo && z_last <= z_hi && std::isinf(up > 0 ? z_hi : z_lo);
        if (k == 1 && first_end_inside) disc = -up * M_PI * profile(0, 0) * profile(0, 0);
        if (k == 2 * n - 1 && last_end_inside) disc = up * M_PI * profile(0, n - 1) * profile(0, n - 1);
        EXPECT_NEAR(gradient[k] + disc, numeric, 1e-6 * std::max(1.0, std::abs(numeric)))
            << "trial " << trial << " planes " << z_lo << " " << z_hi << " " << surface.parameter_name(k);
      }
    }
  }
}

TEST(EnclosedVolume, RefusesHelicalSurfacesAndEmptySlabs) {
  const KinematicSurface cylinder = Frustum(2.0, 0.0, 2.0, 1.0);
  EXPECT_THROW(cylinder.EnclosedVolume(1.0, 1.0), std::invalid_argument);
  EXPECT_THROW(cylinder.EnclosedVolume(2.0, 1.0), std::invalid_argument);
  EXPECT_THROW(cylinder.EnclosedVolume(std::nan(""), 1.0), std::invalid_argument);
  const KinematicSurface helical = KinematicSurface::Helical(cylinder.basis(), cylinder.profile(), 0.1, 2.0);
  EXPECT_THROW(helical.EnclosedVolume(-kInf, kInf), std::logic_error);
}

}  // namespace
}  // namespace s2m
