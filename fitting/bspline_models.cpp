#include "fitting/bspline_models.h"

#include <Eigen/Geometry>
#include <cmath>
#include <stdexcept>

#include "fitting/spline_energy.h"

namespace s2m {
namespace {

const char* kAxis[3] = {"x", "y", "z"};

ParameterDomain DomainOf(const BSplineBasis& b, int dimension) {
  ParameterDomain d;
  d.dimension = dimension;
  d.lo[0] = b.lo();
  d.hi[0] = b.hi();
  d.periodic[0] = b.periodic();
  return d;
}

// Gram matrix of one basis as an Eigen matrix.
Eigen::MatrixXd Gram(const BSplineBasis& b, int derivative) {
  const std::vector<double> g = b.GramMatrix(derivative);
  const int n = b.num_control();
  return Eigen::Map<const Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>>(g.data(), n,
                                                                                                  n);
}

}  // namespace

Eigen::MatrixXd CurveFairness(const BSplineBasis& b, const FairnessWeights& w) {
  Eigen::MatrixXd k = Eigen::MatrixXd::Zero(b.num_control(), b.num_control());
  if (w.stretch != 0.0) k += w.stretch * SplineEnergyMatrix(b, 1);
  if (w.bending != 0.0 && b.order() > 2) k += w.bending * SplineEnergyMatrix(b, 2);
  if (w.variation != 0.0 && b.order() > 3) k += w.variation * SplineEnergyMatrix(b, 3);
  if (w.jump2 != 0.0 && b.order() > 2) k += w.jump2 * SplineJumpMatrix(b, 2);
  if (w.jump3 != 0.0 && b.order() > 3) k += w.jump3 * SplineJumpMatrix(b, 3);
  return k;
}

namespace {

// K (x) I_s for parameters stacked point by point (index = point * s + coordinate).
Eigen::MatrixXd KroneckerIdentity(const Eigen::MatrixXd& k, int s) {
  Eigen::MatrixXd out = Eigen::MatrixXd::Zero(k.rows() * s, k.cols() * s);
  for (Eigen::Index i = 0; i < k.rows(); ++i)
    for (Eigen::Index j = 0; j < k.cols(); ++j)
      for (int c = 0; c < s; ++c) out(i * s + c, j * s + c) = k(i, j);
  return out;
}

std::vector<double> SpanSamples(const BSplineBasis& b, int per_span) {
  std::vector<double> out;
  const std::vector<double> breaks = b.Breakpoints();
  for (std::size_t s = 0; s + 1 < breaks.size(); ++s) {
    for (int i = 0; i < per_span; ++i)
      out.push_back(breaks[s] + (breaks[s + 1] - breaks[s]) * (i + 0.5) / per_span);
  }
  if (!b.periodic()) {
    out.push_back(b.lo());
    out.push_back(b.hi());
  }
  return out;
}

}  // namespace

// ---- SpanPowerForm
// ------------------------------------------------------------------------------------------------

void SpanPowerForm::Build(const BSplineBasis& basis, const Eigen::Ref<const Eigen::MatrixXd>& control) {
  const int k = basis.order(), n = basis.num_control(), s = static_cast<int>(control.rows());
  if (s > 3 || control.cols() != n)
    throw std::invalid_argument("power-form tables take up to 3 x num_control control points");
  dimension_ = s;
  coefficients_.assign(static_cast<std::size_t>(3 * k * basis.num_spans()), 0.0);
  // a_j = sum_i c_ji P_(first + i), c_ji the Taylor coefficients of the basis functions on the span (the
  // change to the local power basis, Piegl & Tiller section 6.6).
  for (int span = 0; span < basis.num_spans(); ++span) {
    const int first = basis.FirstFunction(span);
    double* a = coefficients_.data() + 3 * static_cast<std::ptrdiff_t>(span) * k;
    for (int i = 0; i < k; ++i) {
      const int index = (first + i) % n;
      for (int j = 0; j < k; ++j) {
        const double w = basis.TaylorCoefficient(span, 0, j, i);
        for (int c = 0; c < s; ++c) a[3 * j + c] += w * control(c, index);
      }
    }
  }
}

namespace {

// C, dC/dy, d2C/dy2 of the span polynomial C(y) = sum_j a_j y^j (degree K - 1) by Horner's rule, in the
// first L of the 3 lanes (the others are the padding's zeros).
template <int K, int L>
void SpanPolynomial(const double* a, double y, double (&r)[3][3]) {
  for (int c = 0; c < L; ++c) {
    double v = a[3 * (K - 1) + c], d1 = 0.0, d2 = 0.0;
    for (int j = K - 2; j >= 0; --j) {  // derivatives by the same recurrence (Horner, differentiated)
      d2 = d2 * y + 2.0 * d1;
      d1 = d1 * y + v;
      v = v * y + a[3 * j + c];
    }
    r[0][c] = v;
    r[1][c] = d1;
    r[2][c] = d2;
  }
  for (int c = L; c < 3; ++c) r[0][c] = r[1][c] = r[2][c] = 0.0;
}

template <int L>
void SpanPolynomialOfOrder(int order, const double* a, double y, double (&r)[3][3]) {
  switch (order) {
    case 2:
      SpanPolynomial<2, L>(a, y, r);
      break;
    case 3:
      SpanPolynomial<3, L>(a, y, r);
      break;
    case 4:
      SpanPolynomial<4, L>(a, y, r);
      break;
    case 5:
      SpanPolynomial<5, L>(a, y, r);
      break;
    case 6:
      SpanPolynomial<6, L>(a, y, r);
      break;
    case 7:
      SpanPolynomial<7, L>(a, y, r);
      break;
    default:
      SpanPolynomial<8, L>(a, y, r);
      break;
  }
}

}  // namespace

void SpanPowerForm::Evaluate(const BSplineBasis& basis, double t, int derivatives, double (&r)[3][3]) const {
  double y = 0.0, inv_length = 0.0;
  const int span = basis.LocateSpan(t, y, inv_length);
  const double* a = coefficients_.data() + 3 * static_cast<std::ptrdiff_t>(span) * basis.order();
  // Plane curves (the kinematic generatrices) skip the third lane's Horner steps.
  if (dimension_ == 2)
    SpanPolynomialOfOrder<2>(basis.order(), a, y, r);
  else
    SpanPolynomialOfOrder<3>(basis.order(), a, y, r);
  // Chain rule: d/dt = (1 / length) d/dy.
  const double f1 = derivatives >= 1 ? inv_length : 0.0,
               f2 = derivatives >= 2 ? inv_length * inv_length : 0.0;
  for (int c = 0; c < 3; ++c) {
    r[1][c] *= f1;
    r[2][c] *= f2;
  }
}

// ---- BSplineCurve
// -------------------------------------------------------------------------------------------------

BSplineCurve::BSplineCurve(BSplineBasis basis, Eigen::MatrixXd control_points)
    : basis_(std::move(basis)), control_(std::move(control_points)) {
  if (control_.rows() != 2 && control_.rows() != 3)
    throw std::invalid_argument("a B-spline curve lives in 2D or 3D");
  if (control_.cols() != basis_.num_control()) {
    throw std::invalid_argument("the basis has " + std::to_string(basis_.num_control()) + " functions but " +
                                std::to_string(control_.cols()) + " control points were given");
  }
  spans_.Build(basis_, control_);
}

ParameterDomain BSplineCurve::domain() const {
  return DomainOf(basis_, 1);
}

std::string BSplineCurve::parameter_name(int index) const {
  const int s = ambient_dimension();
  return "control point " + std::to_string(index / s) + " " + kAxis[index % s];
}

Eigen::VectorXd BSplineCurve::parameters() const {
  return Eigen::Map<const Eigen::VectorXd>(control_.data(), control_.size());
}

void BSplineCurve::set_parameters(const Eigen::VectorXd& p) {
  control_ = Eigen::Map<const Eigen::MatrixXd>(p.data(), control_.rows(), control_.cols());
  spans_.Build(basis_, control_);
}

void BSplineCurve::ApplySimilarity(double scale, const VecS& offset) {
  control_ = (scale * control_).colwise() + Eigen::VectorXd(offset);
  spans_.Build(basis_, control_);
}

void BSplineCurve::Evaluate(const ParamT& t, int derivatives, LocalGeometry& out) const {
  double r[3][3];
  spans_.Evaluate(basis_, t[0], derivatives, r);
  const int s = static_cast<int>(control_.rows());
  out.point.resize(s);
  out.d1.resize(s, 1);
  out.d2.resize(s, 1);
  for (int c = 0; c < s; ++c) {
    out.point[c] = r[0][c];
    out.d1(c, 0) = r[1][c];
    out.d2(c, 0) = r[2][c];
  }
}

void BSplineCurve::ShapeJacobian(const ParamT& t, bool with_dt, std::vector<JacobianEntry>& out) const {
  out.clear();
  BSplineBasis::Values v;
  basis_.Evaluate(t[0], with_dt ? 1 : 0, v);
  const int s = ambient_dimension();
  for (int i = 0; i < basis_.order(); ++i) {
    const int point = basis_.ControlIndex(v.first, i);
    for (int c = 0; c < s; ++c) {
      JacobianEntry e;
      e.index = point * s + c;
      e.column = v.values[0][static_cast<std::size_t>(i)] * Eigen::Vector3d::Unit(c);
      e.dcolumn_dt[0] =
          with_dt ? Eigen::Vector3d(v.values[1][static_cast<std::size_t>(i)] * Eigen::Vector3d::Unit(c))
                  : Eigen::Vector3d::Zero();
      e.dcolumn_dt[1].setZero();
      out.push_back(e);
    }
  }
}

bool BSplineCurve::FactoredShapeJacobian(const ParamT& t, FactoredJacobian& out) const {
  if (basis_.order() > FactoredJacobian::kMaxWeights) return false;
  BSplineBasis::Values v;
  basis_.Evaluate(t[0], 0, v);
  const int s = ambient_dimension();
  out.weight_count = basis_.order();
  for (int i = 0; i < basis_.order(); ++i) {
    const auto k = static_cast<std::size_t>(i);
    out.first_index[k] = s * basis_.ControlIndex(v.first, i);
    out.weights[k] = v.values[0][k];
  }
  out.direction_count = s;
  out.directions = Eigen::Matrix3d::Identity();
  if (s < 3) out.directions.rightCols(3 - s).setZero();
  return true;
}

Eigen::MatrixXd BSplineCurve::FairnessMatrix(const FairnessWeights& w) const {
  if (w.IsZero()) return {};
  // F_1 = integral |C'|^2 = P^T (G1 (x) I) P and F_2 likewise (docs/method.md section 3; Wang et al. 2006,
  // section 5), and Fang's curvature variation and junction jumps (docs/fair-curves.md section 8).
  return KroneckerIdentity(CurveFairness(basis_, w), ambient_dimension());
}

std::vector<ParamT> BSplineCurve::SampleParameters() const {
  std::vector<ParamT> out;
  for (double t : SpanSamples(basis_, 16)) out.push_back({t, 0.0});
  return out;
}

// ---- BSplineSurface
// -------------------------------------------------------------------------------------------------

BSplineSurface::BSplineSurface(BSplineBasis basis_u, BSplineBasis basis_v, Eigen::Matrix3Xd control_points)
    : basis_u_(std::move(basis_u)), basis_v_(std::move(basis_v)), control_(std::move(control_points)) {
  if (basis_v_.periodic()) throw std::invalid_argument("B-spline surfaces may be periodic in u only");
  if (control_.cols() != basis_u_.num_control() * basis_v_.num_control()) {
    throw std::invalid_argument(
        "a " + std::to_string(basis_u_.num_control()) + " x " + std::to_string(basis_v_.num_control()) +
        " surface needs that many control points, got " + std::to_string(control_.cols()));
  }
  BuildPatches();
}

void BSplineSurface::BuildPatches() {
  patches_.clear();
  if (basis_u_.order() != 4 || basis_v_.order() != 4) return;
  const int su_count = basis_u_.num_spans(), sv_count = basis_v_.num_spans();
  const int nu = basis_u_.num_control(), nv = basis_v_.num_control();
  patches_.assign(static_cast<std::size_t>(64 * su_count * sv_count), 0.0);
  // A_jk = sum_i sum_l a_ji b_kl P_(first_u + i),(first_v + l), with a_ji, b_kl the Taylor coefficients of
  // the basis functions on the two spans (the change from the B-spline to the local power basis, Piegl &
  // Tiller section 6.6; here from the tables of BSplineBasis).
  for (int su = 0; su < su_count; ++su) {
    const int fu = basis_u_.FirstFunction(su);
    for (int sv = 0; sv < sv_count; ++sv) {
      const int fv = basis_v_.FirstFunction(sv);
      double* a = patches_.data() + 64 * (static_cast<std::ptrdiff_t>(su) * sv_count + sv);
      for (int i = 0; i < 4; ++i) {
        const int row = (fu + i) % nu;
        for (int l = 0; l < 4; ++l) {
          const Eigen::Vector3d p = control_.col(static_cast<Eigen::Index>(row) * nv + fv + l);
          for (int j = 0; j < 4; ++j) {
            const double wu = basis_u_.TaylorCoefficient(su, 0, j, i);
            for (int k = 0; k < 4; ++k) {
              const double w = wu * basis_v_.TaylorCoefficient(sv, 0, k, l);
              for (int c = 0; c < 3; ++c) a[16 * j + 4 * k + c] += w * p[c];
            }
          }
        }
      }
    }
  }
}

ParameterDomain BSplineSurface::domain() const {
  ParameterDomain d = DomainOf(basis_u_, 2);
  d.lo[1] = basis_v_.lo();
  d.hi[1] = basis_v_.hi();
  d.periodic[1] = false;
  return d;
}

std::string BSplineSurface::parameter_name(int index) const {
  const int point = index / 3, nv = basis_v_.num_control();
  return "control point (" + std::to_string(point / nv) + ", " + std::to_string(point % nv) + ") " +
         kAxis[index % 3];
}

Eigen::VectorXd BSplineSurface::parameters() const {
  return Eigen::Map<const Eigen::VectorXd>(control_.data(), control_.size());
}

void BSplineSurface::set_parameters(const Eigen::VectorXd& p) {
  control_ = Eigen::Map<const Eigen::Matrix3Xd>(p.data(), 3, control_.cols());
  BuildPatches();
}

void BSplineSurface::ApplySimilarity(double scale, const VecS& offset) {
  control_ = (scale * control_).colwise() + Eigen::Vector3d(offset);
  BuildPatches();
}

namespace {

// sum_j w_j q_j over the nv points q_j of a row (3 doubles each).
template <int KV>
inline void VSum(int nv_runtime, const double* q, const std::array<double, BSplineBasis::kMaxOrder>& w,
                 double (&out)[3]) {
  const int nv = KV > 0 ? KV : nv_runtime;
  double x = 0.0, y = 0.0, z = 0.0;
  for (int j = 0; j < nv; ++j) {
    const double wj = w[static_cast<std::size_t>(j)];
    x += wj * q[3 * j];
    y += wj * q[3 * j + 1];
    z += wj * q[3 * j + 2];
  }
  out[0] = x;
  out[1] = y;
  out[2] = z;
}

// The tensor product S^(a,b)(u, v) = sum_i sum_j N_i^(a)(u) M_j^(b)(v) P_ij (Piegl & Tiller eq. 3.17 and its
// derivatives, eq. 3.24) in two passes. `rows[i]` points at P_i,first_v; a row's KV points are 3 KV
// contiguous doubles (v is never periodic). First the u-sums q_a = sum_i N_i^(a) rows[i], whole rows at a
// time, then the v-sums of q_a's points. KU, KV > 0 fix the orders at compile time; 0 takes ku, kv. r: S,
// S_u, S_v, S_uu, S_uv, S_vv.
template <int KU, int KV, int D>
void TensorProduct(const double* const* rows, int ku, int kv, const BSplineBasis::Values& bu,
                   const BSplineBasis::Values& bv, double (&r)[6][3]) {
  constexpr int kMax = BSplineBasis::kMaxOrder;
  const int nu = KU > 0 ? KU : ku, nv = KV > 0 ? KV : kv;
  constexpr int kLen = 3 * (KV > 0 ? KV : kMax);
  const int len = 3 * nv;
  // One a at a time (its 3 nv accumulators stay in registers; all of them at once would spill).
  double q[D + 1][kLen];
  for (int a = 0; a <= D; ++a) {
    const auto& wa = bu.values[static_cast<std::size_t>(a)];
    double acc[kLen];
    for (int k = 0; k < len; ++k) acc[k] = wa[0] * rows[0][k];
    for (int i = 1; i < nu; ++i) {
      const double w = wa[static_cast<std::size_t>(i)];
      const double* p = rows[i];
      for (int k = 0; k < len; ++k) acc[k] += w * p[k];
    }
    for (int k = 0; k < len; ++k) q[a][k] = acc[k];
  }
  // r's rows (a, b): S (0, 0), S_u (1, 0), S_v (0, 1), S_uu (2, 0), S_uv (1, 1), S_vv (0, 2); written out (a
  // loop over a table of (a, b) kept the compiler from unrolling).
  VSum<KV>(nv, q[0], bv.values[0], r[0]);
  if (D >= 1) {
    VSum<KV>(nv, q[D >= 1 ? 1 : 0], bv.values[0], r[1]);
    VSum<KV>(nv, q[0], bv.values[1], r[2]);
  } else {
    for (int m = 1; m < 3; ++m) r[m][0] = r[m][1] = r[m][2] = 0.0;
  }
  if (D >= 2) {
    VSum<KV>(nv, q[D >= 2 ? 2 : 0], bv.values[0], r[3]);
    VSum<KV>(nv, q[D >= 1 ? 1 : 0], bv.values[1], r[4]);
    VSum<KV>(nv, q[0], bv.values[2], r[5]);
  } else {
    for (int m = 3; m < 6; ++m) r[m][0] = r[m][1] = r[m][2] = 0.0;
  }
}

template <int KU, int KV>
void TensorProduct(int derivatives, const double* const* rows, int ku, int kv, const BSplineBasis::Values& bu,
                   const BSplineBasis::Values& bv, double (&r)[6][3]) {
  if (derivatives >= 2) {
    TensorProduct<KU, KV, 2>(rows, ku, kv, bu, bv, r);
  } else if (derivatives == 1) {
    TensorProduct<KU, KV, 1>(rows, ku, kv, bu, bv, r);
  } else {
    TensorProduct<KU, KV, 0>(rows, ku, kv, bu, bv, r);
  }
}

// A bicubic patch S(y, z) = sum_jk A_jk y^j z^k and its y, z derivatives (up to D in total) by Horner's rule:
// first in z per j (value, d/dz, d2/dz2), then in y. Four lanes per point (the fourth is padding), so the
// compiler vectorizes every step. r: S, S_y, S_z, S_yy, S_yz, S_zz (local coordinates).
template <int D>
void BicubicPatch(const double* a, double y, double z, double (&r)[6][4]) {
  double v[4][4], dz[4][4], dzz[4][4];
  for (int j = 0; j < 4; ++j) {
    const double* aj = a + 16 * j;  // aj[4 k + c]
    for (int c = 0; c < 4; ++c) {
      v[j][c] = ((aj[12 + c] * z + aj[8 + c]) * z + aj[4 + c]) * z + aj[c];
      if (D >= 1) dz[j][c] = (3.0 * aj[12 + c] * z + 2.0 * aj[8 + c]) * z + aj[4 + c];
      if (D >= 2) dzz[j][c] = 6.0 * aj[12 + c] * z + 2.0 * aj[8 + c];
    }
  }
  for (int c = 0; c < 4; ++c) {
    r[0][c] = ((v[3][c] * y + v[2][c]) * y + v[1][c]) * y + v[0][c];
    if (D >= 1) {
      r[1][c] = (3.0 * v[3][c] * y + 2.0 * v[2][c]) * y + v[1][c];
      r[2][c] = ((dz[3][c] * y + dz[2][c]) * y + dz[1][c]) * y + dz[0][c];
    }
    if (D >= 2) {
      r[3][c] = 6.0 * v[3][c] * y + 2.0 * v[2][c];
      r[4][c] = (3.0 * dz[3][c] * y + 2.0 * dz[2][c]) * y + dz[1][c];
      r[5][c] = ((dzz[3][c] * y + dzz[2][c]) * y + dzz[1][c]) * y + dzz[0][c];
    }
  }
}

}  // namespace

void BSplineSurface::Evaluate(const ParamT& t, int derivatives, LocalGeometry& out) const {
  out.point.resize(3);
  out.d1.resize(3, 2);
  out.d2.resize(3, 3);
  if (!patches_.empty()) {
    double yu = 0.0, iu = 0.0, yv = 0.0, iv = 0.0;
    const int su = basis_u_.LocateSpan(t[0], yu, iu), sv = basis_v_.LocateSpan(t[1], yv, iv);
    const double* a = patches_.data() + 64 * (static_cast<std::ptrdiff_t>(su) * basis_v_.num_spans() + sv);
    double r[6][4] = {};
    if (derivatives >= 2) {
      BicubicPatch<2>(a, yu, yv, r);
    } else if (derivatives == 1) {
      BicubicPatch<1>(a, yu, yv, r);
    } else {
      BicubicPatch<0>(a, yu, yv, r);
    }
    // Chain rule: d/du = (1 / length_u) d/dy, d/dv = (1 / length_v) d/dz.
    const double iuu = iu * iu, iuv = iu * iv, ivv = iv * iv;
    for (int c = 0; c < 3; ++c) {
      out.point[c] = r[0][c];
      out.d1(c, 0) = iu * r[1][c];
      out.d1(c, 1) = iv * r[2][c];
      out.d2(c, 0) = iuu * r[3][c];
      out.d2(c, 1) = iuv * r[4][c];
      out.d2(c, 2) = ivv * r[5][c];
    }
    return;
  }
  BSplineBasis::Values bu, bv;
  basis_u_.Evaluate(t[0], derivatives, bu);
  basis_v_.Evaluate(t[1], derivatives, bv);
  const int nu = basis_u_.num_control(), nv = basis_v_.num_control();
  const int ku = basis_u_.order(), kv = basis_v_.order();
  const double* rows[BSplineBasis::kMaxOrder] = {};
  int row = bu.first;  // periodic in u: wraps once at most
  for (int i = 0; i < ku; ++i, ++row) {
    if (row == nu) row = 0;
    rows[i] = control_.data() + 3 * (static_cast<std::ptrdiff_t>(row) * nv + bv.first);
  }
  double r[6][3];
  // Bicubic surfaces took the patch tables above; other orders (rare) at run time. A compile-time order pair
  // would go here as TensorProduct<KU, KV>.
  TensorProduct<0, 0>(derivatives, rows, ku, kv, bu, bv, r);
  for (int c = 0; c < 3; ++c) {
    out.point[c] = r[0][c];
    out.d1(c, 0) = r[1][c];
    out.d1(c, 1) = r[2][c];
    out.d2(c, 0) = r[3][c];
    out.d2(c, 1) = r[4][c];
    out.d2(c, 2) = r[5][c];
  }
}

void BSplineSurface::ShapeJacobian(const ParamT& t, bool with_dt, std::vector<JacobianEntry>& out) const {
  out.clear();
  BSplineBasis::Values bu, bv;
  basis_u_.Evaluate(t[0], with_dt ? 1 : 0, bu);
  basis_v_.Evaluate(t[1], with_dt ? 1 : 0, bv);
  const int nv = basis_v_.num_control();
  for (int i = 0; i < basis_u_.order(); ++i) {
    const auto ui = static_cast<std::size_t>(i);
    for (int j = 0; j < basis_v_.order(); ++j) {
      const auto vj = static_cast<std::size_t>(j);
      const int point = basis_u_.ControlIndex(bu.first, i) * nv + basis_v_.ControlIndex(bv.first, j);
      const double w = bu.values[0][ui] * bv.values[0][vj];
      for (int c = 0; c < 3; ++c) {
        JacobianEntry e;
        e.index = point * 3 + c;
        e.column = w * Eigen::Vector3d::Unit(c);
        if (with_dt) {
          e.dcolumn_dt[0] = bu.values[1][ui] * bv.values[0][vj] * Eigen::Vector3d::Unit(c);
          e.dcolumn_dt[1] = bu.values[0][ui] * bv.values[1][vj] * Eigen::Vector3d::Unit(c);
        } else {
          e.dcolumn_dt[0].setZero();
          e.dcolumn_dt[1].setZero();
        }
        out.push_back(e);
      }
    }
  }
}

bool BSplineSurface::FactoredShapeJacobian(const ParamT& t, FactoredJacobian& out) const {
  if (basis_u_.order() * basis_v_.order() > FactoredJacobian::kMaxWeights) return false;
  BSplineBasis::Values bu, bv;
  basis_u_.Evaluate(t[0], 0, bu);
  basis_v_.Evaluate(t[1], 0, bv);
  const int nv = basis_v_.num_control();
  int k = 0;
  for (int i = 0; i < basis_u_.order(); ++i) {
    for (int j = 0; j < basis_v_.order(); ++j, ++k) {
      const int point = basis_u_.ControlIndex(bu.first, i) * nv + basis_v_.ControlIndex(bv.first, j);
      out.first_index[static_cast<std::size_t>(k)] = 3 * point;
      out.weights[static_cast<std::size_t>(k)] =
          bu.values[0][static_cast<std::size_t>(i)] * bv.values[0][static_cast<std::size_t>(j)];
    }
  }
  out.weight_count = k;
  out.direction_count = 3;
  out.directions = Eigen::Matrix3d::Identity();
  return true;
}

Eigen::MatrixXd BSplineSurface::FairnessMatrix(const FairnessWeights& w) const {
  if (w.IsZero()) return {};
  const Eigen::MatrixXd u0 = Gram(basis_u_, 0), u1 = Gram(basis_u_, 1), v0 = Gram(basis_v_, 0),
                        v1 = Gram(basis_v_, 1);
  const Eigen::MatrixXd u2 =
      basis_u_.order() > 2 ? Gram(basis_u_, 2) : Eigen::MatrixXd::Zero(u0.rows(), u0.cols());
  const Eigen::MatrixXd v2 =
      basis_v_.order() > 2 ? Gram(basis_v_, 2) : Eigen::MatrixXd::Zero(v0.rows(), v0.cols());
  const Eigen::Index nu = u0.rows(), nv = v0.rows();
  const bool third = w.variation != 0.0;
  const Eigen::MatrixXd u3 = third ? SplineEnergyMatrix(basis_u_, 3) : Eigen::MatrixXd::Zero(nu, nu);
  const Eigen::MatrixXd v3 = third ? SplineEnergyMatrix(basis_v_, 3) : Eigen::MatrixXd::Zero(nv, nv);
  const Eigen::MatrixXd ju2 = w.jump2 != 0.0 ? SplineJumpMatrix(basis_u_, 2) : Eigen::MatrixXd::Zero(nu, nu);
  const Eigen::MatrixXd jv2 = w.jump2 != 0.0 ? SplineJumpMatrix(basis_v_, 2) : Eigen::MatrixXd::Zero(nv, nv);
  const Eigen::MatrixXd ju3 = w.jump3 != 0.0 ? SplineJumpMatrix(basis_u_, 3) : Eigen::MatrixXd::Zero(nu, nu);
  const Eigen::MatrixXd jv3 = w.jump3 != 0.0 ? SplineJumpMatrix(basis_v_, 3) : Eigen::MatrixXd::Zero(nv, nv);
  Eigen::MatrixXd k = Eigen::MatrixXd::Zero(nu * nv, nu * nv);
  // Tensor-product Gram matrices: integral S_uu . S_uu = P^T (G2u (x) G0v) P, etc. (thin plate + membrane
  // energies).
  for (Eigen::Index a = 0; a < nu; ++a)
    for (Eigen::Index b = 0; b < nu; ++b)
      for (Eigen::Index c = 0; c < nv; ++c)
        for (Eigen::Index d = 0; d < nv; ++d) {
          double e = 0.0;
          if (w.bending != 0.0)
            e += w.bending * (u2(a, b) * v0(c, d) + 2.0 * u1(a, b) * v1(c, d) + u0(a, b) * v2(c, d));
          if (w.stretch != 0.0) e += w.stretch * (u1(a, b) * v0(c, d) + u0(a, b) * v1(c, d));
          // Fang's third-order energy and the jumps across knot lines (docs/fair-curves.md eqs. F25-F26).
          if (w.variation != 0.0)
            e += w.variation * (u3(a, b) * v0(c, d) + 3.0 * u2(a, b) * v1(c, d) + 3.0 * u1(a, b) * v2(c, d) +
                                u0(a, b) * v3(c, d));
          if (w.jump2 != 0.0) e += w.jump2 * (ju2(a, b) * v0(c, d) + u0(a, b) * jv2(c, d));
          if (w.jump3 != 0.0) e += w.jump3 * (ju3(a, b) * v0(c, d) + u0(a, b) * jv3(c, d));
          k(a * nv + c, b * nv + d) = e;
        }
  return KroneckerIdentity(k, 3);
}

std::vector<ParamT> BSplineSurface::SampleParameters() const {
  std::vector<ParamT> out;
  const std::vector<double> us = SpanSamples(basis_u_, 6), vs = SpanSamples(basis_v_, 6);
  for (double u : us)
    for (double v : vs) out.push_back({u, v});
  return out;
}

// ---- Ellipse3D
// ------------------------------------------------------------------------------------------------------

Ellipse3D::Ellipse3D(const Eigen::Vector3d& center, const Eigen::Matrix3d& rotation, double a, double b,
                     bool circle)
    : center_(center), rotation_(rotation), a_(a), b_(circle ? a : b), circle_(circle) {}

ParameterDomain Ellipse3D::domain() const {
  ParameterDomain d;
  d.dimension = 1;
  d.lo[0] = 0.0;
  d.hi[0] = 2.0 * M_PI;
  d.periodic[0] = true;
  return d;
}

std::string Ellipse3D::parameter_name(int index) const {
  static const char* names[] = {"centre x",   "centre y",   "centre z", "rotation x",
                                "rotation y", "rotation z", "a",        "b"};
  if (circle_ && index == 6) return "radius";
  return names[index];
}

Eigen::VectorXd Ellipse3D::parameters() const {
  Eigen::VectorXd p = Eigen::VectorXd::Zero(num_parameters());
  p.head<3>() = center_;
  p[6] = a_;
  if (!circle_) p[7] = b_;
  return p;
}

void Ellipse3D::set_parameters(const Eigen::VectorXd& p) {
  center_ = p.head<3>();
  const Eigen::Vector3d w = p.segment<3>(3);
  if (w.norm() > 0) rotation_ = rotation_ * Eigen::AngleAxisd(w.norm(), w.normalized()).toRotationMatrix();
  a_ = p[6];
  b_ = circle_ ? a_ : p[7];
}

void Ellipse3D::ApplyStep(const Eigen::VectorXd& step) {
  set_parameters(parameters() + step);
  if (a_ < 0) {  // (x, y, z) -> (-x, y, -z): a rotation, maps a cos t to -a cos t
    a_ = -a_;
    rotation_.col(0) *= -1.0;
    rotation_.col(2) *= -1.0;
  }
  if (!circle_ && b_ < 0) {
    b_ = -b_;
    rotation_.col(1) *= -1.0;
    rotation_.col(2) *= -1.0;
  }
}

void Ellipse3D::ApplySimilarity(double scale, const VecS& offset) {
  center_ = scale * center_ + Eigen::Vector3d(offset);
  a_ *= scale;
  b_ *= scale;
}

void Ellipse3D::Evaluate(const ParamT& t, int derivatives, LocalGeometry& out) const {
  const double c = std::cos(t[0]), s = std::sin(t[0]), b = circle_ ? a_ : b_;
  out.point = center_ + rotation_ * Eigen::Vector3d(a_ * c, b * s, 0.0);
  out.d1.resize(3, 1);
  out.d2.resize(3, 1);
  out.d1.col(0) = derivatives >= 1 ? Eigen::Vector3d(rotation_ * Eigen::Vector3d(-a_ * s, b * c, 0.0))
                                   : Eigen::Vector3d::Zero();
  out.d2.col(0) = derivatives >= 2 ? Eigen::Vector3d(rotation_ * Eigen::Vector3d(-a_ * c, -b * s, 0.0))
                                   : Eigen::Vector3d::Zero();
}

void Ellipse3D::ShapeJacobian(const ParamT& t, bool with_dt, std::vector<JacobianEntry>& out) const {
  out.clear();
  const double c = std::cos(t[0]), s = std::sin(t[0]), b = circle_ ? a_ : b_;
  const Eigen::Vector3d p(a_ * c, b * s, 0.0), dp(-a_ * s, b * c, 0.0);
  auto add = [&](int index, const Eigen::Vector3d& column, const Eigen::Vector3d& dcolumn) {
    JacobianEntry e;
    e.index = index;
    e.column = column;
    e.dcolumn_dt[0] = with_dt ? dcolumn : Eigen::Vector3d::Zero();
    e.dcolumn_dt[1].setZero();
    out.push_back(e);
  };
  for (int k = 0; k < 3; ++k) add(k, Eigen::Vector3d::Unit(k), Eigen::Vector3d::Zero());
  // d/dw_k of R exp([w]x) p at w = 0 is R (e_k x p).
  for (int k = 0; k < 3; ++k) {
    add(3 + k, rotation_ * Eigen::Vector3d::Unit(k).cross(p), rotation_ * Eigen::Vector3d::Unit(k).cross(dp));
  }
  if (circle_) {
    add(6, rotation_ * Eigen::Vector3d(c, s, 0.0), rotation_ * Eigen::Vector3d(-s, c, 0.0));
  } else {
    add(6, rotation_ * Eigen::Vector3d(c, 0.0, 0.0), rotation_ * Eigen::Vector3d(-s, 0.0, 0.0));
    add(7, rotation_ * Eigen::Vector3d(0.0, s, 0.0), rotation_ * Eigen::Vector3d(0.0, c, 0.0));
  }
}

std::vector<ParamT> Ellipse3D::SampleParameters() const {
  std::vector<ParamT> out;
  for (int i = 0; i < 256; ++i) out.push_back({2.0 * M_PI * i / 256, 0.0});
  return out;
}

bool Ellipse3D::ClosedFormFootPoint(const VecS& x, ParamT& t) const {
  double distance;
  bool on_boundary, ambiguous;
  return ClosedFormFoot(x, t, distance, on_boundary, ambiguous);
}

bool Ellipse3D::ClosedFormFoot(const VecS& x, ParamT& t, double& distance, bool& on_boundary,
                               bool& ambiguous) const {
  if (!circle_) return false;
  const Eigen::Vector3d q = rotation_.transpose() * (Eigen::Vector3d(x) - center_);
  const double rho = std::sqrt(q.x() * q.x() + q.y() * q.y());
  t = {std::atan2(q.y(), q.x()), 0.0, 0.0};
  t[0] += 2 * M_PI * static_cast<double>(t[0] < 0);  // into [0, 2 pi)
  distance = std::hypot(q.z(), rho - a_);
  on_boundary = false;  // closed curve
  ambiguous = rho == 0;
  return true;
}

}  // namespace s2m
