#include "fitting/hermite_curve.h"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>

#include "fitting/bernstein_roots.h"
#include "fitting/foot_point.h"

namespace s2m {
namespace {

const char* kAxis[3] = {"x", "y", "z"};

double Factorial(int n) {
  double f = 1.0;
  for (int i = 2; i <= n; ++i) f *= i;
  return f;
}

void CheckDegree(int degree) {
  if (degree != 3 && degree != 5) throw std::invalid_argument("Hermite curves are cubic or quintic");
}

}  // namespace

Eigen::MatrixXd HermiteShapeCoefficients(int degree, double h) {
  CheckDegree(degree);
  if (!(h > 0)) throw std::invalid_argument("a Hermite element needs a positive length");
  const int m = (degree - 1) / 2, n = degree + 1;
  // Conditions on a polynomial sum_k c_k t^k: its j-th t-derivative at t = 0 (rows 0..m) and t = 1 (rows
  // m+1..2m+1). The shape functions are the dual basis (docs/fair-curves.md eq. F3): C V^T = I.
  Eigen::MatrixXd v = Eigen::MatrixXd::Zero(n, n);
  for (int j = 0; j <= m; ++j) {
    v(j, j) = Factorial(j);
    for (int k = j; k < n; ++k) v(m + 1 + j, k) = Factorial(k) / Factorial(k - j);
  }
  Eigen::MatrixXd c = v.transpose().fullPivLu().inverse();
  // The dof w^(j) multiplies h^j times the t-basis function (d/du = (1 / h) d/dt).
  for (int side = 0; side < 2; ++side)
    for (int j = 0; j <= m; ++j) c.row(side * (m + 1) + j) *= std::pow(h, j);
  return c;
}

ElementBasis HermiteElementBasis(int degree, double h) {
  ElementBasis b;
  b.coefficients = HermiteShapeCoefficients(degree, h);
  b.length = h;
  b.y_lo = 0.0;
  b.y_hi = 1.0;
  return b;
}

HermiteCurve::HermiteCurve(int degree, std::vector<double> knots, Eigen::MatrixXd dofs, bool closed, bool c2)
    : degree_(degree), per_node_((degree + 1) / 2), knots_(std::move(knots)), closed_(closed), c2_(c2) {
  CheckDegree(degree_);
  if (c2_ && degree_ != 3) throw std::invalid_argument("the C2 reduction is for cubic Hermite curves");
  if (knots_.size() < 2) throw std::invalid_argument("a Hermite curve needs at least one element");
  if (closed_ && knots_.size() < 3) throw std::invalid_argument("a closed Hermite curve needs two elements");
  if (knots_.front() != 0.0 || knots_.back() != 1.0)
    throw std::invalid_argument("the knots of a Hermite curve run from 0 to 1");
  for (std::size_t i = 0; i + 1 < knots_.size(); ++i)
    if (!(knots_[i + 1] > knots_[i])) throw std::invalid_argument("the knots must increase strictly");
  if (dofs.rows() != 2 && dofs.rows() != 3) throw std::invalid_argument("a Hermite curve lives in 2D or 3D");
  if (dofs.cols() != static_cast<Eigen::Index>(num_nodes()) * per_node_) {
    throw std::invalid_argument("the curve has " + std::to_string(num_nodes()) + " nodes of " +
                                std::to_string(per_node_) + " dofs but " + std::to_string(dofs.cols()) +
                                " nodal values were given");
  }
  if (!dofs.allFinite()) throw std::invalid_argument("the nodal values contain NaN or inf");
  values_ = dofs;
  BuildExpansion();
  independent_.resize(values_.rows(), expansion_.cols());
  for (std::size_t k = 0; k < independent_global_.size(); ++k)
    independent_.col(static_cast<Eigen::Index>(k)) = values_.col(independent_global_[k]);
  Rebuild();
}

HermiteCurve HermiteCurve::Uniform(int degree, int elements, Eigen::MatrixXd dofs, bool closed, bool c2) {
  if (elements < 1) throw std::invalid_argument("a Hermite curve needs at least one element");
  std::vector<double> knots(static_cast<std::size_t>(elements) + 1);
  for (int i = 0; i <= elements; ++i) knots[static_cast<std::size_t>(i)] = static_cast<double>(i) / elements;
  knots.back() = 1.0;
  return HermiteCurve(degree, std::move(knots), std::move(dofs), closed, c2);
}

int HermiteCurve::GlobalDof(int element, int local) const {
  return ElementNode(element, local / per_node_) * per_node_ + local % per_node_;
}

void HermiteCurve::BuildExpansion() {
  const int dofs = num_nodes() * per_node_;
  if (!c2_) {
    expansion_ = Eigen::MatrixXd::Identity(dofs, dofs);
    independent_global_.resize(static_cast<std::size_t>(dofs));
    for (int d = 0; d < dofs; ++d) independent_global_[static_cast<std::size_t>(d)] = d;
    return;
  }
  // Reduced transformation (Fang section 5.3, docs/fair-curves.md eq. F11): the C2 conditions A Q = 0, one
  // per junction (the jump of w'' across it), split into the independent dofs (positions, and an open
  // curve's two end slopes) and the dependent ones (the other slopes): Q_dep = -A_dep^-1 A_indep Q_indep.
  std::vector<int> junctions;
  for (int node = closed_ ? 0 : 1; node < (closed_ ? num_nodes() : num_nodes() - 1); ++node)
    junctions.push_back(node);
  Eigen::MatrixXd a = Eigen::MatrixXd::Zero(static_cast<Eigen::Index>(junctions.size()), dofs);
  for (std::size_t r = 0; r < junctions.size(); ++r) {
    const int node = junctions[r];
    const int right = node, left = closed_ ? (node + num_elements() - 1) % num_elements() : node - 1;
    const Eigen::VectorXd row_r =
        ElementDerivativeRow(HermiteElementBasis(3, knots_[right + 1] - knots_[right]), 2, 0.0);
    const Eigen::VectorXd row_l =
        ElementDerivativeRow(HermiteElementBasis(3, knots_[left + 1] - knots_[left]), 2, 1.0);
    for (int l = 0; l < 4; ++l) {
      a(static_cast<Eigen::Index>(r), GlobalDof(right, l)) += row_r[l];
      a(static_cast<Eigen::Index>(r), GlobalDof(left, l)) -= row_l[l];
    }
  }
  std::vector<int> indep, dep;
  for (int node = 0; node < num_nodes(); ++node) {
    indep.push_back(2 * node);
    const bool end = !closed_ && (node == 0 || node == num_nodes() - 1);
    (end ? indep : dep).push_back(2 * node + 1);
  }
  std::sort(indep.begin(), indep.end());
  independent_global_ = indep;
  Eigen::MatrixXd a_dep(a.rows(), static_cast<Eigen::Index>(dep.size())),
      a_indep(a.rows(), static_cast<Eigen::Index>(indep.size()));
  for (std::size_t k = 0; k < dep.size(); ++k) a_dep.col(static_cast<Eigen::Index>(k)) = a.col(dep[k]);
  for (std::size_t k = 0; k < indep.size(); ++k) a_indep.col(static_cast<Eigen::Index>(k)) = a.col(indep[k]);
  const Eigen::MatrixXd d1 = -a_dep.partialPivLu().solve(a_indep);
  expansion_ = Eigen::MatrixXd::Zero(dofs, static_cast<Eigen::Index>(indep.size()));
  for (std::size_t k = 0; k < indep.size(); ++k) expansion_(indep[k], static_cast<Eigen::Index>(k)) = 1.0;
  for (std::size_t k = 0; k < dep.size(); ++k) expansion_.row(dep[k]) = d1.row(static_cast<Eigen::Index>(k));
}

void HermiteCurve::Rebuild() {
  values_ = independent_ * expansion_.transpose();
  const int s = ambient_dimension(), e_count = num_elements(), n = degree_ + 1;
  power_.resize(static_cast<std::size_t>(e_count));
  box_lo_.resize(static_cast<std::size_t>(e_count));
  box_hi_.resize(static_cast<std::size_t>(e_count));
  for (int e = 0; e < e_count; ++e) {
    const Eigen::MatrixXd c = HermiteShapeCoefficients(degree_, knots_[e + 1] - knots_[e]);
    Eigen::MatrixXd local(s, n);
    for (int l = 0; l < n; ++l) local.col(l) = values_.col(GlobalDof(e, l));
    Eigen::MatrixXd& p = power_[static_cast<std::size_t>(e)];
    p = local * c;  // s x (degree + 1)
    // Bounding box of the element's Bezier points (convex hull property): a lower bound of distances.
    Eigen::VectorXd lo(s), hi(s);
    for (int k = 0; k < s; ++k) {
      const Eigen::VectorXd b = PowerToBernstein(p.row(k).transpose());
      lo[k] = b.minCoeff();
      hi[k] = b.maxCoeff();
    }
    box_lo_[static_cast<std::size_t>(e)] = lo;
    box_hi_[static_cast<std::size_t>(e)] = hi;
  }
}

std::string HermiteCurve::name() const {
  return std::string(closed_ ? "closed " : "open ") +
         (degree_ == 3 ? (c2_ ? "C2 cubic" : "cubic") : "quintic") + " Hermite curve";
}

ParameterDomain HermiteCurve::domain() const {
  ParameterDomain d;
  d.dimension = 1;
  d.lo[0] = 0.0;
  d.hi[0] = 1.0;
  d.periodic[0] = closed_;
  return d;
}

std::string HermiteCurve::parameter_name(int index) const {
  const int s = ambient_dimension();
  const int dof = index / s;
  const int global = independent_global_[static_cast<std::size_t>(dof)];
  static const char* kind[3] = {"position", "first derivative", "second derivative"};
  return "node " + std::to_string(global / per_node_) + " " + kind[global % per_node_] + " " +
         kAxis[index % s];
}

Eigen::VectorXd HermiteCurve::parameters() const {
  return Eigen::Map<const Eigen::VectorXd>(independent_.data(), independent_.size());
}

void HermiteCurve::set_parameters(const Eigen::VectorXd& p) {
  independent_ = Eigen::Map<const Eigen::MatrixXd>(p.data(), independent_.rows(), independent_.cols());
  Rebuild();
}

void HermiteCurve::ApplySimilarity(double scale, const VecS& offset) {
  // Positions map affinely, derivatives with respect to u (the domain is unchanged) linearly.
  for (Eigen::Index k = 0; k < independent_.cols(); ++k) {
    const int global = independent_global_[static_cast<std::size_t>(k)];
    independent_.col(k) *= scale;
    if (global % per_node_ == 0) independent_.col(k) += Eigen::VectorXd(offset);
  }
  Rebuild();
}

int HermiteCurve::Locate(double u, double& t) const {
  if (closed_) {
    u -= std::floor(u);
  } else {
    u = std::clamp(u, 0.0, 1.0);
  }
  const auto it = std::upper_bound(knots_.begin(), knots_.end(), u);
  int e = static_cast<int>(it - knots_.begin()) - 1;
  e = std::clamp(e, 0, num_elements() - 1);
  t = (u - knots_[e]) / (knots_[e + 1] - knots_[e]);
  if (closed_ && t >= 1.0) t = 1.0;
  return e;
}

void HermiteCurve::EvaluateOnElement(int element, double t, int order, Eigen::MatrixXd& out) const {
  const Eigen::MatrixXd& a = power_[static_cast<std::size_t>(element)];
  const double h = knots_[element + 1] - knots_[element];
  const int s = ambient_dimension();
  out.setZero(s, order + 1);
  // Horner for each derivative of sum_j a_j t^j, then d^k/du^k = h^-k d^k/dt^k.
  for (int k = 0; k <= order && k <= degree_; ++k) {
    const double scale = std::pow(h, -k);
    for (int c = 0; c < s; ++c) {
      double v = 0.0;
      for (int j = degree_; j >= k; --j) v = v * t + a(c, j) * (Factorial(j) / Factorial(j - k));
      out(c, k) = v * scale;
    }
  }
}

void HermiteCurve::EvaluateJet(double u, int order, Eigen::MatrixXd& out) const {
  double t = 0.0;
  const int e = Locate(u, t);
  EvaluateOnElement(e, t, order, out);
}

void HermiteCurve::Evaluate(const ParamT& t, int derivatives, LocalGeometry& out) const {
  double local = 0.0;
  const int e = Locate(t[0], local);
  const Eigen::MatrixXd& a = power_[static_cast<std::size_t>(e)];
  const double h = knots_[e + 1] - knots_[e];
  const int s = ambient_dimension();
  out.point.resize(s);
  out.d1.resize(s, 1);
  out.d2.resize(s, 1);
  for (int c = 0; c < s; ++c) {
    double v = a(c, degree_), d1 = 0.0, d2 = 0.0;
    for (int j = degree_ - 1; j >= 0; --j) {
      d2 = d2 * local + 2.0 * d1;
      d1 = d1 * local + v;
      v = v * local + a(c, j);
    }
    out.point[c] = v;
    out.d1(c, 0) = derivatives >= 1 ? d1 / h : 0.0;
    out.d2(c, 0) = derivatives >= 2 ? d2 / (h * h) : 0.0;
  }
}

void HermiteCurve::ShapeJacobian(const ParamT& t, bool with_dt, std::vector<JacobianEntry>& out) const {
  out.clear();
  double local = 0.0;
  const int e = Locate(t[0], local);
  const ElementBasis basis = HermiteElementBasis(degree_, knots_[e + 1] - knots_[e]);
  const Eigen::VectorXd phi = ElementDerivativeRow(basis, 0, local);
  const Eigen::VectorXd dphi =
      with_dt ? ElementDerivativeRow(basis, 1, local) : Eigen::VectorXd::Zero(phi.size());
  const int s = ambient_dimension();
  // Weights per independent dof: sum over the element's dofs of phi_l T(global_l, k).
  Eigen::VectorXd w = Eigen::VectorXd::Zero(expansion_.cols()), dw = w;
  for (int l = 0; l < degree_ + 1; ++l) {
    const int g = GlobalDof(e, l);
    if (!c2_) {
      w[g] += phi[l];
      dw[g] += dphi[l];
    } else {
      w += phi[l] * expansion_.row(g).transpose();
      dw += dphi[l] * expansion_.row(g).transpose();
    }
  }
  for (Eigen::Index k = 0; k < w.size(); ++k) {
    if (w[k] == 0.0 && dw[k] == 0.0) continue;
    for (int c = 0; c < s; ++c) {
      JacobianEntry entry;
      entry.index = static_cast<int>(k) * s + c;
      entry.column = w[k] * Eigen::Vector3d::Unit(c);
      entry.dcolumn_dt[0] = dw[k] * Eigen::Vector3d::Unit(c);
      entry.dcolumn_dt[1].setZero();
      out.push_back(entry);
    }
  }
}

Eigen::MatrixXd HermiteCurve::FairnessMatrixOf(const HermiteFairness& f) const {
  const int dofs = num_nodes() * per_node_, n = degree_ + 1;
  Eigen::MatrixXd k = Eigen::MatrixXd::Zero(dofs, dofs);
  const double alpha[4] = {0.0, f.alpha1, f.alpha2, f.alpha3};
  // Element matrices K_p^e, exact (docs/fair-curves.md eq. F5), assembled by global dof.
  for (int e = 0; e < num_elements(); ++e) {
    const ElementBasis basis = HermiteElementBasis(degree_, knots_[e + 1] - knots_[e]);
    for (int p = 1; p <= 3; ++p) {
      if (alpha[p] == 0.0) continue;
      const Eigen::MatrixXd ke = alpha[p] * ElementEnergyMatrix(basis, p);
      for (int i = 0; i < n; ++i)
        for (int j = 0; j < n; ++j) k(GlobalDof(e, i), GlobalDof(e, j)) += ke(i, j);
    }
  }
  // Junction matrices beta_p kbar kbar^T (eqs. F6-F9): the jump of w^(p) across each junction node.
  const double beta[4] = {0.0, 0.0, degree_ == 3 ? f.beta2 : 0.0, f.beta3};
  for (int node = closed_ ? 0 : 1; node < (closed_ ? num_nodes() : num_nodes() - 1); ++node) {
    const int right = node, left = closed_ ? (node + num_elements() - 1) % num_elements() : node - 1;
    for (int p = 2; p <= 3; ++p) {
      if (beta[p] == 0.0) continue;
      Eigen::VectorXd jump = Eigen::VectorXd::Zero(dofs);
      const Eigen::VectorXd row_r =
          ElementDerivativeRow(HermiteElementBasis(degree_, knots_[right + 1] - knots_[right]), p, 0.0);
      const Eigen::VectorXd row_l =
          ElementDerivativeRow(HermiteElementBasis(degree_, knots_[left + 1] - knots_[left]), p, 1.0);
      for (int l = 0; l < n; ++l) {
        jump[GlobalDof(right, l)] += row_r[l];
        jump[GlobalDof(left, l)] -= row_l[l];
      }
      k += beta[p] * jump * jump.transpose();
    }
  }
  const Eigen::MatrixXd reduced = c2_ ? Eigen::MatrixXd(expansion_.transpose() * k * expansion_) : k;
  // The same K for every coordinate, parameters interleaved (index dof * s + c).
  const int s = ambient_dimension();
  const Eigen::Index r = reduced.rows();
  Eigen::MatrixXd out = Eigen::MatrixXd::Zero(r * s, r * s);
  for (Eigen::Index i = 0; i < r; ++i)
    for (Eigen::Index j = 0; j < r; ++j)
      for (int c = 0; c < s; ++c) out(i * s + c, j * s + c) = reduced(i, j);
  return out;
}

HermiteFairness HermiteCurve::EnergyBreakdown(const HermiteFairness& f) const {
  const Eigen::VectorXd p = parameters();
  auto term = [&](HermiteFairness one) { return p.dot(FairnessMatrixOf(one) * p); };
  HermiteFairness out;
  out.alpha1 = f.alpha1 != 0 ? term({f.alpha1, 0, 0, 0, 0}) : 0.0;
  out.alpha2 = f.alpha2 != 0 ? term({0, f.alpha2, 0, 0, 0}) : 0.0;
  out.alpha3 = f.alpha3 != 0 ? term({0, 0, f.alpha3, 0, 0}) : 0.0;
  out.beta2 = f.beta2 != 0 ? term({0, 0, 0, f.beta2, 0}) : 0.0;
  out.beta3 = f.beta3 != 0 ? term({0, 0, 0, 0, f.beta3}) : 0.0;
  return out;
}

Eigen::MatrixXd HermiteCurve::FairnessMatrix(const FairnessWeights& weights) const {
  HermiteFairness f = fairness_;
  f.alpha1 += weights.stretch;
  f.alpha2 += weights.bending;
  f.alpha3 += weights.variation;
  f.beta2 += weights.jump2;
  f.beta3 += weights.jump3;
  if (f.IsZero()) return {};
  return FairnessMatrixOf(f);
}

std::vector<ParamT> HermiteCurve::SampleParameters() const {
  // Every element at t = j / 8: the knots themselves and points at least h / 8 away from them (samples just
  // off a knot would put difference stencils across it; the model checker jitters samples off the knots).
  std::vector<ParamT> out;
  constexpr int kPerElement = 8;
  for (int e = 0; e < num_elements(); ++e)
    for (int i = 0; i < kPerElement; ++i)
      out.push_back({knots_[e] + (knots_[e + 1] - knots_[e]) * i / kPerElement, 0.0, 0.0});
  if (!closed_) out.push_back({1.0, 0.0, 0.0});
  return out;
}

std::optional<double> HermiteCurve::FirstFold(int samples) const {
  Eigen::MatrixXd jet;
  EvaluateJet(0.0, 1, jet);
  Eigen::VectorXd previous = jet.col(1);
  for (int k = 1; k <= samples; ++k) {
    const double u = static_cast<double>(k) / samples;
    EvaluateJet(u, 1, jet);
    if (jet.col(1).dot(previous) <= 0.0) return u;
    previous = jet.col(1);
  }
  return std::nullopt;
}

HermiteCurve HermiteCurve::Refined(const std::vector<int>& elements) const {
  std::vector<bool> split(static_cast<std::size_t>(num_elements()), elements.empty());
  for (int e : elements)
    if (e >= 0 && e < num_elements()) split[static_cast<std::size_t>(e)] = true;
  std::vector<double> knots;
  std::vector<Eigen::VectorXd> columns;
  Eigen::MatrixXd jet;
  auto add_node = [&](double u, int e, double t) {
    knots.push_back(u);
    EvaluateOnElement(e, t, per_node_ - 1, jet);
    for (int k = 0; k < per_node_; ++k) columns.push_back(jet.col(k));
  };
  for (int e = 0; e < num_elements(); ++e) {
    add_node(knots_[e], e, 0.0);
    if (split[static_cast<std::size_t>(e)]) add_node(0.5 * (knots_[e] + knots_[e + 1]), e, 0.5);
  }
  if (!closed_) add_node(1.0, num_elements() - 1, 1.0);
  if (closed_) knots.push_back(1.0);
  Eigen::MatrixXd dofs(ambient_dimension(), static_cast<Eigen::Index>(columns.size()));
  for (std::size_t i = 0; i < columns.size(); ++i) dofs.col(static_cast<Eigen::Index>(i)) = columns[i];
  HermiteCurve out(degree_, std::move(knots), std::move(dofs), closed_, c2_);
  out.set_fairness(fairness_);
  return out;
}

// ---- Foot points
// -------------------------------------------------------------------------------------------

double HermiteCurve::FootOnElement(int e, const VecS& x, double& t_best) const {
  const Eigen::MatrixXd& a = power_[static_cast<std::size_t>(e)];
  const int s = ambient_dimension(), d = degree_;
  // g(t) = (w(t) - x) . w_t(t), degree 2d - 1 (docs/fair-curves.md eq. F12): its roots in [0, 1] and the
  // element's ends are the candidates for the smallest |w - x|^2.
  Eigen::VectorXd g = Eigen::VectorXd::Zero(2 * d);
  for (int c = 0; c < s; ++c) {
    for (int i = 0; i <= d; ++i) {
      const double ai = i == 0 ? a(c, 0) - x[c] : a(c, i);
      for (int j = 1; j <= d; ++j) g[i + j - 1] += ai * j * a(c, j);
    }
  }
  std::vector<double> candidates = {0.0, 1.0};
  BernsteinRoots(PowerToBernstein(g), candidates);
  double best = std::numeric_limits<double>::infinity();
  for (const double t : candidates) {
    double d2 = 0.0;
    for (int c = 0; c < s; ++c) {
      double v = a(c, d);
      for (int j = d - 1; j >= 0; --j) v = v * t + a(c, j);
      d2 += (v - x[c]) * (v - x[c]);
    }
    if (d2 < best) {
      best = d2;
      t_best = t;
    }
  }
  return best;
}

bool HermiteCurve::ClosedFormFootPoint(const VecS& x, ParamT& t) const {
  double distance = 0.0;
  bool boundary = false, ambiguous = false;
  return ClosedFormFoot(x, t, distance, boundary, ambiguous);
}

bool HermiteCurve::ClosedFormFoot(const VecS& x, ParamT& t, double& distance, bool& on_boundary,
                                  bool& ambiguous) const {
  if (!x.allFinite()) return false;
  const int e_count = num_elements();
  // Elements in order of the lower bound of their distance (the box of their Bezier points); stop when the
  // bound exceeds the best distance found.
  std::vector<std::pair<double, int>> order(static_cast<std::size_t>(e_count));
  for (int e = 0; e < e_count; ++e) {
    const Eigen::VectorXd below = (box_lo_[static_cast<std::size_t>(e)] - Eigen::VectorXd(x)).cwiseMax(0.0);
    const Eigen::VectorXd above = (Eigen::VectorXd(x) - box_hi_[static_cast<std::size_t>(e)]).cwiseMax(0.0);
    order[static_cast<std::size_t>(e)] = {below.squaredNorm() + above.squaredNorm(), e};
  }
  std::sort(order.begin(), order.end());
  double best = std::numeric_limits<double>::infinity();
  int best_e = 0;
  double best_t = 0.0;
  for (const auto& [bound, e] : order) {
    if (bound > best) break;
    double te = 0.0;
    const double d2 = FootOnElement(e, x, te);
    if (d2 < best) {
      best = d2;
      best_e = e;
      best_t = te;
    }
  }
  double u = knots_[best_e] + best_t * (knots_[best_e + 1] - knots_[best_e]);
  if (closed_ && u >= 1.0) u = 0.0;
  t = {u, 0.0, 0.0};
  distance = std::sqrt(best);
  ambiguous = false;
  on_boundary = FootPointOnBoundary(x, t);
  return true;
}

bool HermiteCurve::FootPointOnBoundary(const VecS& x, const ParamT& t) const {
  if (closed_ || (t[0] > 0.0 && t[0] < 1.0)) return false;
  LocalGeometry g;
  Evaluate(t, 1, g);
  return IsBoundaryFootPoint(domain(), t, g, x);
}

}  // namespace s2m
