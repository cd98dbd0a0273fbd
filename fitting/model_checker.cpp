#include "fitting/model_checker.h"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <functional>
#include <limits>
#include <random>
#include <sstream>
#include <stdexcept>

#include "fitting/foot_point.h"

namespace s2m {
namespace {

constexpr double kInfinity = std::numeric_limits<double>::infinity();
// A derivative smaller than this fraction of the model's size (per unit scale of the parameters
// differentiated in) counts as zero: the relative errors' floor.
constexpr double kFloorFraction = 1e-3;

std::string FormatT(const ParamT& t, int m) {
  std::ostringstream s;
  s.precision(6);
  s << "t=(" << t[0];
  if (m == 2) s << ", " << t[1];
  if (t[2] != 0.0) s << ", face " << t[2];
  s << ")";
  return s.str();
}

// Records one error of a check; `where` is formatted only when the error is the worst so far. NaN counts as
// infinite (a failure).
void Record(ModelCheck& check, double error, const std::function<std::string()>& where) {
  if (std::isnan(error)) error = kInfinity;
  ++check.evaluations;
  if (check.evaluations == 1 || error > check.worst_error) {
    check.worst_error = error;
    check.worst_at = where();
  }
}

ModelCheck MakeCheck(const char* name, double tolerance) {
  ModelCheck c;
  c.name = name;
  c.tolerance = tolerance;
  return c;
}

Eigen::Vector3d PointAt(const ParametricModel& model, const ParamT& t) {
  LocalGeometry g;
  model.Evaluate(t, 0, g);
  return To3(g.point);
}

// The scale of parameter k at t: the domain's width when it is finite and moderate, else 1 + |t_k| (the
// cylinder's axial range and the parts' planes are unbounded).
double ParameterScale(const ParameterDomain& d, int k, const ParamT& t) {
  const auto i = static_cast<std::size_t>(k);
  const double width = d.hi[i] - d.lo[i];
  if (std::isfinite(width) && width > 0 && width <= 100.0) return width;
  return 1.0 + std::abs(t[i]);
}

struct Sample {
  ParamT t{0.0, 0.0, 0.0};
  std::array<double, 2> scale{1.0, 1.0};
};

// `count` of the model's own sample parameters (strided, so that every face and span is visited), each moved
// off by a random fraction of its scale and kept far enough inside open ends for the difference stencils.
std::vector<Sample> ChooseSamples(const ParametricModel& model, const ModelCheckOptions& o,
                                  std::mt19937& rng) {
  const ParameterDomain d = model.domain();
  const std::vector<ParamT> all = model.SampleParameters();
  std::vector<Sample> out;
  if (all.empty()) return out;
  const std::size_t count = std::min(all.size(), static_cast<std::size_t>(o.sample_count));
  std::uniform_real_distribution<double> magnitude(0.5, 1.0);
  std::bernoulli_distribution sign(0.5);
  const double reach = 2.0 * std::max(o.second_derivative_step, o.derivative_step);
  for (std::size_t i = 0; i < count; ++i) {
    Sample s;
    s.t = all[i * all.size() / count];
    for (int k = 0; k < d.dimension; ++k) {
      const auto ku = static_cast<std::size_t>(k);
      const double scale = ParameterScale(d, k, s.t);
      s.t[ku] += (sign(rng) ? 1.0 : -1.0) * magnitude(rng) * o.sample_jitter * scale;
      if (!d.periodic[ku]) {
        const double margin = reach * ParameterScale(d, k, s.t);
        s.t[ku] = std::clamp(s.t[ku], d.lo[ku] + margin, d.hi[ku] - margin);
      } else {
        const double width = d.hi[ku] - d.lo[ku];
        s.t[ku] = d.lo[ku] + std::fmod(std::fmod(s.t[ku] - d.lo[ku], width) + width, width);
      }
      s.scale[ku] = ParameterScale(d, k, s.t);
    }
    out.push_back(s);
  }
  return out;
}

double ModelSize(const ParametricModel& model) {
  Eigen::Vector3d lo = Eigen::Vector3d::Constant(kInfinity), hi = -lo;
  for (const ParamT& t : model.SampleParameters()) {
    const Eigen::Vector3d p = PointAt(model, t);
    if (!p.allFinite()) continue;
    lo = lo.cwiseMin(p);
    hi = hi.cwiseMax(p);
  }
  const double size = (hi - lo).norm();
  return std::isfinite(size) && size > 0 ? size : 1.0;
}

// dC/dP at t as a dense 3 x r matrix (entries of the same index summed). False when an entry's index is out
// of range.
bool DenseJacobian(const ParametricModel& model, const ParamT& t, bool with_dt, Eigen::Matrix3Xd& columns,
                   std::array<Eigen::Matrix3Xd, 2>* dt = nullptr) {
  std::vector<JacobianEntry> entries;
  model.ShapeJacobian(t, with_dt, entries);
  const int r = model.num_parameters();
  columns.setZero(3, r);
  if (dt) (*dt)[0].setZero(3, r), (*dt)[1].setZero(3, r);
  for (const JacobianEntry& e : entries) {
    if (e.index < 0 || e.index >= r) return false;
    columns.col(e.index) += e.column;
    if (dt) {
      (*dt)[0].col(e.index) += e.dcolumn_dt[0];
      (*dt)[1].col(e.index) += e.dcolumn_dt[1];
    }
  }
  return true;
}

// An orthonormal basis of the normal space at a model point (columns; s - m of them), from the tangents d1.
Eigen::Matrix3Xd NormalSpace(const LocalGeometry& g) {
  const int s = static_cast<int>(g.point.size()), m = static_cast<int>(g.d1.cols());
  Eigen::Matrix3Xd tangents = Eigen::Matrix3Xd::Zero(3, m);
  for (int k = 0; k < m; ++k) tangents.col(k) = To3(g.d1.col(k));
  Eigen::HouseholderQR<Eigen::MatrixXd> qr(Eigen::MatrixXd(tangents.topRows(s)));
  const Eigen::MatrixXd q = qr.householderQ();
  Eigen::Matrix3Xd normals = Eigen::Matrix3Xd::Zero(3, s - m);
  normals.topRows(s) = q.rightCols(s - m);
  return normals;
}

class Checker {
 public:
  Checker(const ParametricModel& model, const ModelCheckOptions& options)
      : model_(model), o_(options), rng_(options.seed) {}

  ModelCheckReport Run();

 private:
  // Per-sample checks at one state of the shape (`label` names it in the report).
  void CheckDerivatives(const ParametricModel& m, const std::vector<Sample>& samples,
                        const std::string& label);
  void CheckJacobian(const ParametricModel& m, const std::vector<Sample>& samples, const std::string& label);
  void CheckFactored(const ParametricModel& m, const std::vector<Sample>& samples, const std::string& label);
  void CheckPrincipalFrame(const ParametricModel& m, const std::vector<Sample>& samples,
                           const std::string& label);
  double PrincipalFrameError(const ParametricModel& m, const Sample& s, const LocalGeometry& g);
  void CheckInvariantMotions(const ParametricModel& m, const std::vector<Sample>& samples,
                             const std::string& label);
  void CheckCommonMotions(const ParametricModel& m, const std::string& label);
  void CheckSimilarity(const ParametricModel& m, const std::vector<Sample>& samples,
                       const std::string& label);
  void CheckCloneCopy(const ParametricModel& m, const std::vector<Sample>& samples, const std::string& label);
  void CheckRoundTrip(const ParametricModel& m, const std::vector<Sample>& samples, const std::string& label);
  void CheckApplyStep(const ParametricModel& m, const std::vector<Sample>& samples, const std::string& label);
  void CheckFeet(const ParametricModel& m, const std::vector<Sample>& samples, const std::string& label);

  // Second derivative d2C / dt_a dt_b by the second difference with step h, and its Richardson extrapolation
  // from h and h / 2 (the truncation error's leading term is h^2 C''''/12 for both).
  Eigen::Vector3d SecondDifference(const ParametricModel& m, const Sample& s, int a, int b, double h) const;
  Eigen::Vector3d FirstDifference(const ParametricModel& m, const Sample& s, int k) const;
  Eigen::Vector3d SecondDerivativeNumeric(const ParametricModel& m, const Sample& s, int a, int b) const {
    const double h = step_factor_ * o_.second_derivative_step;
    return (4.0 * SecondDifference(m, s, a, b, 0.5 * h) - SecondDifference(m, s, a, b, h)) / 3.0;
  }
  double ParameterStepScale(double p) const { return std::max(1.0, std::abs(p)); }
  // The smaller of `error()` with the difference steps in t as given and a quarter of them: truncation and
  // a stencil that straddles a knot (where a B-spline's higher derivatives jump) shrink with the step, a
  // wrong derivative does not (the idea of Ridders' extrapolation, Numerical Recipes section 5.7, reduced
  // to two steps).
  template <class Error>
  double MinOverSteps(Error error) {
    step_factor_ = 1.0;
    const double coarse = error();
    step_factor_ = 0.25;
    const double fine = error();
    step_factor_ = 1.0;
    return std::isnan(coarse) ? fine : (std::isnan(fine) ? coarse : std::min(coarse, fine));
  }

  ModelCheck& Get(const char* name);
  // Records, at every sample, how far `other` puts C(t) from where m has it (relative to the model's size):
  // `what` says what should have left the points in place.
  void RecordSamePoints(ModelCheck& check, const ParametricModel& m, const ParametricModel& other,
                        const std::vector<Sample>& samples, const std::string& label,
                        const std::string& what);

  const ParametricModel& model_;
  ModelCheckOptions o_;
  std::mt19937 rng_;
  double size_ = 1.0;
  double step_factor_ = 1.0;  // scales the difference steps in t (MinOverSteps)
  int m_ = 1, s_ = 3;
  std::vector<ModelCheck> checks_;
};

ModelCheck& Checker::Get(const char* name) {
  for (ModelCheck& c : checks_)
    if (c.name == name) return c;
  throw std::logic_error(std::string("no check named ") + name);
}

void Checker::RecordSamePoints(ModelCheck& check, const ParametricModel& m, const ParametricModel& other,
                               const std::vector<Sample>& samples, const std::string& label,
                               const std::string& what) {
  for (const Sample& s : samples) {
    Record(check, (PointAt(other, s.t) - PointAt(m, s.t)).norm() / size_,
           [&] { return label + ", " + FormatT(s.t, m_) + ": " + what; });
  }
}

Eigen::Vector3d Checker::FirstDifference(const ParametricModel& m, const Sample& s, int k) const {
  const auto ku = static_cast<std::size_t>(k);
  const double h = step_factor_ * o_.derivative_step * s.scale[ku];
  ParamT tp = s.t, tm = s.t;
  tp[ku] += h;
  tm[ku] -= h;
  return (PointAt(m, tp) - PointAt(m, tm)) / (2.0 * h);
}

Eigen::Vector3d Checker::SecondDifference(const ParametricModel& m, const Sample& s, int a, int b,
                                          double step) const {
  const auto au = static_cast<std::size_t>(a), bu = static_cast<std::size_t>(b);
  const double ha = step * s.scale[au], hb = step * s.scale[bu];
  if (a == b) {
    ParamT tp = s.t, tm = s.t;
    tp[au] += ha;
    tm[au] -= ha;
    return (PointAt(m, tp) - 2.0 * PointAt(m, s.t) + PointAt(m, tm)) / (ha * ha);
  }
  auto at = [&](double da, double db) {
    ParamT t = s.t;
    t[au] += da;
    t[bu] += db;
    return PointAt(m, t);
  };
  return (at(ha, hb) - at(ha, -hb) - at(-ha, hb) + at(-ha, -hb)) / (4.0 * ha * hb);
}

void Checker::CheckDerivatives(const ParametricModel& m, const std::vector<Sample>& samples,
                               const std::string& label) {
  ModelCheck& first = Get(kCheckFirstDerivatives);
  ModelCheck& second = Get(kCheckSecondDerivatives);
  LocalGeometry g;
  for (const Sample& s : samples) {
    m.Evaluate(s.t, 2, g);
    const Eigen::Vector3d point = To3(g.point);
    Record(first, (point - PointAt(m, s.t)).norm() / size_,
           [&] { return label + ", " + FormatT(s.t, m_) + ": Evaluate(t, 2) and Evaluate(t, 0) differ"; });
    for (int k = 0; k < m_; ++k) {
      const Eigen::Vector3d analytic = To3(g.d1.col(k));
      const double floor = kFloorFraction * size_ / s.scale[static_cast<std::size_t>(k)];
      Record(first, MinOverSteps([&] {
               return (analytic - FirstDifference(m, s, k)).norm() / (analytic.norm() + floor);
             }),
             [&] { return label + ", " + FormatT(s.t, m_) + ", d/dt" + std::to_string(k); });
    }
    // Columns of d2: curves C''; surfaces C_uu, C_uv, C_vv.
    const int columns = m_ == 1 ? 1 : 3;
    for (int c = 0; c < columns; ++c) {
      const int a = m_ == 1 ? 0 : (c == 2 ? 1 : 0), b = m_ == 1 ? 0 : (c == 0 ? 0 : 1);
      const Eigen::Vector3d analytic = To3(g.d2.col(c));
      const double floor = kFloorFraction * size_ /
                           (s.scale[static_cast<std::size_t>(a)] * s.scale[static_cast<std::size_t>(b)]);
      const double error = MinOverSteps([&] {
        return (analytic - SecondDerivativeNumeric(m, s, a, b)).norm() / (analytic.norm() + floor);
      });
      Record(second, error, [&] {
        return label + ", " + FormatT(s.t, m_) + ", d2/dt" + std::to_string(a) + "dt" + std::to_string(b);
      });
    }
  }
}

void Checker::CheckJacobian(const ParametricModel& m, const std::vector<Sample>& samples,
                            const std::string& label) {
  ModelCheck& jac = Get(kCheckShapeJacobian);
  ModelCheck& jac_dt = Get(kCheckShapeJacobianDt);
  const int r = m.num_parameters();
  const Eigen::VectorXd p0 = m.parameters();
  // Central differences in each parameter, at every sample: 2 r shapes.
  std::vector<Eigen::Matrix3Xd> numeric(samples.size(), Eigen::Matrix3Xd::Zero(3, r));
  for (int i = 0; i < r; ++i) {
    // A fresh clone per difference: rotation parameters are increments set_parameters applies to the frame
    // (they do not accumulate only on a model as given).
    const double h = o_.parameter_step * ParameterStepScale(p0[i]);
    Eigen::VectorXd p = p0;
    p[i] = p0[i] + h;
    std::unique_ptr<ParametricModel> trial = m.Clone();
    trial->set_parameters(p);
    for (std::size_t j = 0; j < samples.size(); ++j) numeric[j].col(i) = PointAt(*trial, samples[j].t);
    p[i] = p0[i] - h;
    trial = m.Clone();
    trial->set_parameters(p);
    for (std::size_t j = 0; j < samples.size(); ++j)
      numeric[j].col(i) = (numeric[j].col(i) - PointAt(*trial, samples[j].t)) / (2.0 * h);
  }
  Eigen::Matrix3Xd analytic, analytic_plain, plus, minus;
  std::array<Eigen::Matrix3Xd, 2> dt;
  for (std::size_t j = 0; j < samples.size(); ++j) {
    const Sample& s = samples[j];
    const bool ok =
        DenseJacobian(m, s.t, true, analytic, &dt) && DenseJacobian(m, s.t, false, analytic_plain);
    if (!ok) {
      Record(jac, kInfinity,
             [&] { return label + ", " + FormatT(s.t, m_) + ": a column index out of range"; });
      continue;
    }
    for (int i = 0; i < r; ++i) {
      const double floor = kFloorFraction * size_ / ParameterStepScale(p0[i]);
      const Eigen::Vector3d a = analytic.col(i);
      Record(jac, (a - numeric[j].col(i)).norm() / (a.norm() + floor), [&] {
        return label + ", " + FormatT(s.t, m_) + ", column " + std::to_string(i) + " (" +
               m.parameter_name(i) + ")";
      });
      // The columns must not depend on whether their t-derivatives were asked for.
      Record(jac, (a - analytic_plain.col(i)).norm() / (a.norm() + floor), [&] {
        return label + ", " + FormatT(s.t, m_) + ", column " + std::to_string(i) + ": with_dt changes it";
      });
    }
    for (int k = 0; k < m_; ++k) {
      const auto ku = static_cast<std::size_t>(k);
      // Central differences of the columns with the step as given and a quarter of it (MinOverSteps).
      std::array<Eigen::Matrix3Xd, 2> numeric_dt;
      for (int ladder = 0; ladder < 2; ++ladder) {
        const double h = (ladder == 0 ? 1.0 : 0.25) * o_.derivative_step * s.scale[ku];
        ParamT tp = s.t, tm = s.t;
        tp[ku] += h;
        tm[ku] -= h;
        DenseJacobian(m, tp, false, plus);
        DenseJacobian(m, tm, false, minus);
        numeric_dt[static_cast<std::size_t>(ladder)] = (plus - minus) / (2.0 * h);
      }
      for (int i = 0; i < r; ++i) {
        const double floor = kFloorFraction * size_ / (ParameterStepScale(p0[i]) * s.scale[ku]);
        const Eigen::Vector3d a = dt[ku].col(i);
        const double error = std::min((a - numeric_dt[0].col(i)).norm(), (a - numeric_dt[1].col(i)).norm());
        Record(jac_dt, error / (a.norm() + floor), [&] {
          return label + ", " + FormatT(s.t, m_) + ", column " + std::to_string(i) + " (" +
                 m.parameter_name(i) + "), d/dt" + std::to_string(k);
        });
      }
    }
  }
}

void Checker::CheckFactored(const ParametricModel& m, const std::vector<Sample>& samples,
                            const std::string& label) {
  ModelCheck& check = Get(kCheckFactoredJacobian);
  const int r = m.num_parameters();
  int factored = 0;
  Eigen::Matrix3Xd analytic;
  FactoredJacobian f;
  for (const Sample& s : samples) {
    if (!m.FactoredShapeJacobian(s.t, f)) continue;
    ++factored;
    check.applicable = true;
    DenseJacobian(m, s.t, false, analytic);
    Eigen::Matrix3Xd from_factors = Eigen::Matrix3Xd::Zero(3, r);
    bool in_range = f.weight_count >= 0 && f.weight_count <= FactoredJacobian::kMaxWeights &&
                    f.direction_count >= 0 && f.direction_count <= 3;
    for (int i = 0; in_range && i < f.weight_count; ++i) {
      const auto iu = static_cast<std::size_t>(i);
      for (int c = 0; c < f.direction_count; ++c) {
        const int index = f.first_index[iu] + c;
        if (index < 0 || index >= r) {
          in_range = false;
          break;
        }
        from_factors.col(index) += f.weights[iu] * f.directions.col(c);
      }
    }
    if (!in_range) {
      Record(check, kInfinity, [&] { return label + ", " + FormatT(s.t, m_) + ": an index out of range"; });
      continue;
    }
    for (int i = 0; i < r; ++i) {
      const double floor = kFloorFraction * size_ / ParameterStepScale(m.parameters()[i]);
      Record(check, (analytic.col(i) - from_factors.col(i)).norm() / (analytic.col(i).norm() + floor), [&] {
        return label + ", " + FormatT(s.t, m_) + ", column " + std::to_string(i) + " (" +
               m.parameter_name(i) + ")";
      });
    }
  }
  // FactoredShapeJacobian factors at every t or at none (parametric_model.h).
  if (factored > 0 && factored < static_cast<int>(samples.size())) {
    Record(check, kInfinity, [&] {
      return label + ": factored at " + std::to_string(factored) + " of " + std::to_string(samples.size()) +
             " samples";
    });
  }
}

// The largest error of the principal frame at one sample against the finite-difference curve or surface;
// -1 where the parametrization is singular (no frame to compare).
double Checker::PrincipalFrameError(const ParametricModel& m, const Sample& s, const LocalGeometry& g) {
  const double curvature_floor = 1.0 / size_;
  const double offset = 1e-2 * size_;
  if (m_ == 1) {
    // The finite-difference curve's Frenet quantities (do Carmo, Differential Geometry of Curves and
    // Surfaces, section 1-5): T = C'/|C'|, curvature vector k = (C'' - (C''.T) T) / |C'|^2.
    const Eigen::Vector3d c1 = FirstDifference(m, s, 0), c2 = SecondDerivativeNumeric(m, s, 0, 0);
    const double speed = c1.norm();
    if (!(speed > kFloorFraction * size_ / s.scale[0])) return -1.0;  // a singular point: no frame
    const Eigen::Vector3d tangent = c1 / speed;
    const Eigen::Vector3d k = (c2 - c2.dot(tangent) * tangent) / (speed * speed);
    Eigen::Vector3d normal;
    if (s_ == 2) {
      normal = Eigen::Vector3d(-tangent.y(), tangent.x(), 0.0);
    } else if (k.norm() > 1e-6 * curvature_floor) {
      normal = k.normalized();
    } else {
      normal = tangent.unitOrthogonal();
    }
    VecS data = g.point;
    data += (offset * normal).head(s_);
    const PrincipalFrame f = ComputePrincipalFrame(g, data);
    double error = std::min((f.tangents[0] - tangent).norm(), (f.tangents[0] + tangent).norm());
    error = std::max(error, (f.normals[0] - normal).norm());
    error = std::max(error,
                     std::abs(f.curvatures[0] - k.dot(normal)) / (std::abs(k.dot(normal)) + curvature_floor));
    error = std::max(error, std::abs(f.delta - offset) / size_);
    if (s_ == 3) error = std::max(error, (f.normals[1] - f.tangents[0].cross(f.normals[0])).norm());
    return error;
  }
  // Surfaces: the first and second fundamental forms I = [E F; F G], II = n . [S_uu S_uv; S_uv S_vv] of the
  // finite-difference surface (do Carmo, sections 2-5 and 3-3); principal curvatures the eigenvalues of
  // I^-1 II, here by Eigen's generalized symmetric solver (independent of SolvePrincipalCurvatures).
  const Eigen::Vector3d su = FirstDifference(m, s, 0), sv = FirstDifference(m, s, 1);
  const Eigen::Vector3d suu = SecondDerivativeNumeric(m, s, 0, 0), suv = SecondDerivativeNumeric(m, s, 0, 1),
                        svv = SecondDerivativeNumeric(m, s, 1, 1);
  const Eigen::Vector3d cross = su.cross(sv);
  if (!(cross.norm() > 1e-6 * su.norm() * sv.norm())) return -1.0;  // a singular point: no frame
  const Eigen::Vector3d normal = cross.normalized();
  Eigen::Matrix2d first, second;
  first << su.dot(su), su.dot(sv), su.dot(sv), sv.dot(sv);
  second << normal.dot(suu), normal.dot(suv), normal.dot(suv), normal.dot(svv);
  Eigen::GeneralizedSelfAdjointEigenSolver<Eigen::Matrix2d> solver(second, first);
  if (solver.info() != Eigen::Success) return -1.0;
  const Eigen::Vector2d kappa = solver.eigenvalues();  // ascending
  const VecS data = g.point + (offset * normal).head(s_);
  const PrincipalFrame f = ComputePrincipalFrame(g, data);
  double error = (f.normals[0] - normal).norm();
  error = std::max(error, std::abs(f.delta - offset) / size_);
  Eigen::Matrix<double, 3, 2> basis;
  basis << su, sv;
  for (int c = 0; c < 2; ++c) {
    const auto cu = static_cast<std::size_t>(c);
    error = std::max(error, std::abs(f.curvatures[cu] - kappa[c]) / (std::abs(kappa[c]) + curvature_floor));
    // Each tangent is a unit vector of the tangent plane along which the normal curvature II(a, a) / I(a,
    // a) is its curvature (Euler's theorem; well defined also at umbilics).
    const Eigen::Vector3d tangent = f.tangents[cu];
    error = std::max(error, std::abs(tangent.norm() - 1.0));
    error = std::max(error, std::abs(tangent.dot(normal)));
    const Eigen::Vector2d a = basis.colPivHouseholderQr().solve(tangent);
    const double normal_curvature = a.dot(second * a) / a.dot(first * a);
    error = std::max(error, std::abs(f.curvatures[cu] - normal_curvature) /
                                (std::abs(normal_curvature) + curvature_floor));
  }
  error = std::max(error, std::abs(f.tangents[0].dot(f.tangents[1])));
  return error;
}

void Checker::CheckPrincipalFrame(const ParametricModel& m, const std::vector<Sample>& samples,
                                  const std::string& label) {
  ModelCheck& check = Get(kCheckPrincipalFrame);
  check.applicable = true;
  LocalGeometry g;
  for (const Sample& s : samples) {
    m.Evaluate(s.t, 2, g);
    const double error = MinOverSteps([&] { return PrincipalFrameError(m, s, g); });
    if (error >= 0) Record(check, error, [&] { return label + ", " + FormatT(s.t, m_); });
  }
}

void Checker::CheckInvariantMotions(const ParametricModel& m, const std::vector<Sample>& samples,
                                    const std::string& label) {
  const std::vector<Motion6> motions = m.InvariantMotions();
  if (motions.empty()) return;
  ModelCheck& check = Get(kCheckInvariantMotions);
  check.applicable = true;
  LocalGeometry g;
  for (const Sample& s : samples) {
    m.Evaluate(s.t, 1, g);
    const Eigen::Matrix3Xd normals = NormalSpace(g);
    const Eigen::Vector3d point = To3(g.point);
    for (std::size_t k = 0; k < motions.size(); ++k) {
      // The velocity of the model point under the motion, x' = x + cbar + c x x (docs/method.md section 5):
      // the model maps onto itself to first order iff it is tangent, i.e. the distance of any point near the
      // model does not change to first order.
      const Eigen::Vector3d c = motions[k].head<3>(), cbar = motions[k].tail<3>();
      const Eigen::Vector3d velocity = cbar + c.cross(point);
      const double scale = c.norm() * size_ + cbar.norm();
      Record(check, (normals.transpose() * velocity).norm() / scale,
             [&] { return label + ", " + FormatT(s.t, m_) + ", motion " + std::to_string(k); });
    }
  }
}

void Checker::CheckCommonMotions(const ParametricModel& m, const std::string& label) {
  const std::vector<Motion6> motions = m.CommonMotionsAbsorbedByShape();
  if (motions.empty()) return;
  ModelCheck& check = Get(kCheckCommonMotions);
  check.applicable = true;
  // Over all of the model's samples (far more rows than shape parameters): the normal components of the
  // motion's displacement of the model points must be those of a change of shape, n^T J dP = n^T v.
  const std::vector<ParamT> ts = m.SampleParameters();
  const int r = m.num_parameters(), codim = s_ - m_;
  Eigen::MatrixXd a(static_cast<Eigen::Index>(ts.size()) * codim, r);
  Eigen::MatrixXd b(a.rows(), static_cast<Eigen::Index>(motions.size()));
  Eigen::VectorXd velocity_norms = Eigen::VectorXd::Zero(b.cols());
  LocalGeometry g;
  Eigen::Matrix3Xd columns;
  for (std::size_t j = 0; j < ts.size(); ++j) {
    m.Evaluate(ts[j], 1, g);
    const Eigen::Matrix3Xd normals = NormalSpace(g);
    DenseJacobian(m, ts[j], false, columns);
    const Eigen::Index row = static_cast<Eigen::Index>(j) * codim;
    a.middleRows(row, codim) = normals.transpose() * columns;
    for (std::size_t k = 0; k < motions.size(); ++k) {
      const Eigen::Vector3d velocity = motions[k].tail<3>() + motions[k].head<3>().cross(To3(g.point));
      b.block(row, static_cast<Eigen::Index>(k), codim, 1) = normals.transpose() * velocity;
      velocity_norms[static_cast<Eigen::Index>(k)] += velocity.squaredNorm();
    }
  }
  const Eigen::CompleteOrthogonalDecomposition<Eigen::MatrixXd> solver(a);
  const Eigen::MatrixXd residual = a * solver.solve(b) - b;
  for (Eigen::Index k = 0; k < b.cols(); ++k) {
    Record(check, residual.col(k).norm() / std::sqrt(velocity_norms[k]),
           [&] { return label + ", motion " + std::to_string(k); });
  }
}

void Checker::CheckSimilarity(const ParametricModel& m, const std::vector<Sample>& samples,
                              const std::string& label) {
  ModelCheck& check = Get(kCheckSimilarity);
  check.applicable = true;
  const double scale = 1.7;
  VecS offset = VecS::Zero(s_);
  if (m.SupportsTranslation()) {
    const Eigen::Vector3d shift(0.3, -0.2, 0.5);
    offset = (size_ * shift).head(s_);
  }
  std::unique_ptr<ParametricModel> moved = m.Clone();
  moved->ApplySimilarity(scale, offset);
  // Every point of the model, mapped, lies on the mapped model (the same point set: parts keep the plane
  // coordinates of their faces unscaled, so the same t need not give the mapped point).
  const FootPointContext context(*moved);
  LocalGeometry g;
  for (const Sample& s : samples) {
    const VecS mapped = scale * (PointAt(m, s.t).head(s_)) + offset;
    const FootPoint foot = FootPointOf(context, mapped, &s.t, WarmStart::kVerified, g);
    Record(check, foot.distance / (scale * size_),
           [&] { return label + ", " + FormatT(s.t, m_) + ": the mapped point is off the mapped model"; });
  }
  // The inverse map restores the parameters and the points at the same t.
  moved->ApplySimilarity(1.0 / scale, -offset / scale);
  const Eigen::VectorXd p = m.parameters(), back = moved->parameters();
  if (back.size() != p.size()) {
    Record(check, kInfinity, [&] { return label + ": the number of parameters changed"; });
    return;
  }
  for (Eigen::Index i = 0; i < p.size(); ++i) {
    Record(check, std::abs(back[i] - p[i]) / (std::abs(p[i]) + size_), [&] {
      return label + ": parameter " + std::to_string(i) + " (" + m.parameter_name(static_cast<int>(i)) +
             ") after the map and its inverse";
    });
  }
  RecordSamePoints(check, m, *moved, samples, label, "moved by the map and its inverse");
}

void Checker::CheckCloneCopy(const ParametricModel& m, const std::vector<Sample>& samples,
                             const std::string& label) {
  ModelCheck& check = Get(kCheckCloneCopy);
  check.applicable = true;
  std::unique_ptr<ParametricModel> clone = m.Clone();
  auto compare = [&](const ParametricModel& a, const std::string& what) {
    if (a.name() != m.name() || a.num_parameters() != m.num_parameters() ||
        a.ambient_dimension() != m.ambient_dimension() || a.parameters() != m.parameters()) {
      Record(check, kInfinity, [&] { return label + ": " + what + " differs in name or parameters"; });
    }
    RecordSamePoints(check, m, a, samples, label, what);
  };
  compare(*clone, "the clone");
  // A changed clone leaves the original alone, and CopyFrom restores the original's state.
  std::vector<Eigen::Vector3d> before;
  for (const Sample& s : samples) before.push_back(PointAt(m, s.t));
  Eigen::VectorXd changed = m.parameters();
  for (Eigen::Index i = 0; i < changed.size(); ++i) changed[i] += 0.01 * ParameterStepScale(changed[i]);
  clone->set_parameters(changed);
  for (std::size_t j = 0; j < samples.size(); ++j) {
    Record(check, (PointAt(m, samples[j].t) - before[j]).norm() / size_, [&] {
      return label + ", " + FormatT(samples[j].t, m_) + ": changing the clone changed the original";
    });
  }
  clone->CopyFrom(m);
  compare(*clone, "CopyFrom the original");
}

void Checker::CheckRoundTrip(const ParametricModel& m, const std::vector<Sample>& samples,
                             const std::string& label) {
  ModelCheck& check = Get(kCheckParameterRoundTrip);
  check.applicable = true;
  const Eigen::VectorXd p = m.parameters();
  if (p.size() != m.num_parameters()) {
    Record(check, kInfinity, [&] { return label + ": parameters().size() != num_parameters()"; });
    return;
  }
  for (int i = 0; i < m.num_parameters(); ++i) {
    if (m.parameter_name(i).empty())
      Record(check, kInfinity, [&] { return label + ": parameter " + std::to_string(i) + " has no name"; });
  }
  std::unique_ptr<ParametricModel> copy = m.Clone();
  copy->set_parameters(p);
  for (Eigen::Index i = 0; i < p.size(); ++i) {
    Record(check, std::abs(copy->parameters()[i] - p[i]) / (std::abs(p[i]) + 1.0), [&] {
      return label + ": parameter " + std::to_string(i) + " after set_parameters(parameters())";
    });
  }
  RecordSamePoints(check, m, *copy, samples, label, "moved by set_parameters(parameters())");
}

void Checker::CheckApplyStep(const ParametricModel& m, const std::vector<Sample>& samples,
                             const std::string& label) {
  ModelCheck& check = Get(kCheckApplyStep);
  check.applicable = true;
  check.tolerance = o_.step_tolerance;
  const Eigen::VectorXd p = m.parameters();
  std::normal_distribution<double> normal(0.0, 1.0);
  Eigen::VectorXd step(p.size());
  for (Eigen::Index i = 0; i < p.size(); ++i)
    step[i] = o_.step_fraction * ParameterStepScale(p[i]) * normal(rng_);
  std::unique_ptr<ParametricModel> stepped = m.Clone(), set = m.Clone(), zero = m.Clone();
  stepped->ApplyStep(step);
  set->set_parameters(p + step);
  zero->ApplyStep(Eigen::VectorXd::Zero(p.size()));
  Eigen::Matrix3Xd columns;
  for (const Sample& s : samples) {
    const Eigen::Vector3d c0 = PointAt(m, s.t), c1 = PointAt(*stepped, s.t);
    const std::string where = label + ", " + FormatT(s.t, m_);
    // A small step, applied, agrees with setting the stepped parameters (the rotation increments and other
    // non-linear updates of ApplyStep coincide with the linear ones to first order) ...
    Record(
        check,
        (c1 - PointAt(*set, s.t)).norm() / (step.norm() * size_ + kFloorFraction * size_ * o_.step_fraction),
        [&] { return where + ": ApplyStep(D) and set_parameters(P + D) differ"; });
    // ... moves the points by J D to first order (docs/method.md section 6: the linearized problem's step)
    // ...
    DenseJacobian(m, s.t, false, columns);
    const Eigen::Vector3d predicted = columns * step;
    Record(check,
           (c1 - c0 - predicted).norm() / (predicted.norm() + kFloorFraction * size_ * o_.step_fraction),
           [&] { return where + ": ApplyStep(D) does not move C by J D"; });
    // ... and a zero step changes nothing.
    Record(check, (PointAt(*zero, s.t) - c0).norm() / size_,
           [&] { return where + ": ApplyStep(0) moved C"; });
  }
}

void Checker::CheckFeet(const ParametricModel& m, const std::vector<Sample>& samples,
                        const std::string& label) {
  const FootPointContext context(m);
  if (!context.closed_form && context.reduction == nullptr) return;
  ModelCheck& check = Get(kCheckClosedFormFeet);
  check.applicable = true;
  const ParameterDomain domain = m.domain();
  std::bernoulli_distribution sign(0.5);
  LocalGeometry g, fast_g, newton_g;
  for (const Sample& s : samples) {
    m.Evaluate(s.t, 2, g);
    const Eigen::Matrix3Xd normals = NormalSpace(g);
    if (normals.cols() == 0) continue;
    // Off the model along a normal, within half the smallest radius of curvature: the foot is the
    // generating t, at distance |offset|.
    const Eigen::Vector3d direction = normals.col(0);
    const PrincipalFrame frame = ComputePrincipalFrame(g, g.point + (1e-3 * size_ * direction).head(s_));
    double largest_curvature = std::abs(frame.curvatures[0]);
    if (frame.tangent_count == 2)
      largest_curvature = std::max(largest_curvature, std::abs(frame.curvatures[1]));
    double offset = o_.foot_offset * size_;
    if (largest_curvature > 0) offset = std::min(offset, 0.5 / largest_curvature);
    if (sign(rng_)) offset = -offset;
    const VecS x = g.point + (offset * direction).head(s_);
    const FootPoint fast = FootPointOf(context, x, nullptr, WarmStart::kVerified, fast_g);
    const FootPoint newton = RefineFootPoint(m, domain, x, s.t, newton_g);
    const std::string where = label + ", " + FormatT(s.t, m_);
    // The fast foot is a point of the model at the distance it reports ...
    const Eigen::Vector3d foot_point = PointAt(m, fast.t);
    Record(check, std::abs((foot_point - To3(x)).norm() - fast.distance) / size_,
           [&] { return where + ": the reported distance is not |C(t) - x|"; });
    // ... no farther than the generic Newton's foot (closer only where another face of a part is nearer) ...
    Record(check, std::max(0.0, fast.distance - newton.distance) / size_, [&] {
      return where + ": farther than Newton's foot (" + std::to_string(fast.distance) + " vs " +
             std::to_string(newton.distance) + ")";
    });
    // ... and orthogonal: C_t^T (C - x) = 0 (docs/method.md section 10) unless on an open boundary.
    if (!fast.on_boundary) {
      LocalGeometry at_foot;
      m.Evaluate(fast.t, 1, at_foot);
      const Eigen::Vector3d residual = foot_point - To3(x);
      for (int k = 0; k < m_; ++k) {
        const Eigen::Vector3d tangent = To3(at_foot.d1.col(k));
        if (tangent.norm() == 0) continue;
        Record(check, std::abs(tangent.dot(residual)) / (tangent.norm() * size_),
               [&] { return where + ": the foot is not orthogonal along t" + std::to_string(k); });
      }
    }
  }
}

ModelCheckReport Checker::Run() {
  ModelCheckReport report;
  report.model_name = model_.name();
  report.num_parameters = model_.num_parameters();
  m_ = model_.domain().dimension;
  s_ = model_.ambient_dimension();
  size_ = ModelSize(model_);
  report.model_size = size_;
  checks_ = {MakeCheck(kCheckFirstDerivatives, o_.derivative_tolerance),
             MakeCheck(kCheckSecondDerivatives, o_.second_derivative_tolerance),
             MakeCheck(kCheckShapeJacobian, o_.jacobian_tolerance),
             MakeCheck(kCheckShapeJacobianDt, o_.jacobian_tolerance),
             MakeCheck(kCheckFactoredJacobian, o_.identity_tolerance),
             MakeCheck(kCheckPrincipalFrame, o_.curvature_tolerance),
             MakeCheck(kCheckInvariantMotions, o_.identity_tolerance),
             MakeCheck(kCheckCommonMotions, o_.identity_tolerance),
             MakeCheck(kCheckSimilarity, o_.identity_tolerance),
             MakeCheck(kCheckCloneCopy, o_.identity_tolerance),
             MakeCheck(kCheckParameterRoundTrip, o_.identity_tolerance),
             MakeCheck(kCheckApplyStep, o_.step_tolerance),
             MakeCheck(kCheckClosedFormFeet, o_.identity_tolerance)};
  for (const char* name : {kCheckFirstDerivatives, kCheckSecondDerivatives, kCheckShapeJacobian})
    Get(name).applicable = true;
  Get(kCheckShapeJacobianDt).applicable = true;

  std::normal_distribution<double> normal(0.0, 1.0);
  const Eigen::VectorXd p0 = model_.parameters();
  for (int state = 0; state <= o_.perturbation_count; ++state) {
    std::unique_ptr<ParametricModel> m = model_.Clone();
    std::string label = "as given";
    if (state > 0) {
      Eigen::VectorXd p = p0;
      for (Eigen::Index i = 0; i < p.size(); ++i)
        p[i] += o_.parameter_perturbation * std::max(std::abs(p0[i]), 0.1) * normal(rng_);
      m->set_parameters(p);
      label = "perturbation " + std::to_string(state);
    }
    const std::vector<Sample> samples = ChooseSamples(*m, o_, rng_);
    CheckDerivatives(*m, samples, label);
    CheckJacobian(*m, samples, label);
    CheckFactored(*m, samples, label);
    CheckPrincipalFrame(*m, samples, label);
    CheckInvariantMotions(*m, samples, label);
    CheckCommonMotions(*m, label);
    CheckSimilarity(*m, samples, label);
    CheckCloneCopy(*m, samples, label);
    CheckRoundTrip(*m, samples, label);
    CheckApplyStep(*m, samples, label);
    CheckFeet(*m, samples, label);
  }
  for (ModelCheck& c : checks_) c.passed = !c.applicable || c.worst_error <= c.tolerance;
  report.checks = checks_;
  return report;
}

}  // namespace

bool ModelCheckOptions::IsValid(std::string* why) const {
  auto fail = [&](const std::string& reason) {
    if (why) *why = reason;
    return false;
  };
  if (sample_count < 1) return fail("sample_count must be at least 1");
  if (perturbation_count < 0) return fail("perturbation_count must not be negative");
  for (const auto& [name, value] : {std::pair<const char*, double>{"sample_jitter", sample_jitter},
                                    {"parameter_perturbation", parameter_perturbation},
                                    {"derivative_step", derivative_step},
                                    {"second_derivative_step", second_derivative_step},
                                    {"parameter_step", parameter_step},
                                    {"derivative_tolerance", derivative_tolerance},
                                    {"second_derivative_tolerance", second_derivative_tolerance},
                                    {"jacobian_tolerance", jacobian_tolerance},
                                    {"curvature_tolerance", curvature_tolerance},
                                    {"identity_tolerance", identity_tolerance},
                                    {"step_fraction", step_fraction},
                                    {"step_tolerance", step_tolerance},
                                    {"foot_offset", foot_offset}}) {
    if (!(value > 0) || !std::isfinite(value))
      return fail(std::string(name) + " must be positive and finite");
  }
  // The difference stencils must stay within the distance the jitter moves samples off knots.
  if (!(2.0 * std::max(derivative_step, second_derivative_step) < 0.5 * sample_jitter))
    return fail("the difference steps must be below a quarter of sample_jitter");
  if (sample_jitter >= 0.1) return fail("sample_jitter must be below 0.1");
  return true;
}

bool ModelCheckReport::ok() const {
  return std::all_of(checks.begin(), checks.end(), [](const ModelCheck& c) { return c.passed; });
}

const ModelCheck* ModelCheckReport::Find(const std::string& name) const {
  for (const ModelCheck& c : checks)
    if (c.name == name) return &c;
  return nullptr;
}

std::string ModelCheckReport::ToString() const {
  std::ostringstream out;
  out << "model check of " << model_name << " (" << num_parameters << " parameters, size " << model_size
      << "): " << (ok() ? "ok" : "FAILED") << "\n";
  out.precision(3);
  for (const ModelCheck& c : checks) {
    out << "  " << (c.applicable ? (c.passed ? "pass " : "FAIL ") : "n/a  ") << c.name;
    if (c.applicable) {
      out << ": worst " << std::scientific << c.worst_error << " (tolerance " << c.tolerance << ", "
          << c.evaluations << " values)" << std::defaultfloat;
      if (!c.worst_at.empty()) out << " at " << c.worst_at;
    }
    out << "\n";
  }
  return out.str();
}

ModelCheckReport CheckModel(const ParametricModel& model, const ModelCheckOptions& options) {
  std::string why;
  if (!options.IsValid(&why)) throw std::invalid_argument("model check options: " + why);
  return Checker(model, options).Run();
}

}  // namespace s2m
