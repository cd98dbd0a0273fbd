#include "registration/nearest_index.h"

#include <algorithm>
#include <limits>
#include <numeric>

namespace s2m {

namespace {
constexpr int kLeafSize = 8;
}

NearestIndex::NearestIndex(Eigen::Matrix3Xd points) : points_(std::move(points)) {
  order_.resize(static_cast<std::size_t>(points_.cols()));
  std::iota(order_.begin(), order_.end(), Eigen::Index{0});
  if (!order_.empty()) Build(0, static_cast<int>(order_.size()));
}

int NearestIndex::Build(int begin, int end) {
  const int id = static_cast<int>(nodes_.size());
  nodes_.push_back({begin, end});
  if (end - begin <= kLeafSize) return id;
  Eigen::Vector3d lo = Eigen::Vector3d::Constant(std::numeric_limits<double>::infinity()), hi = -lo;
  for (int i = begin; i < end; ++i) {
    lo = lo.cwiseMin(points_.col(order_[static_cast<std::size_t>(i)]));
    hi = hi.cwiseMax(points_.col(order_[static_cast<std::size_t>(i)]));
  }
  int axis;
  (hi - lo).maxCoeff(&axis);
  const int mid = (begin + end) / 2;
  std::nth_element(order_.begin() + begin, order_.begin() + mid, order_.begin() + end,
                   [&](Eigen::Index a, Eigen::Index b) { return points_(axis, a) < points_(axis, b); });
  const double split = points_(axis, order_[static_cast<std::size_t>(mid)]);
  const int left = Build(begin, mid);
  const int right = Build(mid, end);
  Node& node = nodes_[static_cast<std::size_t>(id)];
  node.axis = axis;
  node.split = split;
  node.left = left;
  node.right = right;
  return id;
}

void NearestIndex::Search(int id, const Eigen::Vector3d& q, Eigen::Index& best, double& best_d2) const {
  const Node& node = nodes_[static_cast<std::size_t>(id)];
  if (node.axis < 0) {
    for (int i = node.begin; i < node.end; ++i) {
      const Eigen::Index p = order_[static_cast<std::size_t>(i)];
      const double d2 = (points_.col(p) - q).squaredNorm();
      if (d2 < best_d2) {
        best_d2 = d2;
        best = p;
      }
    }
    return;
  }
  const double diff = q[node.axis] - node.split;
  const int near = diff < 0 ? node.left : node.right;
  const int far = diff < 0 ? node.right : node.left;
  Search(near, q, best, best_d2);
  if (diff * diff < best_d2) Search(far, q, best, best_d2);
}

void NearestIndex::SearchK(int id, const Eigen::Vector3d& q, std::size_t k,
                           std::vector<std::pair<double, Eigen::Index>>& heap) const {
  const Node& node = nodes_[static_cast<std::size_t>(id)];
  if (node.axis < 0) {
    for (int i = node.begin; i < node.end; ++i) {
      const Eigen::Index p = order_[static_cast<std::size_t>(i)];
      const double d2 = (points_.col(p) - q).squaredNorm();
      if (heap.size() < k) {
        heap.emplace_back(d2, p);
        std::push_heap(heap.begin(), heap.end());
      } else if (d2 < heap.front().first) {
        std::pop_heap(heap.begin(), heap.end());
        heap.back() = {d2, p};
        std::push_heap(heap.begin(), heap.end());
      }
    }
    return;
  }
  const double diff = q[node.axis] - node.split;
  SearchK(diff < 0 ? node.left : node.right, q, k, heap);
  if (heap.size() < k || diff * diff < heap.front().first)
    SearchK(diff < 0 ? node.right : node.left, q, k, heap);
}

std::vector<Eigen::Index> NearestIndex::KNearest(const Eigen::Vector3d& q, int k) const {
  std::vector<std::pair<double, Eigen::Index>> heap;  // max-heap on distance
  if (k > 0 && !nodes_.empty()) SearchK(0, q, static_cast<std::size_t>(k), heap);
  std::sort_heap(heap.begin(), heap.end());
  std::vector<Eigen::Index> out;
  for (const auto& h : heap) out.push_back(h.second);
  return out;
}

Eigen::Index NearestIndex::Nearest(const Eigen::Vector3d& q) const {
  Eigen::Index best = 0;
  double best_d2 = std::numeric_limits<double>::infinity();
  Search(0, q, best, best_d2);
  return best;
}

}  // namespace s2m
