#pragma once
// A static k-d tree over 3D points (2D data use z = 0) for nearest-sample queries: seeds foot-point searches
// (docs/method.md section 10) and pairs the views of a scan-to-scan registration. Built once over a point
// set.
//
// Queries prune by the exact squared distance from the query to each cell's region, kept incrementally as the
// search descends (Arya & Mount, "Algorithms for fast vector quantization", DCC 1993; the scheme nanoflann
// uses): a query far outside the cloud, or one bounded by a distance already known, visits a handful of cells
// instead of every cell whose splitting plane is nearer than the current best.

#include <Eigen/Core>
#include <vector>

namespace s2m {

class NearestIndex {
 public:
  NearestIndex() = default;
  explicit NearestIndex(Eigen::Matrix3Xd points);
  // Index of the nearest point to q, the lowest index among equally near points (the tree must not be
  // empty).
  Eigen::Index Nearest(const Eigen::Vector3d& q) const;
  // The nearest point to q closer than sqrt(best_d2): returns true and sets `best` and `best_d2` to it, or
  // returns false and leaves both unchanged. Pass a previous answer's squared distance to bound the search
  // (a warm start), or the best over other trees to find the nearest over several.
  bool NearestWithin(const Eigen::Vector3d& q, Eigen::Index& best, double& best_d2) const;
  // Indices of the k nearest points to q, nearest first (fewer when the tree holds fewer points).
  std::vector<Eigen::Index> KNearest(const Eigen::Vector3d& q, int k) const;
  const Eigen::Matrix3Xd& points() const { return points_; }
  Eigen::Index size() const { return points_.cols(); }

 private:
  struct Node {
    int begin, end;  // range in entries_
    int axis = -1;   // -1 for a leaf
    double split = 0;
    int left = -1, right = -1;
  };
  // Per-axis distances from the query to the current cell (zero where the query lies within the cell's slab)
  // and their sum of squares.
  struct CellDistance {
    Eigen::Vector3d offset;
    double squared = 0;
  };
  int Build(int begin, int end, Eigen::Vector3d lo, Eigen::Vector3d hi);
  CellDistance RootDistance(const Eigen::Vector3d& q) const;
  void Search(int node, const Eigen::Vector3d& q, CellDistance cell, Eigen::Index& best,
              double& best_d2) const;
  void SearchK(int node, const Eigen::Vector3d& q, CellDistance cell, std::size_t k,
               std::vector<std::pair<double, Eigen::Index>>& heap) const;

  // The points in tree order with their original indices: a cell's points are contiguous, so building
  // (nth_element) and scanning leaves read memory in sequence.
  struct Entry {
    Eigen::Vector3d point;
    Eigen::Index index;
  };
  Eigen::Matrix3Xd points_;
  Eigen::Vector3d lower_ = Eigen::Vector3d::Zero(), upper_ = Eigen::Vector3d::Zero();  // bounding box
  std::vector<Entry> entries_;
  std::vector<Node> nodes_;
};

}  // namespace s2m
