#include "fitting/minimum_zone.h"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

#include "fitting/primitive_fit.h"
#include "fitting/primitive_local_models.h"

namespace s2m {

const char* ToString(FitCriterion criterion) {
  switch (criterion) {
    case FitCriterion::kLeastSquares:
      return "lsq";
    case FitCriterion::kMinimumZone:
      return "minzone";
    case FitCriterion::kInscribed:
      return "inscribed";
    case FitCriterion::kCircumscribed:
      return "circumscribed";
  }
  return "?";
}

FitCriterion FitCriterionFromString(const std::string& text) {
  for (FitCriterion c : {FitCriterion::kLeastSquares, FitCriterion::kMinimumZone, FitCriterion::kInscribed,
                         FitCriterion::kCircumscribed}) {
    if (text == ToString(c)) return c;
  }
  throw std::invalid_argument("'" + text + "' is not a criterion: lsq, minzone, inscribed or circumscribed");
}

bool ChebyshevFitOptions::IsValid(std::string* why) const {
  if (max_iterations < 1) {
    if (why) *why = "max_iterations must be at least 1";
    return false;
  }
  if (!(tolerance > 0.0 && tolerance < 1e-3)) {
    if (why) *why = "tolerance must be in (0, 1e-3)";
    return false;
  }
  return linear_program.IsValid(why);
}

namespace {

using primitive_local::ConeLocal;
using primitive_local::CylinderLocal;
using primitive_local::LineLocal;
using primitive_local::Normalize;
using primitive_local::NormalizedData;
using primitive_local::PlanarCircleLocal;
using primitive_local::PlaneLocal;
using primitive_local::SphereLocal;
using primitive_local::TorusLocal;

// Which extremes the criterion bounds (docs/metrology.md eqs. 5-8): the largest distance (circumscribed,
// straightness), the smallest (inscribed) or both (minimum zone).
enum class Side { kUpper, kLower, kBoth };

// Per point the distance v_i and its gradient g_i over the local parameters without the size parameter
// (which shifts every distance alike and so leaves the zone's shape unchanged): the rows of the
// least-squares fits; for the curves the length of the 2-vector residual r_i, with gradient r_i^T J_i / |r_i|
// (docs/metrology.md eq. 6).
template <class Model>
struct Linearized {
  Eigen::VectorXd v;
  Eigen::MatrixXd g;
};

template <class Model>
constexpr int FreeParameters() {
  return Model::kParams - (Model::kSizeParameter >= 0 ? 1 : 0);
}

template <class Model>
Linearized<Model> LinearizeAt(const typename Model::Shape& shape, const Eigen::Matrix3Xd& y) {
  Eigen::VectorXd d;
  Eigen::Matrix<double, Eigen::Dynamic, Model::kParams> J;
  Eigen::Matrix<double, Model::kParams, Model::kParams> T;
  Model::Linearize(shape, y, false, nullptr, d, J, T);
  const Eigen::Index n = y.cols();
  constexpr int q = FreeParameters<Model>();
  Linearized<Model> out;
  out.v.resize(n);
  out.g.resize(n, q);
  for (Eigen::Index i = 0; i < n; ++i) {
    Eigen::Matrix<double, 1, Model::kParams> row;
    if constexpr (Model::kRowsPerPoint == 1) {
      out.v[i] = d[i];
      row = J.row(i);
    } else {
      const auto r = d.template segment<Model::kRowsPerPoint>(Model::kRowsPerPoint * i);
      const double length = r.norm();
      out.v[i] = length;
      row = length > 0 ? Eigen::Matrix<double, 1, Model::kParams>(
                             r.transpose() *
                             J.template middleRows<Model::kRowsPerPoint>(Model::kRowsPerPoint * i) / length)
                       : Eigen::Matrix<double, 1, Model::kParams>::Zero();
    }
    int k = 0;
    for (int p = 0; p < Model::kParams; ++p)
      if (p != Model::kSizeParameter) out.g(i, k++) = row[p];
  }
  return out;
}

double Merit(const Eigen::VectorXd& v, Side side) {
  switch (side) {
    case Side::kUpper:
      return v.maxCoeff();
    case Side::kLower:
      return -v.minCoeff();
    case Side::kBoth:
      return v.maxCoeff() - v.minCoeff();
  }
  return 0.0;
}

// One linear program of the sequence (docs/metrology.md eq. 8): unknowns the step delta (q) and the bounds
// (u for the upper side, l for the lower), rows v_i + g_i delta <= u and/or >= l for the points that can
// be active within the box |delta_k| <= radius, and the box itself. A point i is left out when even its
// largest move s_i = radius |g_i|_1 cannot reach the bound: v_i + s_i < max_j (v_j - s_j) for the upper
// side (and symmetrically for the lower), which is exact (the left-out rows hold for every step in the box).
struct StepProblem {
  Eigen::MatrixXd A;
  Eigen::VectorXd b, c;
  std::vector<Eigen::Index> row_point;  // per row: the point, or -1 for box rows
  std::vector<int> row_side;            // +1 upper, -1 lower, 0 box
};

StepProblem BuildStep(const Eigen::VectorXd& v, const Eigen::MatrixXd& g, Side side, double radius) {
  const Eigen::Index n = v.size(), q = g.cols();
  const Eigen::VectorXd reach = radius * g.cwiseAbs().rowwise().sum();
  const bool upper = side != Side::kLower, lower = side != Side::kUpper;
  const double upper_floor = (v - reach).maxCoeff(), lower_ceiling = (v + reach).minCoeff();
  std::vector<Eigen::Index> up, down;
  for (Eigen::Index i = 0; i < n; ++i) {
    if (upper && v[i] + reach[i] >= upper_floor) up.push_back(i);
    if (lower && v[i] - reach[i] <= lower_ceiling) down.push_back(i);
  }
  const Eigen::Index bounds = (upper ? 1 : 0) + (lower ? 1 : 0);
  const Eigen::Index unknowns = q + bounds;
  const Eigen::Index u = q, l = q + (upper ? 1 : 0);
  const auto rows = static_cast<Eigen::Index>(up.size() + down.size()) + 2 * q;
  StepProblem p;
  p.A = Eigen::MatrixXd::Zero(rows, unknowns);
  p.b.resize(rows);
  p.c = Eigen::VectorXd::Zero(unknowns);
  if (upper) p.c[u] = 1.0;
  if (lower) p.c[l] = -1.0;
  Eigen::Index r = 0;
  for (Eigen::Index i : up) {  // g_i delta - u <= -v_i
    p.A.row(r).head(q) = g.row(i);
    p.A(r, u) = -1.0;
    p.b[r++] = -v[i];
    p.row_point.push_back(i);
    p.row_side.push_back(1);
  }
  for (Eigen::Index i : down) {  // -g_i delta + l <= v_i
    p.A.row(r).head(q) = -g.row(i);
    p.A(r, l) = 1.0;
    p.b[r++] = v[i];
    p.row_point.push_back(i);
    p.row_side.push_back(-1);
  }
  for (Eigen::Index k = 0; k < q; ++k) {
    p.A(r, k) = 1.0;
    p.b[r++] = radius;
    p.A(r, k) = -1.0;
    p.b[r++] = radius;
    p.row_point.insert(p.row_point.end(), 2, -1);
    p.row_side.insert(p.row_side.end(), 2, 0);
  }
  return p;
}

template <class Model>
Eigen::VectorXd FullStep(const Eigen::VectorXd& free_step, double size_step) {
  Eigen::VectorXd full = Eigen::VectorXd::Zero(Model::kParams);
  int k = 0;
  for (int p = 0; p < Model::kParams; ++p) full[p] = p == Model::kSizeParameter ? size_step : free_step[k++];
  return full;
}

template <class Shape>
Shape ToUnitBox(const Shape& s, const NormalizedData& data) {
  return Transformed(s, 1.0 / data.scale, -data.offset / data.scale);
}

// The extremes and contacts of the distances v (normalized units) at `shape`, mapped to input units.
template <class Shape>
void DescribeZone(const Eigen::VectorXd& v, bool curve, double scale, ChebyshevFit<Shape>& fit) {
  fit.max_distance = v.maxCoeff() * scale;
  fit.min_distance = v.minCoeff() * scale;
  fit.zone_width = curve ? 2.0 * fit.max_distance : fit.max_distance - fit.min_distance;
}

// The sequential linear programs (docs/metrology.md section 3, eqs. 8-11).
template <class Model>
ChebyshevFit<typename Model::Shape> SolveChebyshev(const Eigen::Matrix3Xd& points,
                                                   const typename Model::Shape& start, Side side,
                                                   FitCriterion criterion, int min_points, const char* what,
                                                   const ChebyshevFitOptions& options) {
  using Shape = typename Model::Shape;
  std::string why;
  if (!options.IsValid(&why)) throw std::invalid_argument("invalid Chebyshev fit options: " + why);
  const NormalizedData data = Normalize(points, min_points, what);
  const Eigen::Matrix3Xd& y = data.points;
  Shape shape = ToUnitBox(start, data);
  Linearized<Model> at = LinearizeAt<Model>(shape, y);
  if (!at.v.allFinite() || !at.g.allFinite())
    throw FitError(std::string("cannot fit a ") + what + ": the start gives non-finite distances");
  double merit = Merit(at.v, side);
  // The first region: steps of the order of the zone itself (the Chebyshev solution lies that close to the
  // least-squares one); grown x2 on good steps, shrunk x0.25 on bad ones.
  double radius = std::clamp(at.v.maxCoeff() - at.v.minCoeff(), 1e-6, 1.0);
  ChebyshevFit<Shape> fit;
  fit.criterion = criterion;
  fit.stop_reason = "iteration limit";
  LinearProgramResult last;
  StepProblem last_problem;
  double predicted = std::numeric_limits<double>::infinity();
  for (int iteration = 0; iteration < options.max_iterations; ++iteration) {
    StepProblem problem = BuildStep(at.v, at.g, side, radius);
    LinearProgramResult lp = SolveLinearProgram(problem.A, problem.b, problem.c, options.linear_program);
    if (lp.status != LinearProgramStatus::kOptimal) {
      fit.stop_reason = std::string("linear program ") + ToString(lp.status);
      break;
    }
    predicted = merit - lp.objective;
    if (predicted <= options.tolerance) {
      fit.converged = true;
      fit.stop_reason = "converged";
      last = std::move(lp);
      last_problem = std::move(problem);
      break;
    }
    fit.iterations = iteration + 1;
    const Eigen::VectorXd step = lp.x.head(FreeParameters<Model>());
    const Shape trial = Model::Update(shape, FullStep<Model>(step, 0.0));
    Linearized<Model> trial_at = LinearizeAt<Model>(trial, y);
    const double trial_merit =
        trial_at.v.allFinite() ? Merit(trial_at.v, side) : std::numeric_limits<double>::infinity();
    const double ratio = (merit - trial_merit) / predicted;
    if (ratio >= 0.1) {
      shape = trial;
      at = std::move(trial_at);
      merit = trial_merit;
      if (ratio > 0.75 && step.cwiseAbs().maxCoeff() > 0.99 * radius) radius = std::min(2.0 * radius, 1.0);
      // An inscribed feature inside the points is no larger than their extent (2 in the unit box): one that
      // has grown by more than 10 is not bounded by them (they do not surround it).
      if (side == Side::kLower && -merit > 10.0) {
        throw FitError(std::string("no bounded inscribed ") + what +
                       ": the points do not surround one (a partial arc?)");
      }
    } else {
      radius *= 0.25;
      if (radius < 1e-15) {
        fit.stop_reason = "step region collapsed";
        break;
      }
    }
  }
  // The size parameter closes the feature: the zone's median (both sides), or the outermost / innermost
  // point (eq. 11).
  double size_step = 0.0;
  if constexpr (Model::kSizeParameter >= 0) {
    if (side == Side::kBoth) size_step = 0.5 * (at.v.maxCoeff() + at.v.minCoeff());
    if (side == Side::kUpper) size_step = at.v.maxCoeff();
    if (side == Side::kLower) size_step = at.v.minCoeff();
    shape = Model::Update(shape, FullStep<Model>(Eigen::VectorXd::Zero(FreeParameters<Model>()), size_step));
    at = LinearizeAt<Model>(shape, y);
  }
  DescribeZone(at.v, Model::kRowsPerPoint > 1, data.scale, fit);
  fit.optimality = std::isfinite(predicted) ? std::max(0.0, predicted) * data.scale : predicted;
  if (fit.converged) {
    // The defining points: rows with a positive multiplier (eq. 10).
    const double floor = 1e-9 * std::max(1.0, last.duals.size() > 0 ? last.duals.maxCoeff() : 0.0);
    for (Eigen::Index r = 0; r < last.duals.size(); ++r) {
      const Eigen::Index i = last_problem.row_point[static_cast<std::size_t>(r)];
      if (i < 0 || !(last.duals[r] > floor)) continue;
      fit.contacts.push_back({i, last_problem.row_side[static_cast<std::size_t>(r)], at.v[i] * data.scale});
    }
  } else {
    Eigen::Index hi, lo;
    at.v.maxCoeff(&hi);
    at.v.minCoeff(&lo);
    if (side != Side::kLower) fit.contacts.push_back({hi, 1, at.v[hi] * data.scale});
    if (side != Side::kUpper) fit.contacts.push_back({lo, -1, at.v[lo] * data.scale});
  }
  std::sort(fit.contacts.begin(), fit.contacts.end(),
            [](const ZoneContact& a, const ZoneContact& b) { return a.index < b.index; });
  fit.shape = Transformed(shape, data.scale, data.offset);
  if constexpr (requires(Shape s) { MoveAxisPointNear(s, data.offset); })
    MoveAxisPointNear(fit.shape, data.offset);
  return fit;
}

// Roundness and the inscribed and circumscribed circles live in the circle's plane: the points must not be
// collinear there.
void CheckPlanarSpread(const Eigen::Matrix3Xd& points, const Circle3d& start) {
  if (points.cols() < 3 || !points.allFinite()) return;  // Normalize reports these
  const Eigen::Matrix3d frame = FrameWithAxis(start.normal.normalized());
  const Eigen::Matrix2Xd q = frame.leftCols<2>().transpose() * points;
  const Eigen::Matrix2Xd centred = q.colwise() - q.rowwise().mean();
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> eig(centred * centred.transpose());
  if (!(eig.eigenvalues()[0] > 1e-12 * eig.eigenvalues()[1]))
    throw FitError("cannot fit a circle: the points are collinear in its plane (a circle is not determined)");
}

}  // namespace

ChebyshevFit<Plane> MinimumZoneFit(const Eigen::Matrix3Xd& p, const Plane& s, const ChebyshevFitOptions& o) {
  return SolveChebyshev<PlaneLocal>(p, s, Side::kBoth, FitCriterion::kMinimumZone, 3, "plane", o);
}
ChebyshevFit<Sphere> MinimumZoneFit(const Eigen::Matrix3Xd& p, const Sphere& s,
                                    const ChebyshevFitOptions& o) {
  return SolveChebyshev<SphereLocal>(p, s, Side::kBoth, FitCriterion::kMinimumZone, 4, "sphere", o);
}
ChebyshevFit<Cylinder> MinimumZoneFit(const Eigen::Matrix3Xd& p, const Cylinder& s,
                                      const ChebyshevFitOptions& o) {
  return SolveChebyshev<CylinderLocal>(p, s, Side::kBoth, FitCriterion::kMinimumZone, 5, "cylinder", o);
}
ChebyshevFit<Cone> MinimumZoneFit(const Eigen::Matrix3Xd& p, const Cone& s, const ChebyshevFitOptions& o) {
  return SolveChebyshev<ConeLocal>(p, s, Side::kBoth, FitCriterion::kMinimumZone, 6, "cone", o);
}
ChebyshevFit<Torus> MinimumZoneFit(const Eigen::Matrix3Xd& p, const Torus& s, const ChebyshevFitOptions& o) {
  return SolveChebyshev<TorusLocal>(p, s, Side::kBoth, FitCriterion::kMinimumZone, 7, "torus", o);
}
ChebyshevFit<Line3d> MinimumZoneFit(const Eigen::Matrix3Xd& p, const Line3d& s,
                                    const ChebyshevFitOptions& o) {
  return SolveChebyshev<LineLocal>(p, s, Side::kUpper, FitCriterion::kMinimumZone, 2, "line", o);
}
ChebyshevFit<Circle3d> MinimumZoneFit(const Eigen::Matrix3Xd& p, const Circle3d& s,
                                      const ChebyshevFitOptions& o) {
  CheckPlanarSpread(p, s);
  return SolveChebyshev<PlanarCircleLocal>(p, s, Side::kBoth, FitCriterion::kMinimumZone, 3, "circle", o);
}

ChebyshevFit<Circle3d> InscribedFit(const Eigen::Matrix3Xd& p, const Circle3d& s,
                                    const ChebyshevFitOptions& o) {
  CheckPlanarSpread(p, s);
  return SolveChebyshev<PlanarCircleLocal>(p, s, Side::kLower, FitCriterion::kInscribed, 3, "circle", o);
}
ChebyshevFit<Cylinder> InscribedFit(const Eigen::Matrix3Xd& p, const Cylinder& s,
                                    const ChebyshevFitOptions& o) {
  return SolveChebyshev<CylinderLocal>(p, s, Side::kLower, FitCriterion::kInscribed, 5, "cylinder", o);
}
ChebyshevFit<Sphere> InscribedFit(const Eigen::Matrix3Xd& p, const Sphere& s, const ChebyshevFitOptions& o) {
  return SolveChebyshev<SphereLocal>(p, s, Side::kLower, FitCriterion::kInscribed, 4, "sphere", o);
}
ChebyshevFit<Circle3d> CircumscribedFit(const Eigen::Matrix3Xd& p, const Circle3d& s,
                                        const ChebyshevFitOptions& o) {
  CheckPlanarSpread(p, s);
  return SolveChebyshev<PlanarCircleLocal>(p, s, Side::kUpper, FitCriterion::kCircumscribed, 3, "circle", o);
}
ChebyshevFit<Cylinder> CircumscribedFit(const Eigen::Matrix3Xd& p, const Cylinder& s,
                                        const ChebyshevFitOptions& o) {
  return SolveChebyshev<CylinderLocal>(p, s, Side::kUpper, FitCriterion::kCircumscribed, 5, "cylinder", o);
}
ChebyshevFit<Sphere> CircumscribedFit(const Eigen::Matrix3Xd& p, const Sphere& s,
                                      const ChebyshevFitOptions& o) {
  return SolveChebyshev<SphereLocal>(p, s, Side::kUpper, FitCriterion::kCircumscribed, 4, "sphere", o);
}

namespace {
template <class Model>
ChebyshevFit<typename Model::Shape> Zone(const Eigen::Matrix3Xd& points, const typename Model::Shape& shape) {
  ChebyshevFit<typename Model::Shape> fit;
  fit.shape = shape;
  fit.criterion = FitCriterion::kLeastSquares;
  fit.converged = true;
  fit.stop_reason = "given";
  if (points.cols() == 0) return fit;
  const Eigen::VectorXd v = LinearizeAt<Model>(shape, points).v;
  DescribeZone(v, Model::kRowsPerPoint > 1, 1.0, fit);
  Eigen::Index hi, lo;
  v.maxCoeff(&hi);
  v.minCoeff(&lo);
  fit.contacts.push_back({hi, 1, v[hi]});
  if (Model::kRowsPerPoint == 1) fit.contacts.push_back({lo, -1, v[lo]});
  return fit;
}
}  // namespace

ChebyshevFit<Plane> ZoneAbout(const Eigen::Matrix3Xd& p, const Plane& s) {
  return Zone<PlaneLocal>(p, s);
}
ChebyshevFit<Sphere> ZoneAbout(const Eigen::Matrix3Xd& p, const Sphere& s) {
  return Zone<SphereLocal>(p, s);
}
ChebyshevFit<Cylinder> ZoneAbout(const Eigen::Matrix3Xd& p, const Cylinder& s) {
  return Zone<CylinderLocal>(p, s);
}
ChebyshevFit<Cone> ZoneAbout(const Eigen::Matrix3Xd& p, const Cone& s) {
  return Zone<ConeLocal>(p, s);
}
ChebyshevFit<Torus> ZoneAbout(const Eigen::Matrix3Xd& p, const Torus& s) {
  return Zone<TorusLocal>(p, s);
}
ChebyshevFit<Line3d> ZoneAbout(const Eigen::Matrix3Xd& p, const Line3d& s) {
  return Zone<LineLocal>(p, s);
}
ChebyshevFit<Circle3d> ZoneAbout(const Eigen::Matrix3Xd& p, const Circle3d& s) {
  return Zone<PlanarCircleLocal>(p, s);
}

}  // namespace s2m
