#include "fitting/part_complexity.h"

#include <cmath>
#include <limits>
#include <map>
#include <stdexcept>
#include <utility>

namespace s2m {
namespace {

// sum_k w_k e_k of linear expressions (terms of one parameter merged).
LinearExpression Combine(const std::vector<std::pair<double, const LinearExpression*>>& parts) {
  LinearExpression out;
  std::map<int, double> terms;
  for (const auto& [w, e] : parts) {
    if (w == 0.0) continue;
    out.constant += w * e->constant;
    for (const auto& [index, coefficient] : e->terms) terms[index] += w * coefficient;
  }
  for (const auto& [index, coefficient] : terms)
    if (coefficient != 0.0) out.terms.emplace_back(index, coefficient);
  return out;
}

// Parameter indices at or beyond `from` move by `shift`.
void Renumber(LinearExpression& e, int from, int shift) {
  for (auto& term : e.terms)
    if (term.first >= from) term.first += shift;
}

void RenumberFace(PartFace& f, int from, int shift) {
  for (LinearExpression& e : f.origin) Renumber(e, from, shift);
  Renumber(f.offset, from, shift);
  Renumber(f.radius, from, shift);
  Renumber(f.minor_radius, from, shift);
  Renumber(f.half_angle, from, shift);
  if (f.patch) {
    for (auto& point : f.patch->control_points)
      for (LinearExpression& e : point) Renumber(e, from, shift);
    if (f.patch->first_displacement >= from) f.patch->first_displacement += shift;
  }
}

}  // namespace

PartDefinition RefinePatch(const PartDefinition& part, const Eigen::VectorXd& values, std::size_t face,
                           int direction, double knot) {
  if (face >= part.faces.size() || !part.faces[face].patch)
    throw std::invalid_argument("RefinePatch: face " + std::to_string(face) + " is not a spline patch");
  if (direction != 0 && direction != 1) throw std::invalid_argument("RefinePatch: direction must be 0 or 1");
  if (values.size() != static_cast<Eigen::Index>(part.parameters.size()))
    throw std::invalid_argument("RefinePatch: one value per parameter expected");
  PartDefinition out = part;
  for (std::size_t i = 0; i < out.parameters.size(); ++i)
    out.parameters[i].value = values[static_cast<Eigen::Index>(i)];
  const SplinePatch& old = *part.faces[face].patch;
  const BSplineBasis& refined_basis = direction == 0 ? old.u : old.v;
  if (!(knot > refined_basis.lo() && knot < refined_basis.hi()))
    throw std::invalid_argument("RefinePatch: the knot is outside the patch's domain");
  const BasisRefinement r = RefineBasis(refined_basis, {knot});
  const int nu = old.u.num_control(), nv = old.v.num_control();
  const int nu2 = direction == 0 ? r.basis.num_control() : nu;
  const int nv2 = direction == 0 ? nv : r.basis.num_control();
  const bool free_form = old.first_displacement >= 0;
  const int first = old.first_displacement;

  // P_ij = B_ij + d_ij a (docs/parts.md): the displacement's term is taken out of the base expression, and
  // base and displacement are refined alike (eq. 69 is linear in the control points).
  std::vector<std::array<LinearExpression, 3>> base = old.control_points;
  std::vector<double> displacement(base.size(), 0.0);
  if (free_form) {
    for (std::size_t k = 0; k < base.size(); ++k) {
      const int index = first + static_cast<int>(k);
      displacement[k] = values[index];
      for (LinearExpression& e : base[k]) {
        std::vector<std::pair<int, double>> kept;
        for (const auto& term : e.terms)
          if (term.first != index) kept.push_back(term);
        e.terms = std::move(kept);
      }
    }
  }
  SplinePatch refined = old;
  (direction == 0 ? refined.u : refined.v) = r.basis;
  refined.control_points.assign(static_cast<std::size_t>(nu2 * nv2), {});
  std::vector<double> refined_displacement(static_cast<std::size_t>(nu2 * nv2), 0.0);
  const int n_old = direction == 0 ? nu : nv;
  for (int i2 = 0; i2 < nu2; ++i2) {
    for (int j2 = 0; j2 < nv2; ++j2) {
      const std::size_t at = static_cast<std::size_t>(i2 * nv2 + j2);
      std::array<std::vector<std::pair<double, const LinearExpression*>>, 3> parts;
      for (int k = 0; k < n_old; ++k) {
        const double w = r.transform(direction == 0 ? i2 : j2, k);
        if (w == 0.0) continue;
        const std::size_t from = static_cast<std::size_t>(direction == 0 ? k * nv + j2 : i2 * nv + k);
        for (std::size_t c = 0; c < 3; ++c) parts[c].emplace_back(w, &base[from][c]);
        refined_displacement[at] += w * displacement[from];
      }
      for (std::size_t c = 0; c < 3; ++c) refined.control_points[at][c] = Combine(parts[c]);
    }
  }

  if (free_form) {
    // The face's block of displacements [first, first + n) becomes [first, first + n2): later parameters and
    // every expression that refers to them move by the difference.
    const int n = nu * nv, n2 = nu2 * nv2, shift = n2 - n;
    for (std::size_t f = 0; f < out.faces.size(); ++f)
      if (f != face) RenumberFace(out.faces[f], first + n, shift);
    const std::string& name = part.faces[face].name;
    std::vector<PartParameter> block;
    for (int i = 0; i < nu2; ++i)
      for (int j = 0; j < nv2; ++j)
        block.push_back({name + "[" + std::to_string(i) + "," + std::to_string(j) + "]",
                         refined_displacement[static_cast<std::size_t>(i * nv2 + j)], false});
    out.parameters.erase(out.parameters.begin() + first, out.parameters.begin() + first + n);
    out.parameters.insert(out.parameters.begin() + first, block.begin(), block.end());
    for (int k = 0; k < n2; ++k) {
      for (int c = 0; c < 3; ++c) {
        if (old.free_along[c] != 0.0)
          refined.control_points[static_cast<std::size_t>(k)][static_cast<std::size_t>(c)].terms.emplace_back(
              first + k, old.free_along[c]);
      }
    }
  }
  out.faces[face].patch = std::move(refined);
  return out;
}

std::string PatchControlPoints(const PartDefinition& part) {
  std::string out;
  for (const PartFace& f : part.faces) {
    if (!f.patch) continue;
    if (!out.empty()) out += ", ";
    out += f.name + " " + std::to_string(f.patch->u.num_control()) + "x" +
           std::to_string(f.patch->v.num_control());
  }
  return out;
}

bool RefinablePartFit::HasFreeFormPatches(const PartDefinition& part) {
  for (const PartFace& f : part.faces)
    if (f.patch && f.patch->first_displacement >= 0) return true;
  return false;
}

RefinablePartFit::RefinablePartFit(PartModel& part, std::vector<Eigen::Matrix3Xd> scans,
                                   std::vector<RigidMotion> model_T_scan, JointFitOptions options,
                                   int max_control_points)
    : part_(part),
      scans_(std::move(scans)),
      model_T_scan_(std::move(model_T_scan)),
      options_(std::move(options)),
      max_control_points_(max_control_points) {}

void RefinablePartFit::ComputeFeet() {
  feet_.clear();
  feet_d2_.clear();
  ambiguous_.clear();
  for (std::size_t k = 0; k < scans_.size(); ++k) {
    const Eigen::Matrix3Xd placed = model_T_scan_[k].apply(scans_[k]);
    for (Eigen::Index j = 0; j < placed.cols(); ++j) {
      const VecS x = placed.col(j);
      ParamT t{0.0, 0.0, 0.0};
      double distance = 0.0;
      bool on_boundary = false, ambiguous = false;
      part_.ClosedFormFoot(x, t, distance, on_boundary, ambiguous);
      feet_.push_back(t);
      feet_d2_.push_back(distance * distance);
      ambiguous_.push_back(ambiguous || !std::isfinite(distance));
    }
  }
}

RefinableFit::Outcome RefinablePartFit::Fit() {
  // Every step keeps the first step's edge margin (FitPartJointly reuses a margin the part already has), so
  // the steps are judged on the same points up to the feet's own moves.
  result_ = FitPartJointly(part_, scans_, model_T_scan_, options_);
  model_T_scan_ = result_.model_T_scan;
  total_iterations_ += result_.iterations;
  ComputeFeet();
  Outcome r;
  for (std::size_t j = 0; j < feet_d2_.size(); ++j) {
    if (ambiguous_[j]) continue;
    r.sum_squares += feet_d2_[j];
    r.points += 1.0;
  }
  r.shape_parameters = part_.num_parameters();
  r.other_parameters = 6 * static_cast<int>(scans_.size());
  r.iterations = result_.iterations;
  return r;
}

bool RefinablePartFit::Refine() {
  // The span with the largest sum of squared residuals over every free-form patch and both directions,
  // compared per control point the insertion adds (as RefinableSplineFit does for one surface).
  const PartDefinition& d = part_.definition();
  double best_value = -1.0, best_knot = 0.0;
  int best_face = -1, best_direction = 0;
  for (std::size_t f = 0; f < d.faces.size(); ++f) {
    const PartFace& face = d.faces[f];
    if (!face.patch || face.patch->first_displacement < 0) continue;
    std::vector<double> u, v, d2;
    for (std::size_t j = 0; j < feet_.size(); ++j) {
      if (ambiguous_[j] || PartModel::FaceOf(feet_[j]) != static_cast<int>(f)) continue;
      u.push_back(feet_[j][0]);
      v.push_back(feet_[j][1]);
      d2.push_back(feet_d2_[j]);
    }
    if (d2.empty()) continue;
    for (int direction = 0; direction < 2; ++direction) {
      const BSplineBasis& basis = direction == 0 ? face.patch->u : face.patch->v;
      const int across = direction == 0 ? face.patch->v.num_control() : face.patch->u.num_control();
      if (basis.num_control() >= max_control_points_) continue;
      const SpanResiduals s = ResidualsPerSpan(basis, direction == 0 ? u : v, d2);
      for (std::size_t i = 0; i < s.sum_squares.size(); ++i) {
        const double value = s.sum_squares[i] / across;
        if (s.points[i] == 0 || value <= best_value) continue;
        best_value = value;
        best_face = static_cast<int>(f);
        best_direction = direction;
        best_knot = 0.5 * (s.breakpoints[i] + s.breakpoints[i + 1]);
      }
    }
  }
  if (best_face < 0) return false;
  const double margin = part_.edge_margin();
  part_ = PartModel(
      RefinePatch(d, part_.parameters(), static_cast<std::size_t>(best_face), best_direction, best_knot));
  part_.set_edge_margin(margin);
  return true;
}

void RefinablePartFit::Keep(std::size_t index) {
  kept_.resize(std::max(kept_.size(), index + 1));
  kept_[index] = {part_.Clone(), result_, model_T_scan_};
}

void RefinablePartFit::Restore(std::size_t index) {
  KeptState& s = kept_.at(index);
  part_.CopyFrom(*s.part);
  result_ = s.result;
  model_T_scan_ = s.poses;
  ComputeFeet();
}

}  // namespace s2m
