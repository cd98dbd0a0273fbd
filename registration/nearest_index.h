#pragma once
// A static k-d tree over 3D points (2D data use z = 0) for nearest-sample queries: seeds foot-point searches
// (docs/method.md section 10). Built once per iteration over samples of the current model.

#include <Eigen/Core>
#include <vector>

namespace s2m {

class NearestIndex {
 public:
  NearestIndex() = default;
  explicit NearestIndex(Eigen::Matrix3Xd points);
  // Index of the nearest point to q (the tree must not be empty).
  Eigen::Index Nearest(const Eigen::Vector3d& q) const;
  // Indices of the k nearest points to q, nearest first (fewer when the tree holds fewer points).
  std::vector<Eigen::Index> KNearest(const Eigen::Vector3d& q, int k) const;
  const Eigen::Matrix3Xd& points() const { return points_; }
  Eigen::Index size() const { return points_.cols(); }

 private:
  struct Node {
    int begin, end;  // range in order_
    int axis = -1;   // -1 for a leaf
    double split = 0;
    int left = -1, right = -1;
  };
  int Build(int begin, int end);
  void Search(int node, const Eigen::Vector3d& q, Eigen::Index& best, double& best_d2) const;
  void SearchK(int node, const Eigen::Vector3d& q, std::size_t k,
               std::vector<std::pair<double, Eigen::Index>>& heap) const;

  Eigen::Matrix3Xd points_;
  std::vector<Eigen::Index> order_;
  std::vector<Node> nodes_;
};

}  // namespace s2m
