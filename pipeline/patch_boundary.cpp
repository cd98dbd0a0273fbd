#include "pipeline/patch_boundary.h"

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>
#include <optional>
#include <sstream>
#include <stdexcept>

#include "acquisition/format_error.h"
#include "acquisition/formats/readers.h"
#include "pipeline/exit_code.h"
#include "pipeline/fit_options.h"
#include "pipeline/output.h"

namespace s2m::pipeline {
namespace {

std::vector<std::string> SplitList(const std::string& list) {
  std::vector<std::string> out;
  std::stringstream in(list);
  std::string item;
  while (std::getline(in, item, ','))
    if (!item.empty()) out.push_back(item);
  return out;
}

Eigen::Vector3d Point3(const nlohmann::json& j, const std::string& file, const std::string& what) {
  if (!j.is_array() || j.size() != 3)
    throw FitFailure(kInputError,
                     file + ": " + what + " is not a 3-D point (boundary curves must be space curves)");
  Eigen::Vector3d p;
  for (int c = 0; c < 3; ++c) p(c) = j.at(static_cast<std::size_t>(c)).get<double>();
  if (!p.allFinite()) throw FitFailure(kInputError, file + ": " + what + " is not finite");
  return p;
}

// The cubic Hermite curve of a scan2model.hermite/1 document (docs/cli.md).
HermiteCurve ReadCurve(const std::string& file) {
  nlohmann::json j;
  try {
    j = nlohmann::json::parse(formats::ReadFileBytes(file));
  } catch (const nlohmann::json::parse_error& e) {
    throw FitFailure(kInputError, file + ": invalid JSON (" + e.what() + ")");
  } catch (const nlohmann::json::out_of_range& e) {  // a number beyond double's range
    throw FitFailure(kInputError, file + ": invalid JSON (" + e.what() + ")");
  } catch (const FormatError& e) {
    throw FitFailure(kInputError, e.what());
  }
  try {
    if (j.value("schema", "") != "scan2model.hermite/1")
      throw FitFailure(kInputError, file +
                                        ": not a Hermite curve's document (scan2model.hermite/1, written by "
                                        "'fit --model hermite-curve -o PREFIX')");
    if (j.at("degree").get<int>() != 3)
      throw FitFailure(kInputError, file +
                                        ": a boundary curve must be cubic (the surface's sides are cubic); "
                                        "this one has degree " +
                                        std::to_string(j.at("degree").get<int>()));
    if (j.at("closed").get<bool>())
      throw FitFailure(kInputError, file + ": a closed curve is not one side of a patch");
    const nlohmann::json& nodes = j.at("nodes");
    const std::vector<double> knots = j.at("knots").get<std::vector<double>>();
    if (nodes.size() < 2 || knots.size() != nodes.size())
      throw FitFailure(kInputError, file + ": " + std::to_string(nodes.size()) + " nodes and " +
                                        std::to_string(knots.size()) + " knots");
    Eigen::MatrixXd dofs(3, 2 * static_cast<Eigen::Index>(nodes.size()));
    for (std::size_t i = 0; i < nodes.size(); ++i) {
      dofs.col(2 * static_cast<Eigen::Index>(i)) =
          Point3(nodes[i].at("position"), file, "node " + std::to_string(i) + "'s position");
      dofs.col(2 * static_cast<Eigen::Index>(i) + 1) =
          Point3(nodes[i].at("first_derivative"), file, "node " + std::to_string(i) + "'s derivative");
    }
    return HermiteCurve(3, knots, dofs, false);
  } catch (const nlohmann::json::exception& e) {
    throw FitFailure(kInputError, file + ": malformed Hermite curve document: " + e.what());
  } catch (const std::invalid_argument& e) {
    throw FitFailure(kInputError, file + ": " + e.what());
  }
}

// The same curve run the other way: u -> 1 - u.
HermiteCurve Reversed(const HermiteCurve& c) {
  const int nodes = c.num_nodes();
  std::vector<double> knots(static_cast<std::size_t>(nodes));
  Eigen::MatrixXd dofs(3, 2 * nodes);
  for (int i = 0; i < nodes; ++i) {
    const int from = nodes - 1 - i;
    knots[static_cast<std::size_t>(i)] = 1.0 - c.knots()[static_cast<std::size_t>(from)];
    dofs.col(2 * i) = c.nodal_values().col(2 * from);
    dofs.col(2 * i + 1) = -c.nodal_values().col(2 * from + 1);
  }
  return HermiteCurve(3, knots, dofs, false);
}

HermiteCurve WithEnd(const HermiteCurve& c, int side, const Eigen::Vector3d& point) {
  Eigen::MatrixXd dofs = c.nodal_values();
  dofs.col(side == 0 ? 0 : 2 * (c.num_nodes() - 1)) = point;
  return HermiteCurve(3, c.knots(), dofs, false);
}

Eigen::Vector3d At(const HermiteCurve& c, double u, int derivative) {
  Eigen::MatrixXd jet;
  c.EvaluateJet(u, derivative, jet);
  return jet.col(derivative);
}

// The piece of c over [a, b] as a curve on [0, 1]: nodes at a, at c's knots inside (a, b) and at b, the
// derivatives scaled by b - a. Every element of c is a cubic, so the pieces are exact.
HermiteCurve Trimmed(const HermiteCurve& c, double a, double b) {
  std::vector<double> at = {a};
  for (double k : c.knots())
    if (k > a + 1e-9 && k < b - 1e-9) at.push_back(k);
  at.push_back(b);
  std::vector<double> knots;
  Eigen::MatrixXd dofs(3, 2 * static_cast<Eigen::Index>(at.size()));
  for (std::size_t i = 0; i < at.size(); ++i) {
    knots.push_back(i + 1 == at.size() ? 1.0 : (at[i] - a) / (b - a));
    dofs.col(2 * static_cast<Eigen::Index>(i)) = At(c, at[i], 0);
    dofs.col(2 * static_cast<Eigen::Index>(i) + 1) = (b - a) * At(c, at[i], 1);
  }
  return HermiteCurve(3, knots, dofs, false);
}

// Where two curves come closest (the corner between consecutive sides, each fitted curve possibly running a
// little past it or stopping short of it): the nearest pair of 201 samples on each, refined by Gauss-Newton
// on |a(u) - b(v)|^2 within [0, 1]^2.
std::pair<double, double> ClosestParameters(const HermiteCurve& a, const HermiteCurve& b) {
  constexpr int kSamples = 200;
  double best = std::numeric_limits<double>::infinity(), u = 0, v = 0;
  std::vector<Eigen::Vector3d> pb;
  for (int j = 0; j <= kSamples; ++j) pb.push_back(At(b, j / double(kSamples), 0));
  for (int i = 0; i <= kSamples; ++i) {
    const Eigen::Vector3d pa = At(a, i / double(kSamples), 0);
    for (int j = 0; j <= kSamples; ++j) {
      const double d = (pa - pb[static_cast<std::size_t>(j)]).squaredNorm();
      if (d < best) {
        best = d;
        u = i / double(kSamples);
        v = j / double(kSamples);
      }
    }
  }
  for (int it = 0; it < 30; ++it) {
    const Eigen::Vector3d r = At(a, u, 0) - At(b, v, 0);
    Eigen::Matrix<double, 3, 2> j;
    j.col(0) = At(a, u, 1);
    j.col(1) = -At(b, v, 1);
    const Eigen::Matrix2d n = j.transpose() * j;
    if (std::abs(n.determinant()) < 1e-300) break;
    const Eigen::Vector2d step = -n.ldlt().solve(j.transpose() * r);
    u = std::clamp(u + step(0), 0.0, 1.0);
    v = std::clamp(v + step(1), 0.0, 1.0);
    if (step.norm() < 1e-14) break;
  }
  return {u, v};
}

// Arc length by 5-point Gauss-Legendre quadrature on every element.
double ArcLength(const HermiteCurve& c) {
  static const double x[5] = {-0.9061798459386640, -0.5384693101056831, 0.0, 0.5384693101056831,
                              0.9061798459386640};
  static const double w[5] = {0.2369268850561891, 0.4786286704993665, 0.5688888888888889, 0.4786286704993665,
                              0.2369268850561891};
  double length = 0.0;
  for (int e = 0; e < c.num_elements(); ++e) {
    const double a = c.knots()[static_cast<std::size_t>(e)], b = c.knots()[static_cast<std::size_t>(e + 1)];
    for (int k = 0; k < 5; ++k)
      length += 0.5 * (b - a) * w[k] * At(c, 0.5 * (a + b) + 0.5 * (b - a) * x[k], 1).norm();
  }
  return length;
}

}  // namespace

bool IsCurveBoundary(const std::string& boundary) {
  if (boundary.find(',') != std::string::npos) return true;
  return boundary.size() > 5 && boundary.compare(boundary.size() - 5, 5, ".json") == 0;
}

CurvedBoundary ReadCurvedBoundary(const std::string& boundary) {
  CurvedBoundary b;
  b.files = SplitList(boundary);
  const std::size_t n = b.files.size();
  if (n < 3)
    throw FitFailure(kFitError,
                     "--boundary " + boundary + ": " + std::to_string(n) +
                         " curve(s); an n-sided patch needs 3 or more, comma-separated in their order "
                         "round the patch");
  std::vector<HermiteCurve> curves;
  for (const std::string& f : b.files) curves.push_back(ReadCurve(f));
  // Orient: curve 0 so that its end is the nearer to curve 1, every next curve so that it starts where the
  // previous one ends.
  const auto ends = [](const HermiteCurve& c) { return std::make_pair(At(c, 0, 0), At(c, 1, 0)); };
  {
    const auto [s0, e0] = ends(curves[0]);
    const auto [s1, e1] = ends(curves[1]);
    if (std::min((s0 - s1).norm(), (s0 - e1).norm()) < std::min((e0 - s1).norm(), (e0 - e1).norm()))
      curves[0] = Reversed(curves[0]);
  }
  for (std::size_t i = 1; i < n; ++i) {
    const Eigen::Vector3d previous_end = At(curves[i - 1], 1, 0);
    const auto [s, e] = ends(curves[i]);
    if ((e - previous_end).norm() < (s - previous_end).norm()) curves[i] = Reversed(curves[i]);
  }
  // Corners: where curve i and curve i + 1 come closest; each curve trimmed to the piece between its two
  // corners (a fitted open curve may run past its end points: its ends are free), and the corners' two ends
  // made to coincide at their middle.
  std::vector<double> start(n, 0.0), end(n, 1.0);
  for (std::size_t i = 0; i < n; ++i) {
    const std::size_t next = (i + 1) % n;
    const auto [u, v] = ClosestParameters(curves[i], curves[next]);
    end[i] = u;
    start[next] = v;
    b.corner_gaps.push_back((At(curves[i], u, 0) - At(curves[next], v, 0)).norm());
  }
  for (std::size_t i = 0; i < n; ++i) {
    if (!(end[i] - start[i] > 0.05))
      throw FitFailure(kFitError, "--boundary: the curve " + b.files[i] +
                                      " meets its neighbours at parameters " + Format(start[i], 3) + " and " +
                                      Format(end[i], 3) +
                                      ": not one side between two corners (list the curves in their order "
                                      "round the patch)");
    curves[i] = Trimmed(curves[i], start[i], end[i]);
  }
  // A side runs one way: a curve whose tangent turns back between neighbouring samples folds over itself
  // (a fit whose free ends ran past the data and back); its corners and length would mean nothing.
  for (std::size_t i = 0; i < n; ++i)
    if (const std::optional<double> fold = curves[i].FirstFold()) {
      const Eigen::Vector3d p = At(curves[i], *fold, 0);
      throw FitFailure(kFitError, "--boundary: the curve " + b.files[i] + " folds back on itself near (" +
                                      Format(p.x(), 4) + ", " + Format(p.y(), 4) + ", " + Format(p.z(), 4) +
                                      "): it is not one side of a patch (refit it)");
    }
  for (const HermiteCurve& c : curves) b.lengths.push_back(ArcLength(c));
  for (std::size_t i = 0; i < n; ++i) {
    const std::size_t next = (i + 1) % n;
    const double gap = b.corner_gaps[i];
    const double allowed = 0.05 * std::min(b.lengths[i], b.lengths[next]);
    if (gap > allowed)
      throw FitFailure(kFitError, "--boundary: the curves " + b.files[i] + " and " + b.files[next] +
                                      " do not meet: they come no closer than " + Format(gap, 4) +
                                      " (more than 5 % of the shorter one's length, " + Format(allowed, 4) +
                                      "); list the curves in their order round the patch");
    const Eigen::Vector3d corner = 0.5 * (At(curves[i], 1, 0) + At(curves[next], 0, 0));
    curves[i] = WithEnd(curves[i], 1, corner);
    curves[next] = WithEnd(curves[next], 0, corner);
  }
  // The loop's best plane (principal axes of points along the curves), its normal making the loop turn
  // counter-clockwise.
  std::vector<Eigen::Vector3d> samples;
  for (const HermiteCurve& c : curves)
    for (int k = 0; k < 50; ++k) samples.push_back(At(c, k / 50.0, 0));
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  for (const auto& p : samples) mean += p;
  mean /= static_cast<double>(samples.size());
  Eigen::Matrix3d scatter = Eigen::Matrix3d::Zero();
  for (const auto& p : samples) scatter += (p - mean) * (p - mean).transpose();
  b.normal = Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(scatter).eigenvectors().col(0);
  const auto turn = [&](std::size_t i) {
    const Eigen::Vector3d out = At(curves[i], 1, 1), in = At(curves[(i + 1) % n], 0, 1);
    const Eigen::Vector3d a = out - b.normal * b.normal.dot(out), c = in - b.normal * b.normal.dot(in);
    return std::atan2(b.normal.dot(a.cross(c)), a.dot(c));
  };
  double sum = 0.0;
  for (std::size_t i = 0; i < n; ++i) {
    b.turns.push_back(turn(i));
    sum += b.turns.back();
  }
  if (sum < 0) {
    b.normal = -b.normal;
    for (double& t : b.turns) t = -t;
    sum = -sum;
  }
  if (std::abs(sum - 2.0 * M_PI) > M_PI)
    throw FitFailure(kFitError, "--boundary: the curves' turns sum to " + Format(sum * 180.0 / M_PI, 4) +
                                    " degrees, not one turn (360): they do not bound one patch");
  try {
    b.closure = ClosePolygon(b.lengths, b.turns);
  } catch (const std::invalid_argument& e) {
    throw FitFailure(kFitError, std::string("--boundary: ") + e.what());
  }
  if (!b.closure.converged)
    throw FitFailure(kFitError, "--boundary: the domain polygon did not close (error " +
                                    Format(b.closure.closure_error, 3) + " of its perimeter)");
  b.sides = std::move(curves);
  // The polygon: every corner, then the side's curve nodes in proportion to their parameters.
  std::vector<Eigen::Vector2d> outer;
  for (std::size_t i = 0; i < n; ++i) {
    const Eigen::Vector2d a = b.closure.vertices.col(static_cast<Eigen::Index>(i)),
                          c = b.closure.vertices.col(static_cast<Eigen::Index>((i + 1) % n));
    outer.push_back(a);
    const std::vector<double>& knots = b.sides[i].knots();
    for (std::size_t k = 1; k + 1 < knots.size(); ++k) outer.push_back(a + knots[k] * (c - a));
  }
  b.polygon.outer.resize(2, static_cast<Eigen::Index>(outer.size()));
  for (std::size_t i = 0; i < outer.size(); ++i) b.polygon.outer.col(static_cast<Eigen::Index>(i)) = outer[i];
  try {
    b.polygon.Validate();
  } catch (const std::invalid_argument& e) {
    throw FitFailure(kFitError,
                     std::string("--boundary: the closed domain polygon is not valid: ") + e.what());
  }
  return b;
}

FeBoundaryTrace CurvedBoundary::Trace() const {
  return [this](const Eigen::Vector2d& uv, const Eigen::Vector2d& d, Eigen::Vector3d& point,
                Eigen::Vector3d& slope) {
    const std::size_t n = sides.size();
    const double tolerance = 1e-9 * std::accumulate(lengths.begin(), lengths.end(), 0.0);
    for (std::size_t i = 0; i < n; ++i) {
      const Eigen::Vector2d a = closure.vertices.col(static_cast<Eigen::Index>(i)),
                            c = closure.vertices.col(static_cast<Eigen::Index>((i + 1) % n));
      const double length = (c - a).norm();
      const Eigen::Vector2d t = (c - a) / length;
      const Eigen::Vector2d r = uv - a;
      const double along = r.dot(t);
      if (std::abs(r.x() * t.y() - r.y() * t.x()) > tolerance || along < -tolerance ||
          along > length + tolerance || std::abs(d.x() * t.y() - d.y() * t.x()) > 1e-6)
        continue;
      Eigen::MatrixXd jet;
      sides[i].EvaluateJet(std::clamp(along / length, 0.0, 1.0), 1, jet);
      point = jet.col(0);
      slope = jet.col(1) / length * d.dot(t);
      return;
    }
    throw std::invalid_argument("boundary curves: the domain point (" + std::to_string(uv.x()) + ", " +
                                std::to_string(uv.y()) + ") is on no side of the polygon");
  };
}

nlohmann::json CurvedBoundary::ToJson() const {
  nlohmann::json curves = nlohmann::json::array();
  for (std::size_t i = 0; i < sides.size(); ++i)
    curves.push_back({{"file", files[i]},
                      {"arc_length", lengths[i]},
                      {"elements", sides[i].num_elements()},
                      {"turn_deg", turns[i] * 180.0 / M_PI},
                      {"closed_turn_deg", closure.turning[i] * 180.0 / M_PI},
                      {"gap_after", corner_gaps[i]}});
  return {{"curves", curves},
          {"normal", {normal.x(), normal.y(), normal.z()}},
          {"closure",
           {{"error", closure.closure_error},
            {"angle_sum_error", closure.angle_sum_error},
            {"multiplier_updates", closure.outer_iterations}}}};
}

}  // namespace s2m::pipeline
