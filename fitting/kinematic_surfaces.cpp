#include "fitting/kinematic_surfaces.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <vector>

#include "fitting/fast_atan2.h"

namespace s2m {
namespace {

// The generatrix (r(u), z(u)) and its first `derivatives` u-derivatives (at most 2): rz[2 d] = r^(d),
// rz[2 d + 1] = z^(d); higher entries are zero. Plain sums over the order's control points: the reference
// that KinematicSurface::ProfileAt's per-span power form agrees with to rounding, and SpiralSurface's
// generatrix.
void GeneratrixValues(const BSplineBasis& basis, const Eigen::Matrix2Xd& profile, double u, int derivatives,
                      double (&rz)[6]) {
  BSplineBasis::Values b;
  basis.Evaluate(u, derivatives, b);
  const int top = std::min(derivatives, 2);
  for (double& value : rz) value = 0.0;
  const double* p = profile.data();
  for (int i = 0; i < basis.order(); ++i) {
    const double* q = p + 2 * basis.ControlIndex(b.first, i);
    const auto j = static_cast<std::size_t>(i);
    for (int d = 0; d <= top; ++d) {
      const double w = b.values[static_cast<std::size_t>(d)][j];
      rz[2 * d] += w * q[0];
      rz[2 * d + 1] += w * q[1];
    }
  }
}

// The same as the columns of a 2 x 3 matrix (value, d/du, d2/du2).
Eigen::Matrix<double, 2, 3> Generatrix(const BSplineBasis& basis, const Eigen::Matrix2Xd& profile, double u,
                                       int derivatives) {
  double rz[6];
  GeneratrixValues(basis, profile, u, derivatives, rz);
  return Eigen::Map<const Eigen::Matrix<double, 2, 3>>(rz);
}

// Names of the parameters of a generatrix with one extra parameter (pitch, growth) after the profile points.
std::string GeneratrixParameterName(int index, Eigen::Index profile_size, const char* extra) {
  if (index == static_cast<int>(profile_size)) return extra;
  return std::string(index % 2 == 0 ? "radius" : "height") + " of profile point " + std::to_string(index / 2);
}

// Parameters u sampled along a generatrix: 8 steps per knot span (the u values of the surfaces' samples).
std::vector<double> GeneratrixSampleParameters(const BSplineBasis& basis) {
  std::vector<double> out;
  const std::vector<double> breaks = basis.Breakpoints();
  for (std::size_t s = 0; s + 1 < breaks.size(); ++s)
    for (int i = 0; i <= 8; ++i) out.push_back(breaks[s] + (breaks[s + 1] - breaks[s]) * i / 8);
  return out;
}

// The generatrix (r(u), z(u)) as a planar open curve, the model that a surface of revolution's feet reduce
// to. Evaluated by the same per-span power form as KinematicSurface::ProfileAt (built the same way from the
// same basis and profile), so the profile values are the surface's to the bit.
class GeneratrixCurve final : public ParametricModel {
 public:
  GeneratrixCurve(BSplineBasis basis, Eigen::Matrix2Xd profile)
      : basis_(std::move(basis)), profile_(std::move(profile)) {
    table_.Build(basis_, profile_);
  }
  std::unique_ptr<ParametricModel> Clone() const override { return std::make_unique<GeneratrixCurve>(*this); }
  void CopyFrom(const ParametricModel& other) override {
    *this = dynamic_cast<const GeneratrixCurve&>(other);
  }
  std::string name() const override { return "generatrix"; }
  int ambient_dimension() const override { return 2; }
  ParameterDomain domain() const override {
    ParameterDomain d;
    d.dimension = 1;
    d.lo = {basis_.lo(), 0.0};
    d.hi = {basis_.hi(), 0.0};
    d.periodic = {false, false};
    return d;
  }
  int num_parameters() const override { return static_cast<int>(profile_.size()); }
  std::string parameter_name(int index) const override {
    return GeneratrixParameterName(index, profile_.size(), "");
  }
  Eigen::VectorXd parameters() const override {
    return Eigen::Map<const Eigen::VectorXd>(profile_.data(), profile_.size());
  }
  void set_parameters(const Eigen::VectorXd& p) override {
    profile_ = Eigen::Map<const Eigen::Matrix2Xd>(p.data(), 2, profile_.cols());
    table_.Build(basis_, profile_);
  }
  void ApplySimilarity(double scale, const VecS& offset) override {
    profile_ *= scale;
    profile_.colwise() += Eigen::Vector2d(offset);
    table_.Build(basis_, profile_);
  }
  void Evaluate(const ParamT& t, int derivatives, LocalGeometry& out) const override {
    double r[3][3];  // r[d][c]: derivative d of coordinate c (r, z)
    table_.Evaluate(basis_, t[0], derivatives, r);
    out.point.resize(2);
    out.d1.resize(2, 1);
    out.d2.resize(2, 1);
    out.point[0] = r[0][0];
    out.point[1] = r[0][1];
    out.d1(0, 0) = r[1][0];
    out.d1(1, 0) = r[1][1];
    out.d2(0, 0) = r[2][0];
    out.d2(1, 0) = r[2][1];
  }
  void ShapeJacobian(const ParamT& t, bool with_dt, std::vector<JacobianEntry>& out) const override {
    out.clear();
    BSplineBasis::Values b;
    basis_.Evaluate(t[0], with_dt ? 1 : 0, b);
    for (int i = 0; i < basis_.order(); ++i) {
      const int k = basis_.ControlIndex(b.first, i);
      const double w = b.values[0][static_cast<std::size_t>(i)];
      const double dw = with_dt ? b.values[1][static_cast<std::size_t>(i)] : 0.0;
      for (int c = 0; c < 2; ++c) {
        JacobianEntry e;
        e.index = 2 * k + c;
        e.column = w * Eigen::Vector3d::Unit(c);
        e.dcolumn_dt = {Eigen::Vector3d(dw * Eigen::Vector3d::Unit(c)), Eigen::Vector3d::Zero()};
        out.push_back(e);
      }
    }
  }
  std::vector<ParamT> SampleParameters() const override {
    std::vector<ParamT> out;
    for (const double u : GeneratrixSampleParameters(basis_)) out.push_back({u, 0.0, 0.0});
    return out;
  }

 private:
  BSplineBasis basis_;
  Eigen::Matrix2Xd profile_;
  SpanPowerForm table_;  // of profile_, rebuilt whenever it changes
};

// The feet of a surface of revolution (pitch 0) with r(u) >= 0 everywhere, in x's meridian half-plane
// (FootPointReduction; docs/method.md section 10). With x = (rho cos phi, rho sin phi, h),
// d^2(u, v) = (rho - r)^2 + (z - h)^2 + 2 rho r (1 - cos(v - phi)): for r >= 0 the last term is >= 0 and zero
// at v = phi, so the foot is (u*, phi) with u* the foot of (rho, h) on the generatrix, at the same distance;
// and at v = phi the orthogonality residual along u is the generatrix's, so the boundary flag is too.
class RevolutionFootPoints final : public FootPointReduction {
 public:
  explicit RevolutionFootPoints(GeneratrixCurve generatrix) : generatrix_(std::move(generatrix)) {}
  const ParametricModel& reduced_model() const override { return generatrix_; }
  bool Reduce(const VecS& x, VecS& reduced_x) const override {
    reduced_x.resize(2);
    reduced_x << std::sqrt(x[0] * x[0] + x[1] * x[1]), x[2];
    return reduced_x.allFinite();
  }
  bool Lift(const VecS& x, const ParamT& reduced_t, const LocalGeometry& reduced_g, ParamT& t,
            LocalGeometry& g) const override {
    const double r = reduced_g.point[0], z = reduced_g.point[1];
    // On the axis (r = 0) every v is a foot and the surface is singular: left to the 2-D Newton.
    if (!(r > 0)) return false;
    const double r1 = reduced_g.d1(0, 0), z1 = reduced_g.d1(1, 0), r2 = reduced_g.d2(0, 0),
                 z2 = reduced_g.d2(1, 0);
    // cos v and sin v from x itself (no trigonometry); x on the axis: v = 0, every v being a foot there.
    const double rho = std::sqrt(x[0] * x[0] + x[1] * x[1]);
    double c = 1.0, s = 0.0, v = 0.0;
    if (rho > 0) {
      c = x[0] / rho;
      s = x[1] / rho;
      v = FastAtan2(x[1], x[0]);   // fitting/fast_atan2.h: std::atan2 within 2 ulp, cheaper
      if (v < 0) v += 2 * M_PI;    // the domain is [0, 2 pi)
      if (v >= 2 * M_PI) v = 0.0;  // -tiny + 2 pi rounding up to 2 pi
    }
    t = {reduced_t[0], v, 0.0};
    // KinematicSurface::Evaluate at (u*, v) with pitch 0.
    g.point = Eigen::Vector3d(r * c, r * s, z);
    g.d1.resize(3, 2);
    g.d1.col(0) = Eigen::Vector3d(r1 * c, r1 * s, z1);
    g.d1.col(1) = Eigen::Vector3d(-r * s, r * c, 0.0);
    g.d2.resize(3, 3);
    g.d2.col(0) = Eigen::Vector3d(r2 * c, r2 * s, z2);
    g.d2.col(1) = Eigen::Vector3d(-r1 * s, r1 * c, 0.0);
    g.d2.col(2) = Eigen::Vector3d(-r * c, -r * s, 0.0);
    return true;
  }

 private:
  GeneratrixCurve generatrix_;
};

}  // namespace

KinematicSurface::KinematicSurface(BSplineBasis basis, Eigen::Matrix2Xd profile, bool helical, double pitch,
                                   double turns)
    : basis_(std::move(basis)),
      profile_(std::move(profile)),
      helical_(helical),
      pitch_(pitch),
      turns_(turns) {
  if (basis_.periodic())
    throw std::invalid_argument("the generatrix of a kinematic surface is an open curve");
  if (profile_.cols() != basis_.num_control()) {
    throw std::invalid_argument("the generatrix basis has " + std::to_string(basis_.num_control()) +
                                " functions but " + std::to_string(profile_.cols()) +
                                " profile points were given");
  }
  if (helical_ && !(turns_ > 0))
    throw std::invalid_argument("a helical surface needs a positive number of turns");
  generatrix_.Build(basis_, profile_);
}

Eigen::Matrix<double, 2, 3> KinematicSurface::ProfileAt(double u, int derivatives) const {
  double r[3][3];  // r[d][c]: derivative d of coordinate c (r, z)
  generatrix_.Evaluate(basis_, u, derivatives, r);
  Eigen::Matrix<double, 2, 3> rz;
  rz << r[0][0], r[1][0], r[2][0], r[0][1], r[1][1], r[2][1];
  return rz;
}

KinematicSurface KinematicSurface::Revolution(BSplineBasis basis, Eigen::Matrix2Xd profile) {
  return KinematicSurface(std::move(basis), std::move(profile), false, 0.0, 1.0);
}

KinematicSurface KinematicSurface::Helical(BSplineBasis basis, Eigen::Matrix2Xd profile, double pitch,
                                           double turns) {
  return KinematicSurface(std::move(basis), std::move(profile), true, pitch, turns);
}

Eigen::Vector2d KinematicSurface::ProfilePoint(double u, int derivative) const {
  if (derivative < 0 || derivative > 2) throw std::invalid_argument("ProfilePoint: derivative 0, 1 or 2");
  return ProfileAt(u, derivative).col(derivative);
}

double KinematicSurface::RadiusAtHeight(double height, Eigen::VectorXd* gradient) const {
  // Bracket on samples, then Newton on z(u) = height.
  const int samples = 64 * basis_.num_control();
  double u = basis_.lo();
  bool found = false;
  // A height within rounding of a sample counts as reached there: the generatrix's end heights come from
  // another evaluation of the same spline (a caller's basis sums), equal only to the last few bits.
  const double tolerance = 1e-12 * (1.0 + std::abs(height));
  for (int i = 0; i < samples && !found; ++i) {
    const double a = basis_.lo() + (basis_.hi() - basis_.lo()) * i / samples;
    const double b = basis_.lo() + (basis_.hi() - basis_.lo()) * (i + 1) / samples;
    const double za = ProfilePoint(a).y() - height, zb = ProfilePoint(b).y() - height;
    const bool at_a = std::abs(za) <= tolerance, at_b = std::abs(zb) <= tolerance;
    // The last interval includes its end (the generatrix's end height itself is reached).
    if (at_a || za * zb < 0 || (at_b && i == samples - 1)) {
      u = at_a ? a : at_b ? b : a - za * (b - a) / (zb - za);
      found = true;
    }
  }
  if (!found) throw std::domain_error("the profile does not reach height " + std::to_string(height));
  Eigen::Vector2d point, tangent;
  double u_point = u;  // where point and tangent were evaluated
  for (int it = 0; it < 50; ++it) {
    const Eigen::Matrix<double, 2, 3> rz = ProfileAt(u, 1);
    point = rz.col(0);
    tangent = rz.col(1);
    u_point = u;
    const double du = (point.y() - height) / tangent.y();
    u = basis_.Normalize(u - du);
    if (std::abs(du) < 1e-15 * (basis_.hi() - basis_.lo())) break;
  }
  if (gradient) {
    BSplineBasis::Values v;
    basis_.Evaluate(u_point, 0, v);
    gradient->setZero(num_parameters());
    const double slope = tangent.x() / tangent.y();  // dr/dz along the profile
    for (int i = 0; i < basis_.order(); ++i) {
      const int k = basis_.ControlIndex(v.first, i);
      (*gradient)[2 * k] += v.values[0][static_cast<std::size_t>(i)];
      (*gradient)[2 * k + 1] -= slope * v.values[0][static_cast<std::size_t>(i)];
    }
  }
  return point.x();
}

double KinematicSurface::EnclosedVolume(double z_lo, double z_hi, Eigen::VectorXd* gradient) const {
  if (helical_) throw std::logic_error("an enclosed volume is defined for surfaces of revolution only");
  if (!(z_lo < z_hi)) throw std::invalid_argument("the planes of an enclosed volume need z_lo < z_hi");
  // 8-point Gauss-Legendre on [-1, 1]: exact for polynomials of degree <= 15, and r^2 z' has degree 3 d - 1
  // on a span (d the generatrix's degree); higher degrees split each piece in four.
  static const double kNodes[4] = {0.1834346424956498, 0.5255324099163290, 0.7966664774136267,
                                   0.9602898564975363};
  static const double kWeights[4] = {0.3626837833783620, 0.3137066458778873, 0.2223810344533745,
                                     0.1012285362903763};
  const int subdivisions = 3 * basis_.degree() - 1 <= 15 ? 1 : 4;
  // g(u) <= 0 where the generatrix is between the planes (eq. A2); a plane through an end leaves it inside.
  auto g = [&](double u) {
    const double z = ProfilePoint(u).y();
    return std::max(z_lo - z, z - z_hi);
  };
  if (gradient) gradient->setZero(num_parameters());
  BSplineBasis::Values values;
  double integral = 0.0;  // of r^2 z' du over the pieces between the planes
  // Adds w r(u)^2 z'(u) and its gradient (dI/dr_k = 2 r z' B_k, dI/dz_k = r^2 B_k').
  auto add = [&](double u, double w) {
    basis_.Evaluate(u, 1, values);
    double r = 0.0, dz = 0.0;
    for (int i = 0; i < basis_.order(); ++i) {
      const int k = basis_.ControlIndex(values.first, i);
      r += values.values[0][static_cast<std::size_t>(i)] * profile_(0, k);
      dz += values.values[1][static_cast<std::size_t>(i)] * profile_(1, k);
    }
    integral += w * r * r * dz;
    if (!gradient) return;
    for (int i = 0; i < basis_.order(); ++i) {
      const int k = basis_.ControlIndex(values.first, i);
      (*gradient)[2 * k] += w * 2.0 * r * dz * values.values[0][static_cast<std::size_t>(i)];
      (*gradient)[2 * k + 1] += w * r * r * values.values[1][static_cast<std::size_t>(i)];
    }
  };
  // The planes stay where they are (eq. A3): each piece [a, b] of the generatrix that is integrated gives
  // back r^2 dz/dP at its ends, -[r(u)^2 B_k(u)]_a^b on the z entries (inner ends of adjacent pieces cancel).
  auto hold_planes = [&](double u, double sign) {
    basis_.Evaluate(u, 0, values);
    double r = 0.0;
    for (int i = 0; i < basis_.order(); ++i)
      r += values.values[0][static_cast<std::size_t>(i)] * profile_(0, basis_.ControlIndex(values.first, i));
    for (int i = 0; i < basis_.order(); ++i)
      (*gradient)[2 * basis_.ControlIndex(values.first, i) + 1] +=
          sign * r * r * values.values[0][static_cast<std::size_t>(i)];
  };
  const std::vector<double>& knots = basis_.knots();
  for (std::size_t i = 0; i + 1 < knots.size(); ++i) {
    const double a = std::max(knots[i], basis_.lo()), b = std::min(knots[i + 1], basis_.hi());
    if (!(b > a)) continue;
    // Sign changes of g on 16 sub-intervals, each refined by bisection to rounding.
    std::vector<double> cuts = {a};
    double lo = a, g_lo = g(a);
    for (int j = 1; j <= 16; ++j) {
      const double hi = a + (b - a) * j / 16, g_hi = g(hi);
      if ((g_lo <= 0) != (g_hi <= 0)) {
        double x0 = lo, x1 = hi;
        const bool rising = g_hi > 0;
        for (int it = 0; it < 100 && x1 - x0 > 1e-15 * (b - a); ++it) {
          const double m = 0.5 * (x0 + x1);
          ((g(m) > 0) == rising ? x1 : x0) = m;
        }
        cuts.push_back(0.5 * (x0 + x1));
      }
      lo = hi;
      g_lo = g_hi;
    }
    cuts.push_back(b);
    for (std::size_t c = 0; c + 1 < cuts.size(); ++c) {
      if (g(0.5 * (cuts[c] + cuts[c + 1])) > 0) continue;  // outside the planes
      const double h = (cuts[c + 1] - cuts[c]) / subdivisions;
      for (int part = 0; part < subdivisions; ++part) {
        const double mid = cuts[c] + (part + 0.5) * h, half = 0.5 * h;
        for (int q = 0; q < 4; ++q) {
          add(mid - half * kNodes[q], half * kWeights[q]);
          add(mid + half * kNodes[q], half * kWeights[q]);
        }
      }
      if (gradient) {
        hold_planes(cuts[c], 1.0);
        hold_planes(cuts[c + 1], -1.0);
      }
    }
  }
  if (gradient) *gradient *= M_PI * (integral < 0 ? -1.0 : 1.0);
  return M_PI * std::abs(integral);
}

ParameterDomain KinematicSurface::domain() const {
  ParameterDomain d;
  d.dimension = 2;
  d.lo = {basis_.lo(), helical_ ? -M_PI * turns_ : 0.0};
  d.hi = {basis_.hi(), helical_ ? M_PI * turns_ : 2 * M_PI};
  d.periodic = {false, !helical_};
  return d;
}

std::string KinematicSurface::parameter_name(int index) const {
  return GeneratrixParameterName(index, profile_.size(), "pitch");
}

Eigen::VectorXd KinematicSurface::parameters() const {
  Eigen::VectorXd p(num_parameters());
  p.head(profile_.size()) = Eigen::Map<const Eigen::VectorXd>(profile_.data(), profile_.size());
  if (helical_) p[profile_.size()] = pitch_;
  return p;
}

void KinematicSurface::set_parameters(const Eigen::VectorXd& p) {
  profile_ = Eigen::Map<const Eigen::Matrix2Xd>(p.data(), 2, profile_.cols());
  if (helical_) pitch_ = p[profile_.size()];
  generatrix_.Build(basis_, profile_);
}

void KinematicSurface::ApplySimilarity(double scale, const VecS& offset) {
  if (offset.size() >= 2 && (offset[0] != 0.0 || offset[1] != 0.0)) {
    throw std::logic_error(
        "a kinematic surface is tied to its frame: only shifts along its axis are representable");
  }
  profile_ *= scale;
  if (offset.size() == 3) profile_.row(1).array() += offset[2];
  pitch_ *= scale;
  generatrix_.Build(basis_, profile_);
}

void KinematicSurface::Evaluate(const ParamT& t, int derivatives, LocalGeometry& out) const {
  const Eigen::Matrix<double, 2, 3> rz = ProfileAt(t[0], derivatives);  // value, d/du, d2/du2
  const double v = t[1], c = std::cos(v), s = std::sin(v);
  const double r = rz(0, 0), z = rz(1, 0), r1 = rz(0, 1), z1 = rz(1, 1), r2 = rz(0, 2), z2 = rz(1, 2);
  // Element writes into the (fixed-capacity) outputs: no zero fill then column copies on this hot path.
  out.point.resize(3);
  out.d1.resize(3, 2);
  out.d2.resize(3, 3);
  out.point[0] = r * c;
  out.point[1] = r * s;
  out.point[2] = z + pitch_ * v;
  const bool first = derivatives >= 1, second = derivatives >= 2;
  out.d1(0, 0) = first ? r1 * c : 0.0;
  out.d1(1, 0) = first ? r1 * s : 0.0;
  out.d1(2, 0) = first ? z1 : 0.0;
  out.d1(0, 1) = first ? -r * s : 0.0;
  out.d1(1, 1) = first ? r * c : 0.0;
  out.d1(2, 1) = first ? pitch_ : 0.0;
  out.d2(0, 0) = second ? r2 * c : 0.0;
  out.d2(1, 0) = second ? r2 * s : 0.0;
  out.d2(2, 0) = second ? z2 : 0.0;
  out.d2(0, 1) = second ? -r1 * s : 0.0;
  out.d2(1, 1) = second ? r1 * c : 0.0;
  out.d2(2, 1) = 0.0;
  out.d2(0, 2) = second ? -r * c : 0.0;
  out.d2(1, 2) = second ? -r * s : 0.0;
  out.d2(2, 2) = 0.0;
}

void KinematicSurface::ShapeJacobian(const ParamT& t, bool with_dt, std::vector<JacobianEntry>& out) const {
  out.clear();
  BSplineBasis::Values b;
  basis_.Evaluate(t[0], with_dt ? 1 : 0, b);
  const double v = t[1], c = std::cos(v), s = std::sin(v);
  for (int i = 0; i < basis_.order(); ++i) {
    const int k = basis_.ControlIndex(b.first, i);
    const double w = b.values[0][static_cast<std::size_t>(i)];
    const double dw = with_dt ? b.values[1][static_cast<std::size_t>(i)] : 0.0;
    JacobianEntry radius, height;
    radius.index = 2 * k;
    radius.column = w * Eigen::Vector3d(c, s, 0.0);
    radius.dcolumn_dt = {
        Eigen::Vector3d(dw * Eigen::Vector3d(c, s, 0.0)),
        with_dt ? Eigen::Vector3d(w * Eigen::Vector3d(-s, c, 0.0)) : Eigen::Vector3d::Zero()};
    height.index = 2 * k + 1;
    height.column = w * Eigen::Vector3d::UnitZ();
    height.dcolumn_dt = {Eigen::Vector3d(dw * Eigen::Vector3d::UnitZ()), Eigen::Vector3d::Zero()};
    out.push_back(radius);
    out.push_back(height);
  }
  if (helical_) {
    JacobianEntry pitch;
    pitch.index = static_cast<int>(profile_.size());
    pitch.column = Eigen::Vector3d(0.0, 0.0, v);
    pitch.dcolumn_dt = {Eigen::Vector3d::Zero(),
                        with_dt ? Eigen::Vector3d(Eigen::Vector3d::UnitZ()) : Eigen::Vector3d::Zero()};
    out.push_back(pitch);
  }
}

bool KinematicSurface::FactoredShapeJacobian(const ParamT& t, FactoredJacobian& out) const {
  if (helical_ || basis_.order() > FactoredJacobian::kMaxWeights) return false;
  BSplineBasis::Values b;
  basis_.Evaluate(t[0], 0, b);
  out.weight_count = basis_.order();
  for (int i = 0; i < basis_.order(); ++i) {
    const auto j = static_cast<std::size_t>(i);
    out.first_index[j] = 2 * basis_.ControlIndex(b.first, i);
    out.weights[j] = b.values[0][j];
  }
  out.direction_count = 2;
  out.directions << std::cos(t[1]), 0.0, 0.0,  //
      std::sin(t[1]), 0.0, 0.0,                //
      0.0, 1.0, 0.0;
  return true;
}

Eigen::MatrixXd KinematicSurface::FairnessMatrix(const FairnessWeights& w) const {
  if (w.IsZero()) return {};
  const int n = basis_.num_control();
  // Fairness of the generatrix (r(u), z(u)) as a plane curve (docs/method.md section 3, docs/fair-curves.md
  // section 8).
  const Eigen::MatrixXd k = CurveFairness(basis_, w);
  Eigen::MatrixXd out = Eigen::MatrixXd::Zero(num_parameters(), num_parameters());
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < n; ++j)
      for (int c = 0; c < 2; ++c) out(2 * i + c, 2 * j + c) = k(i, j);
  return out;
}

std::vector<ParamT> KinematicSurface::SampleParameters() const {
  std::vector<ParamT> out;
  const ParameterDomain d = domain();
  const int angles = helical_ ? static_cast<int>(48 * turns_) : 48;
  for (const double u : GeneratrixSampleParameters(basis_))
    for (int a = 0; a < angles; ++a) out.push_back({u, d.lo[1] + (d.hi[1] - d.lo[1]) * (a + 0.5) / angles});
  return out;
}

std::optional<ParamT> KinematicSurface::ContinuationSeed(const ParamT& t) const {
  if (!helical_) return std::nullopt;
  // H(u, v + 2 pi) = H(u, v) + 2 pi p a: one turn on, the same generatrix one lead further along the axis.
  // When the generatrix spans about one lead, its end at v lies where its start lies at v + 2 pi.
  const double span = basis_.hi() - basis_.lo(), tolerance = 1e-9 * span;
  ParamT seed = t;
  if (t[0] >= basis_.hi() - tolerance) {
    seed[0] = basis_.lo();
    seed[1] = t[1] + 2 * M_PI;
  } else if (t[0] <= basis_.lo() + tolerance) {
    seed[0] = basis_.hi();
    seed[1] = t[1] - 2 * M_PI;
  } else {
    return std::nullopt;
  }
  if (seed[1] < -M_PI * turns_ || seed[1] > M_PI * turns_) return std::nullopt;
  return seed;
}

std::unique_ptr<FootPointReduction> KinematicSurface::MakeFootPointReduction() const {
  if (helical_ || !(profile_.row(0).minCoeff() >= 0.0)) return nullptr;
  return std::make_unique<RevolutionFootPoints>(GeneratrixCurve(basis_, profile_));
}

std::vector<Motion6> KinematicSurface::InvariantMotions() const {
  // A rotation about the axis (with the screw's axial advance for helical surfaces) maps the surface onto
  // itself.
  Motion6 screw;
  screw << 0, 0, 1, 0, 0, pitch_;
  return {screw};
}

std::vector<Motion6> KinematicSurface::CommonMotionsAbsorbedByShape() const {
  Motion6 axial;
  axial << 0, 0, 0, 0, 0, 1;  // every z_k shifts with a common axial translation of all scans
  return {axial};
}

// ---- SpiralSurface
// ------------------------------------------------------------------------------------------------

SpiralSurface::SpiralSurface(BSplineBasis basis, Eigen::Matrix2Xd profile, double growth, double v_lo,
                             double v_hi)
    : basis_(std::move(basis)), profile_(std::move(profile)), growth_(growth), v_lo_(v_lo), v_hi_(v_hi) {
  if (basis_.periodic()) throw std::invalid_argument("the generatrix of a spiral surface is an open curve");
  if (profile_.cols() != basis_.num_control()) throw std::invalid_argument("profile and basis sizes differ");
  if (!(v_hi_ > v_lo_)) throw std::invalid_argument("empty angle range for the spiral surface");
}

SpiralSurface SpiralSurface::WithAllometry(double growth_change, double axial_excess) const {
  SpiralSurface out = *this;
  out.allometric_ = true;
  out.growth_change_ = growth_change;
  out.axial_excess_ = axial_excess;
  out.allometry_reference_ = 0.5 * (v_lo_ + v_hi_);
  return out;
}

SpiralSurface SpiralSurface::WithGeneratrix(BSplineBasis basis, Eigen::Matrix2Xd profile) const {
  SpiralSurface out(std::move(basis), std::move(profile), growth_, v_lo_, v_hi_);
  out.allometric_ = allometric_;
  out.growth_change_ = growth_change_;
  out.axial_excess_ = axial_excess_;
  out.allometry_reference_ = allometry_reference_;
  return out;
}

SpiralSurface SpiralSurface::WithAngleRange(double v_lo, double v_hi) const {
  if (!(v_hi > v_lo)) throw std::invalid_argument("empty angle range for the spiral surface");
  SpiralSurface out = *this;
  out.v_lo_ = v_lo;
  out.v_hi_ = v_hi;
  return out;
}

double SpiralSurface::WhorlExpansionRate() const {
  return std::exp(2.0 * M_PI * growth_);
}

Eigen::Vector4d SpiralSurface::Extents() const {
  return ExtentsBetween(basis_.lo(), basis_.hi(), CurvePoint(basis_.lo()), CurvePoint(basis_.hi()));
}

Eigen::Vector2d SpiralSurface::CurvePoint(double u, int derivative) const {
  if (derivative < 0 || derivative > 2) throw std::invalid_argument("CurvePoint: derivative 0, 1 or 2");
  return Generatrix(basis_, profile_, std::clamp(u, basis_.lo(), basis_.hi()), derivative).col(derivative);
}

Eigen::Vector4d SpiralSurface::ExtentsBetween(double u_lo, double u_hi, const Eigen::Vector2d& end_lo,
                                              const Eigen::Vector2d& end_hi) const {
  if (!(u_lo <= u_hi)) throw std::invalid_argument("ExtentsBetween: u_lo > u_hi (or NaN)");
  u_lo = std::clamp(u_lo, basis_.lo(), basis_.hi());
  u_hi = std::clamp(u_hi, basis_.lo(), basis_.hi());
  double r_min = std::numeric_limits<double>::infinity(), r_max = -r_min, z_min = r_min, z_max = -r_min;
  auto take = [&](const Eigen::Vector2d& rz) {
    r_min = std::min(r_min, rz.x());
    r_max = std::max(r_max, rz.x());
    z_min = std::min(z_min, rz.y());
    z_max = std::max(z_max, rz.y());
  };
  // Eq. S5a: the end point moved onto the tangent line c + s t at its end, s = t . (p - c) / |t|^2.
  auto onto_tangent = [&](double u, const Eigen::Vector2d& p) {
    const Eigen::Matrix<double, 2, 3> rz = Generatrix(basis_, profile_, u, 1);
    const Eigen::Vector2d c = rz.col(0), t = rz.col(1);
    const double tt = t.squaredNorm();
    return tt > 0 ? Eigen::Vector2d(c + t * (t.dot(p - c) / tt)) : c;
  };
  take(onto_tangent(u_lo, end_lo));
  take(onto_tangent(u_hi, end_hi));
  constexpr int kSamples = 2001;
  for (int i = 1; i + 1 < kSamples; ++i)
    take(Generatrix(basis_, profile_, u_lo + (u_hi - u_lo) * i / (kSamples - 1), 0).col(0));
  return {r_min, r_max, z_min, z_max};
}

SpiralSurface::Scales SpiralSurface::ScalesAt(double v) const {
  // Eq. S1: g(v) = p v + q (v - v_c)^2 / 2 radially, g(v) + a (v - v_c) axially.
  const double w = v - allometry_reference_;
  const double g = growth_ * v + 0.5 * growth_change_ * w * w, rate = growth_ + growth_change_ * w;
  return {std::exp(g), std::exp(g + axial_excess_ * w), rate, rate + axial_excess_};
}

SpiralSurface::Raup SpiralSurface::RaupParameters() const {
  return RaupParameters(Extents());
}

SpiralSurface::Raup SpiralSurface::RaupParameters(const Eigen::Vector4d& e) const {
  const double r_min = e[0], r_max = e[1], z_min = e[2], z_max = e[3];
  Raup out;
  out.w = WhorlExpansionRate();
  out.d = r_min >= 0 && r_max > 0 ? r_min / r_max : std::numeric_limits<double>::quiet_NaN();
  const double r_c = 0.5 * (r_min + r_max), z_c = 0.5 * (z_min + z_max);
  out.t = r_c > 0 ? z_c / r_c : std::numeric_limits<double>::quiet_NaN();
  return out;
}

SpiralSurface::Whorl SpiralSurface::WhorlAt(double v) const {
  return WhorlAt(v, Extents());
}

SpiralSurface::Whorl SpiralSurface::WhorlAt(double v, const Eigen::Vector4d& e) const {
  const Scales here = ScalesAt(v), opposite = ScalesAt(v - M_PI);
  Whorl w;
  w.height = here.axial * (e[3] - e[2]);                                        // eq. S4
  w.width = here.radial * (e[1] - e[0]);                                        // eq. S4
  w.umbilical_width = e[0] > 0 ? e[0] * (here.radial + opposite.radial) : 0.0;  // eq. S5
  w.diameter = std::max(0.0, e[1]) * (here.radial + opposite.radial);           // eq. S6
  return w;
}

SpiralSurface::GrowingTube SpiralSurface::GrowingTubeFromRaup(const Raup& raup) {
  GrowingTube g;
  if (!(raup.w > 1 && raup.d > -1 && raup.d < 1 && std::isfinite(raup.t))) {
    const double nan = std::numeric_limits<double>::quiet_NaN();
    return {nan, nan, nan};
  }
  // Eq. A18: the generating circle of radius r = r0 W^(theta / 2 pi) has its centre at r (rho, 0, h) turned
  // by theta about the axis, rho = (1 + D) / (1 - D) (so inner over outer edge is D) and h = 2 T_N / (1 - D)
  // with T_N = T (1 + D) / 2 the centre's height over the outer edge's distance.
  const double L = std::log(raup.w), d = raup.d, t_n = raup.t * (1 + d) / 2;
  const double four_pi2 = 4 * M_PI * M_PI;
  // Eq. A19: |dc/dtheta| = r sqrt(Lambda) / (2 pi (1 - D)).
  const double lambda = four_pi2 * (1 + d) * (1 + d) + L * L * ((1 + d) * (1 + d) + 4 * t_n * t_n);
  // Eq. A20: E = (dr/dtheta) / (ds/dtheta); C and T from the helix' curvature and torsion times r.
  g.expansion = (1 - d) * L / std::sqrt(lambda);
  g.curvature = 2 * M_PI * (1 - d * d) * std::sqrt(four_pi2 + L * L) / lambda;
  g.torsion = 4 * M_PI * t_n * (1 - d) * L / lambda;
  return g;
}

ParameterDomain SpiralSurface::domain() const {
  ParameterDomain d;
  d.dimension = 2;
  d.lo = {basis_.lo(), v_lo_};
  d.hi = {basis_.hi(), v_hi_};
  d.periodic = {false, false};
  return d;
}

std::string SpiralSurface::parameter_name(int index) const {
  const auto after = static_cast<int>(profile_.size()) + 1;
  if (index == after) return "growth_change";
  if (index == after + 1) return "axial_excess";
  return GeneratrixParameterName(index, profile_.size(), "growth");
}

Eigen::VectorXd SpiralSurface::parameters() const {
  Eigen::VectorXd p(num_parameters());
  p.head(profile_.size()) = Eigen::Map<const Eigen::VectorXd>(profile_.data(), profile_.size());
  p[profile_.size()] = growth_;
  if (allometric_) p.tail(2) << growth_change_, axial_excess_;
  return p;
}

void SpiralSurface::set_parameters(const Eigen::VectorXd& p) {
  profile_ = Eigen::Map<const Eigen::Matrix2Xd>(p.data(), 2, profile_.cols());
  growth_ = p[profile_.size()];
  if (allometric_) {
    growth_change_ = p[profile_.size() + 1];
    axial_excess_ = p[profile_.size() + 2];
  }
}

void SpiralSurface::ApplySimilarity(double scale, const VecS& offset) {
  if (offset.size() > 0 && offset.cwiseAbs().maxCoeff() != 0.0) {
    throw std::logic_error("a spiral surface is tied to its frame: only scaling is representable");
  }
  profile_ *= scale;
}

void SpiralSurface::Evaluate(const ParamT& t, int derivatives, LocalGeometry& out) const {
  const Eigen::Matrix<double, 2, 3> rz = Generatrix(basis_, profile_, t[0], derivatives);
  const double v = std::clamp(t[1], v_lo_, v_hi_), c = std::cos(v), s = std::sin(v);
  // Eq. S1: x = (E r cos v, E r sin v, F z), E = e^{g(v)}, F = e^{g(v) + a (v - v_c)}; E' = g' E, F' = h F
  // with g' = p + q (v - v_c), h = g' + a, and E'' = (q + g'^2) E, F'' = (q + h^2) F.
  const Scales k = ScalesAt(v);
  const double E = k.radial, F = k.axial, g = k.radial_rate, h = k.axial_rate, q = growth_change_;
  out.point = Eigen::Vector3d(E * rz(0, 0) * c, E * rz(0, 0) * s, F * rz(1, 0));
  out.d1.setZero(3, 2);
  out.d2.setZero(3, 3);
  if (derivatives >= 1) {
    out.d1.col(0) = Eigen::Vector3d(E * rz(0, 1) * c, E * rz(0, 1) * s, F * rz(1, 1));
    out.d1.col(1) = Eigen::Vector3d(E * rz(0, 0) * (g * c - s), E * rz(0, 0) * (g * s + c), h * F * rz(1, 0));
  }
  if (derivatives >= 2) {
    out.d2.col(0) = Eigen::Vector3d(E * rz(0, 2) * c, E * rz(0, 2) * s, F * rz(1, 2));
    out.d2.col(1) = Eigen::Vector3d(E * rz(0, 1) * (g * c - s), E * rz(0, 1) * (g * s + c), h * F * rz(1, 1));
    const double radial = q + g * g - 1.0;
    out.d2.col(2) = Eigen::Vector3d(E * rz(0, 0) * (radial * c - 2.0 * g * s),
                                    E * rz(0, 0) * (radial * s + 2.0 * g * c), (q + h * h) * F * rz(1, 0));
  }
}

void SpiralSurface::ShapeJacobian(const ParamT& t, bool with_dt, std::vector<JacobianEntry>& out) const {
  out.clear();
  BSplineBasis::Values b;
  basis_.Evaluate(t[0], with_dt ? 1 : 0, b);
  const double v = std::clamp(t[1], v_lo_, v_hi_), c = std::cos(v), s = std::sin(v);
  const Scales k = ScalesAt(v);
  const double E = k.radial, F = k.axial, g = k.radial_rate, h = k.axial_rate;
  const Eigen::Vector3d radial_direction(c, s, 0.0), radial_turn(g * c - s, g * s + c, 0.0);
  for (int i = 0; i < basis_.order(); ++i) {
    const int index = basis_.ControlIndex(b.first, i);
    const double w = b.values[0][static_cast<std::size_t>(i)];
    const double dw = with_dt ? b.values[1][static_cast<std::size_t>(i)] : 0.0;
    JacobianEntry radius, height;
    radius.index = 2 * index;
    radius.column = E * w * radial_direction;
    radius.dcolumn_dt = {Eigen::Vector3d(E * dw * radial_direction),
                         with_dt ? Eigen::Vector3d(E * w * radial_turn) : Eigen::Vector3d::Zero()};
    height.index = 2 * index + 1;
    height.column = F * w * Eigen::Vector3d::UnitZ();
    height.dcolumn_dt = {
        Eigen::Vector3d(F * dw * Eigen::Vector3d::UnitZ()),
        with_dt ? Eigen::Vector3d(h * F * w * Eigen::Vector3d::UnitZ()) : Eigen::Vector3d::Zero()};
    out.push_back(radius);
    out.push_back(height);
  }
  LocalGeometry geo;
  Evaluate(t, with_dt ? 1 : 0, geo);
  const Eigen::Vector3d x = geo.point,
                        x_u = with_dt ? Eigen::Vector3d(geo.d1.col(0)) : Eigen::Vector3d::Zero(),
                        x_v = with_dt ? Eigen::Vector3d(geo.d1.col(1)) : Eigen::Vector3d::Zero();
  // d/dp of x is v x (both scales carry p v); with w = v - v_c, d/dq is (w^2 / 2) x and d/da is w times x's
  // axial component.
  JacobianEntry growth;
  growth.index = static_cast<int>(profile_.size());
  growth.column = v * x;
  growth.dcolumn_dt = {Eigen::Vector3d(v * x_u),
                       with_dt ? Eigen::Vector3d(x + v * x_v) : Eigen::Vector3d::Zero()};
  out.push_back(growth);
  if (allometric_) {
    JacobianEntry change, excess;
    change.index = growth.index + 1;
    const double w = v - allometry_reference_;
    change.column = 0.5 * w * w * x;
    change.dcolumn_dt = {Eigen::Vector3d(0.5 * w * w * x_u),
                         with_dt ? Eigen::Vector3d(w * x + 0.5 * w * w * x_v) : Eigen::Vector3d::Zero()};
    excess.index = growth.index + 2;
    excess.column = Eigen::Vector3d(0.0, 0.0, w * x.z());
    excess.dcolumn_dt = {Eigen::Vector3d(0.0, 0.0, w * x_u.z()),
                         with_dt ? Eigen::Vector3d(0.0, 0.0, x.z() + w * x_v.z()) : Eigen::Vector3d::Zero()};
    out.push_back(change);
    out.push_back(excess);
  }
}

std::vector<ParamT> SpiralSurface::SampleParameters() const {
  std::vector<ParamT> out;
  const std::vector<double> breaks = basis_.Breakpoints();
  const int angles = std::max(16, static_cast<int>(24 * (v_hi_ - v_lo_) / M_PI));
  for (std::size_t s = 0; s + 1 < breaks.size(); ++s)
    for (int i = 0; i <= 8; ++i)
      for (int a = 0; a <= angles; ++a) {
        out.push_back(
            {breaks[s] + (breaks[s + 1] - breaks[s]) * i / 8, v_lo_ + (v_hi_ - v_lo_) * a / angles});
      }
  return out;
}

std::vector<Motion6> SpiralSurface::CommonMotionsAbsorbedByShape() const {
  Motion6 rotation;
  rotation << 0, 0, 1, 0, 0, 0;
  return {rotation};
}

}  // namespace s2m
