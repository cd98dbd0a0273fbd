#pragma once
// A precomputed approximation of the squared distance function d^2 to a fixed model, for fast registration of
// scans to it (Mitra, Gelfand, Pottmann, Guibas, "Registration of point cloud data from a geometric
// optimization perspective", SGP 2004: the "d2tree", whose cells store local quadratic approximants of d^2).
// Here a uniform grid of cubic cells over a box, stored sparsely: only cells whose centre lies within `band`
// of the model. Each stored cell keeps the exact foot point of its centre with the model's second-order
// geometry there: point p, unit normal n, principal directions e1, e2 and principal curvatures k1, k2
// (Pottmann & Hofer, "Geometry of the squared distance function to curves and surfaces", 2003). A query y is
// answered in O(1): the cell containing y, then the foot of y on the osculating paraboloid z = (k1 u^2 + k2
// v^2) / 2 of the model at p (frame e1, e2, n), whose normal, tangents and the cell's curvatures give the SDM
// second-order approximant of d^2 at y (docs/method.md section 2):
//   F(x) = beta1 ((x - q).T1)^2 + beta2 ((x - q).T2)^2 + ((x - q).N)^2,  beta_k = SdmWeight(delta, k_k),
// i.e. Pottmann & Hofer's d/(d - rho_k) weights clamped at 0 (positive semidefinite), at the approximate foot
// q. Using the paraboloid's foot rather than the Taylor approximant at the cell centre makes the distance
// error third order in the distance from p to y's foot (the model's third derivatives), not second.
//
// Accuracy (measured by tests/squared_distance_field_test.cpp, points within 5 mm of the model): on the
// benchmark's bumpy B-spline patch (curvature radii >= about 20 mm) the distance error is at most 2.1e-4 mm
// with cells of 1 mm and 1.6e-3 mm with cells of 2 mm (third order in the cell size); on a cylinder of radius
// 20 mm (no third-order terms) 5.8e-6 mm with cells of 1 mm. Cells that cannot be trusted answer "no" and the
// caller uses exact foot points: cells outside the band, cells whose centre's foot lies on or near an open
// boundary of the model (within 2 cells), and cells near a focal point (|k| (|d| + h) >= 0.5, where the
// distance function stops being smooth). Points near the medial axis of a strongly curved model (two distant
// feet at about the same distance) are not detected: keep `band` below the model's curvature radii.
//
// Built whole (the default), the field costs one exact foot per cell of the band around the entire model,
// most of which a registration never visits: a scan near its pose touches a layer one or two cells thick over
// the part of the model it covers. Built lazily (Options::lazy), the constructor only lays out the grid and
// Prepare(points) computes the cells the given points fall in, once each, by the same code: a
// registration calls it with the scan's points at every pose it evaluates, so the field holds exactly the
// cells the scans have visited and later scans of the same model reuse them. Queries are identical.

#include <Eigen/Core>
#include <array>
#include <cstdint>
#include <memory>
#include <vector>

#include "fitting/foot_point.h"
#include "fitting/parametric_model.h"

namespace s2m {

class SquaredDistanceField {
 public:
  struct Options {
    double cell_size = 1.0;  // edge of the cubic cells, model units (the accuracy above scales with it)
    double band = 6.0;  // cells whose centre lies within band + half a cell diagonal of the model are kept
    // The region covered. Empty (min > max, the default): the bounding box of the model's seed samples
    // (ParametricModel::SampleParameters) grown by `band`; give it for unbounded models (cylinders).
    Eigen::Vector3d box_min = Eigen::Vector3d::Constant(1.0), box_max = Eigen::Vector3d::Constant(-1.0);
    double max_grid_cells = 2e8;  // the dense cell index's size limit (4 bytes per grid cell)
    // Compute cells on demand (Prepare) instead of all at once. The model must then outlive the field.
    bool lazy = false;
  };

  // The SDM approximant of d^2 at one query point, in the form the error terms use: the approximate foot q,
  // its principal frame oriented towards the query (delta >= 0), the approximate squared distance |y - q|^2,
  // and a parameter near the exact foot (a warm start for exact Newton: the approximate foot's parameter to
  // second order in the parametrization, its model point within about 1e-3 mm of the exact foot on the
  // benchmark's patch with cells of 1 mm for points within 3 mm).
  struct Answer {
    Eigen::Vector3d foot;
    PrincipalFrame frame;
    double squared_distance = 0.0;
    ParamT t{0.0, 0.0, 0.0};
  };

  // Builds the field of `model` (a surface in 3D): the exact foot points of all cell centres near the model,
  // in parallel; with options.lazy only the grid (cells come with Prepare). Throws std::invalid_argument for
  // other models or a grid beyond max_grid_cells.
  SquaredDistanceField(const ParametricModel& model, const Options& options);

  // Lazy fields: computes (in parallel) every not yet computed block of cells that holds one of `points`
  // (3 x n), so that Query answers for them. Does nothing for a field built whole. Not to be called while
  // another thread queries the field.
  void Prepare(const Eigen::Matrix3Xd& points);

  // False when y is outside the box, its cell is not stored or cannot be trusted: use an exact foot point.
  // Without `tangents` only the normal of out.frame is set (enough for TDM).
  bool Query(const Eigen::Vector3d& y, Answer& out, bool tangents = true) const;

  const Options& options() const { return options_; }
  std::size_t cell_count() const { return cells_.size(); }         // stored (trusted) cells
  std::size_t untrusted_cell_count() const { return untrusted_; }  // in the band but left to exact feet
  // Wall time of the constructor and every Prepare so far.
  double build_seconds() const { return build_seconds_; }

 private:
  struct Cell {
    Eigen::Vector3d p, e1, e2, n;  // foot of the centre and the principal frame there
    double k1 = 0.0, k2 = 0.0;     // principal curvatures w.r.t. n
    Eigen::Matrix<double, 2, 3> t_of_x =
        Eigen::Matrix<double, 2,
                      3>::Zero();  // A = (C_t^T C_t)^-1 C_t^T: parameter change per model-point change
    // A C_uu, A C_uv, A C_vv: the parametrization's second-order term, so that the parameter of a point q
    // near p is s - (A C_tt[s, s]) / 2 with s = A (q - p), exact to third order in |q - p| (a near-exact warm
    // start for Newton on the model).
    Eigen::Matrix<double, 2, 3> t_second = Eigen::Matrix<double, 2, 3>::Zero();
    ParamT t{0.0, 0.0, 0.0};
  };
  // Computes the cells of the given blocks (indices into the grid of blocks), in parallel, and stores them.
  void BuildBlocks(const std::vector<std::int64_t>& blocks);

  Options options_;
  const ParametricModel& model_;
  std::unique_ptr<FootPointContext> context_;  // seeds for the exact feet, kept by lazy fields only
  ParameterDomain domain_;
  Eigen::Vector3d origin_;
  double inverse_cell_ = 1.0;
  std::array<std::int64_t, 3> dims_{0, 0, 0};
  std::vector<std::int32_t> index_;              // dense over the grid: -1 or the cell's index in cells_
  int block_edge_ = 1;                           // cells per block edge
  std::array<std::int64_t, 3> blocks_{0, 0, 0};  // blocks of block_edge_^3 cells along each axis
  std::vector<std::uint8_t> block_built_;        // 1 once a block's cells are computed
  std::vector<Cell> cells_;
  std::size_t untrusted_ = 0;
  double build_seconds_ = 0.0;
};

}  // namespace s2m
