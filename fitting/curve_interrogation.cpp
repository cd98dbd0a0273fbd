#include "fitting/curve_interrogation.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace s2m {
namespace {

using Jet = Eigen::Matrix<double, Eigen::Dynamic, 4>;

// 5-point Gauss-Legendre on [0, 1]: degree 9 exactly.
constexpr double kGaussX[5] = {0.04691007703066800, 0.23076534494715845, 0.5, 0.76923465505284155,
                               0.95308992296933200};
constexpr double kGaussW[5] = {0.11846344252809454, 0.23931433524968324, 0.28444444444444444,
                               0.23931433524968324, 0.11846344252809454};
constexpr int kSubintervals = 16;  // per piece, for the arc-length table

Eigen::Vector3d Pad(const Eigen::VectorXd& v) {
  Eigen::Vector3d out = Eigen::Vector3d::Zero();
  out.head(v.size()) = v;
  return out;
}

}  // namespace

bool InterrogationOptions::IsValid(std::string* why) const {
  if (samples < 3) {
    if (why) *why = "at least 3 samples";
    return false;
  }
  if (!(comb_scale >= 0) || !std::isfinite(comb_scale)) {
    if (why) *why = "the comb scale must be finite and >= 0";
    return false;
  }
  return true;
}

void CurvatureOf(const Eigen::Ref<const Eigen::VectorXd>& d1v, const Eigen::Ref<const Eigen::VectorXd>& d2v,
                 const Eigen::Ref<const Eigen::VectorXd>& d3v, double& kappa, double& dkappa_ds,
                 double& torsion) {
  const double speed2 = d1v.squaredNorm();
  torsion = 0.0;
  if (!(speed2 > 0)) {
    kappa = dkappa_ds = 0.0;
    return;
  }
  const double speed = std::sqrt(speed2), dot12 = d1v.dot(d2v);
  if (d1v.size() == 2) {
    // Signed plane curvature and its arc-length derivative (Fang A.1.7 and A.1.10 with the erratum's sign).
    const double cross12 = d1v[0] * d2v[1] - d2v[0] * d1v[1];
    const double cross13 = d1v[0] * d3v[1] - d3v[0] * d1v[1];
    kappa = cross12 / (speed2 * speed);
    dkappa_ds = cross13 / (speed2 * speed2) - 3.0 * kappa * dot12 / (speed2 * speed);
    return;
  }
  const Eigen::Vector3d a = Pad(d1v), b = Pad(d2v), c = Pad(d3v);
  const Eigen::Vector3d cross = a.cross(b), cross_dot = a.cross(c);  // d/du (w' x w'') = w' x w'''
  const double norm = cross.norm();
  kappa = norm / (speed2 * speed);
  // d kappa / ds = (c . c') / (|c| |w'|^4) - 3 kappa (w' . w'') / |w'|^3, c = w' x w''; where c = 0 the
  // one-sided magnitude |c'| / |w'|^4.
  dkappa_ds = norm > 0
                  ? cross.dot(cross_dot) / (norm * speed2 * speed2) - 3.0 * kappa * dot12 / (speed2 * speed)
                  : cross_dot.norm() / (speed2 * speed2);
  torsion = norm > 0 ? cross.dot(c) / (norm * norm) : 0.0;
}

InterrogatedCurve ToInterrogated(const HermiteCurve& curve) {
  InterrogatedCurve out;
  out.dimension = curve.ambient_dimension();
  out.lo = 0.0;
  out.hi = 1.0;
  out.closed = curve.closed();
  const std::vector<double>& k = curve.knots();
  out.junctions.assign(k.begin() + 1, k.end() - 1);
  if (curve.closed()) out.junctions.insert(out.junctions.begin(), 0.0);
  out.jet = [&curve](double u, int side, Jet& jet) {
    double t = 0.0;
    int e = curve.Locate(u, t);
    const int count = curve.num_elements();
    if (side < 0 && t <= 1e-14 && (e > 0 || curve.closed())) {
      e = (e + count - 1) % count;
      t = 1.0;
    } else if (side > 0 && t >= 1.0 - 1e-14 && (e + 1 < count || curve.closed())) {
      e = (e + 1) % count;
      t = 0.0;
    }
    Eigen::MatrixXd m;
    curve.EvaluateOnElement(e, t, 3, m);
    jet = m;
  };
  return out;
}

InterrogatedCurve ToInterrogated(const BSplineCurve& curve) {
  InterrogatedCurve out;
  const BSplineBasis& b = curve.basis();
  out.dimension = curve.ambient_dimension();
  out.lo = b.lo();
  out.hi = b.hi();
  out.closed = b.periodic();
  const std::vector<double> breaks = b.Breakpoints();
  out.junctions.assign(breaks.begin() + 1, breaks.end() - 1);
  if (out.closed) out.junctions.insert(out.junctions.begin(), b.lo());
  out.jet = [&curve](double u, int side, Jet& jet) {
    const BSplineBasis& basis = curve.basis();
    const double width = basis.hi() - basis.lo();
    // The span on the requested side of a breakpoint: step off it by a few ulps of the domain.
    const double eps = 1e-13 * width;
    if (side < 0) u -= eps;
    if (side > 0) u += eps;
    double y = 0.0, inv_length = 0.0;
    const int span = basis.LocateSpan(u, y, inv_length);
    const int first = basis.FirstFunction(span), order = basis.order(), s = curve.ambient_dimension();
    // Power coefficients a_j of the span in y (BSplineBasis' Taylor tables), then derivatives by y.
    Eigen::MatrixXd a = Eigen::MatrixXd::Zero(s, order);
    for (int i = 0; i < order; ++i) {
      const Eigen::VectorXd p = curve.control_points().col(basis.ControlIndex(first, i));
      for (int j = 0; j < order; ++j) a.col(j) += basis.TaylorCoefficient(span, 0, j, i) * p;
    }
    jet.setZero(s, 4);
    for (int d = 0; d < 4; ++d) {
      const double scale = std::pow(inv_length, d);
      for (int c = 0; c < s; ++c) {
        double v = 0.0;
        for (int j = order - 1; j >= d; --j) {
          double falling = 1.0;
          for (int q = 0; q < d; ++q) falling *= (j - q);
          v = v * y + falling * a(c, j);
        }
        jet(c, d) = v * scale;
      }
    }
  };
  return out;
}

CurveInterrogation InterrogateCurve(const InterrogatedCurve& curve, const InterrogationOptions& options) {
  std::string why;
  if (!options.IsValid(&why)) throw std::invalid_argument("interrogation options: " + why);
  if (!curve.jet || !(curve.hi > curve.lo)) throw std::invalid_argument("interrogation: an empty curve");
  CurveInterrogation out;
  // Pieces between junctions, each split into sub-intervals: the arc-length table by Gauss-Legendre.
  std::vector<double> breaks = {curve.lo};
  for (const double j : curve.junctions)
    if (j > curve.lo && j < curve.hi) breaks.push_back(j);
  breaks.push_back(curve.hi);
  std::vector<double> u_table = {curve.lo}, s_table = {0.0};
  Jet jet;
  double dk2 = 0.0, k2 = 0.0;
  for (std::size_t p = 0; p + 1 < breaks.size(); ++p) {
    for (int k = 0; k < kSubintervals; ++k) {
      const double a = breaks[p] + (breaks[p + 1] - breaks[p]) * k / kSubintervals;
      const double b = breaks[p] + (breaks[p + 1] - breaks[p]) * (k + 1) / kSubintervals;
      double length = 0.0;
      for (int q = 0; q < 5; ++q) {
        curve.jet(a + (b - a) * kGaussX[q], 0, jet);
        const double speed = jet.col(1).norm();
        length += kGaussW[q] * (b - a) * speed;
        double kappa = 0.0, dkds = 0.0, tau = 0.0;
        CurvatureOf(jet.col(1), jet.col(2), jet.col(3), kappa, dkds, tau);
        dk2 += kGaussW[q] * (b - a) * speed * dkds * dkds;
        k2 += kGaussW[q] * (b - a) * speed * kappa * kappa;
      }
      u_table.push_back(b);
      s_table.push_back(s_table.back() + length);
    }
  }
  out.length = s_table.back();
  out.dkappa_ds_squared = dk2;
  out.kappa_squared = k2;
  if (!(out.length > 0)) throw std::invalid_argument("interrogation: the curve has zero length");
  // s -> u: the table's sub-interval, then Newton on s(u) = s kept in it.
  auto u_at = [&](double s) {
    const auto it = std::upper_bound(s_table.begin(), s_table.end(), s);
    std::size_t i = static_cast<std::size_t>(std::max<std::ptrdiff_t>(1, it - s_table.begin()));
    i = std::min(i, s_table.size() - 1);
    double lo = u_table[i - 1], hi = u_table[i];
    const double s0 = s_table[i - 1], s1 = s_table[i];
    double u = s1 > s0 ? lo + (hi - lo) * (s - s0) / (s1 - s0) : lo;
    for (int it2 = 0; it2 < 8; ++it2) {
      // s(u) - s0 by 5-point Gauss on [lo_i, u].
      double partial = 0.0;
      const double a = u_table[i - 1];
      for (int q = 0; q < 5; ++q) {
        curve.jet(a + (u - a) * kGaussX[q], 0, jet);
        partial += kGaussW[q] * (u - a) * jet.col(1).norm();
      }
      curve.jet(u, 0, jet);
      const double speed = jet.col(1).norm();
      const double f = s0 + partial - s;
      if (std::abs(f) < 1e-13 * out.length || !(speed > 0)) break;
      u = std::clamp(u - f / speed, lo, hi);
    }
    return u;
  };
  const int n = options.samples;
  out.samples.resize(static_cast<std::size_t>(n));
  for (int i = 0; i < n; ++i) {
    CurvatureSample& c = out.samples[static_cast<std::size_t>(i)];
    c.s = static_cast<double>(i) / (n - 1);
    c.u = i == 0 ? curve.lo : (i == n - 1 ? curve.hi : u_at(c.s * out.length));
    curve.jet(c.u, i == n - 1 ? -1 : (i == 0 ? 1 : 0), jet);
    c.point = Pad(jet.col(0));
    CurvatureOf(jet.col(1), jet.col(2), jet.col(3), c.kappa, c.dkappa_ds, c.torsion);
    const Eigen::Vector3d d1 = Pad(jet.col(1)), d2 = Pad(jet.col(2));
    const Eigen::Vector3d tangent = d1.normalized();
    if (curve.dimension == 2) {
      c.normal = Eigen::Vector3d(-tangent.y(), tangent.x(), 0.0);
    } else {
      const Eigen::Vector3d k = d2 - d2.dot(tangent) * tangent;
      c.normal = k.norm() > 0 ? Eigen::Vector3d(k.normalized()) : Eigen::Vector3d::Zero();
    }
    out.max_abs_kappa = std::max(out.max_abs_kappa, std::abs(c.kappa));
  }
  // Junctions: one-sided values.
  auto s_of_u = [&](double u) {
    const auto it = std::lower_bound(u_table.begin(), u_table.end(), u);
    const std::size_t i = static_cast<std::size_t>(
        std::clamp<std::ptrdiff_t>(it - u_table.begin(), 0, static_cast<std::ptrdiff_t>(u_table.size()) - 1));
    return s_table[i] / out.length;
  };
  for (const double u : curve.junctions) {
    Jet left, right;
    const double u_left = (curve.closed && u == curve.lo) ? curve.hi : u;
    curve.jet(u_left, -1, left);
    curve.jet(u, 1, right);
    double kl = 0, dl = 0, tl = 0, kr = 0, dr = 0, tr = 0;
    CurvatureOf(left.col(1), left.col(2), left.col(3), kl, dl, tl);
    CurvatureOf(right.col(1), right.col(2), right.col(3), kr, dr, tr);
    JunctionJump j;
    j.u = u;
    j.s = s_of_u(u);
    const Eigen::Vector3d tl3 = Pad(left.col(1)).normalized(), tr3 = Pad(right.col(1)).normalized();
    j.g1 = std::atan2(tl3.cross(tr3).norm(), tl3.dot(tr3));
    if (curve.dimension == 2) {
      j.g2 = std::abs(kr - kl);
    } else {
      // Curvature vectors (w'' - (w''.T) T) / |w'|^2 on both sides.
      auto kvec = [](const Jet& jt) {
        const Eigen::Vector3d d1 = Pad(jt.col(1)), d2 = Pad(jt.col(2));
        const Eigen::Vector3d t = d1.normalized();
        return Eigen::Vector3d((d2 - d2.dot(t) * t) / d1.squaredNorm());
      };
      j.g2 = (kvec(right) - kvec(left)).norm();
    }
    j.g3 = std::abs(dr - dl);
    out.zeta += j.g3;
    out.max_g1 = std::max(out.max_g1, j.g1);
    out.max_g2 = std::max(out.max_g2, j.g2);
    out.max_abs_kappa = std::max({out.max_abs_kappa, std::abs(kl), std::abs(kr)});
    out.junctions.push_back(j);
  }
  out.comb_scale = options.comb_scale > 0
                       ? options.comb_scale
                       : (out.max_abs_kappa > 0 ? 0.5 * out.length / out.max_abs_kappa : 0.0);
  for (CurvatureSample& c : out.samples) c.comb_tip = c.point - out.comb_scale * c.kappa * c.normal;
  // Inflections of plane curves: sign changes of kappa between samples, ignoring |kappa| below 1e-6 of its
  // largest value (a straight piece is not an inflection at every sample); located by linear interpolation.
  if (curve.dimension == 2 && out.max_abs_kappa > 0) {
    const double zero = 1e-6 * out.max_abs_kappa;
    int last = 0;
    double last_s = 0.0, last_k = 0.0;
    for (const CurvatureSample& c : out.samples) {
      const int sign = c.kappa > zero ? 1 : (c.kappa < -zero ? -1 : 0);
      if (sign == 0) continue;
      if (last != 0 && sign != last)
        out.inflections.push_back(last_s + (c.s - last_s) * last_k / (last_k - c.kappa));
      last = sign;
      last_s = c.s;
      last_k = c.kappa;
    }
  }
  // Curvature extrema: sign changes of dkappa/ds between consecutive samples (a closed curve's last sample is
  // its first: the seam's change counts once), ignoring values below 1e-6 of the largest.
  double max_dk = 0.0;
  for (const CurvatureSample& c : out.samples) max_dk = std::max(max_dk, std::abs(c.dkappa_ds));
  if (max_dk > 0) {
    const double zero = 1e-6 * max_dk;
    int first = 0, last = 0;
    for (const CurvatureSample& c : out.samples) {
      const int sign = c.dkappa_ds > zero ? 1 : (c.dkappa_ds < -zero ? -1 : 0);
      if (sign == 0) continue;
      if (first == 0) first = sign;
      if (last != 0 && sign != last) ++out.curvature_extrema;
      last = sign;
    }
    if (curve.closed && first != 0 && last != 0 && first != last) ++out.curvature_extrema;
  }
  return out;
}

}  // namespace s2m
