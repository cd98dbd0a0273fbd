#include "registration/nearest_index.h"

#include <algorithm>
#include <limits>

namespace s2m {

namespace {
constexpr int kLeafSize = 8;
}

NearestIndex::NearestIndex(Eigen::Matrix3Xd points) : points_(std::move(points)) {
  if (points_.cols() == 0) return;
  entries_.resize(static_cast<std::size_t>(points_.cols()));
  for (Eigen::Index i = 0; i < points_.cols(); ++i)
    entries_[static_cast<std::size_t>(i)] = {points_.col(i), i};
  nodes_.reserve(2 * entries_.size() / kLeafSize + 1);
  lower_ = points_.rowwise().minCoeff();
  upper_ = points_.rowwise().maxCoeff();
  Build(0, static_cast<int>(entries_.size()), lower_, upper_);
}

// Splits the longest side of the cell at its middle, slid to the points' range along it (the sliding-midpoint
// rule of Maneewongvatana & Mount, "Analysis of approximate nearest neighbor searching with clustered point
// sets", 1999; nanoflann's default): one pass for the range and one partition instead of a median selection.
// When the middle leaves one side empty, the median. The cell is the parent's cut at the split (not the
// children's tight boxes): no extra pass over the points.
int NearestIndex::Build(int begin, int end, Eigen::Vector3d lo, Eigen::Vector3d hi) {
  const int id = static_cast<int>(nodes_.size());
  nodes_.push_back({begin, end});
  if (end - begin <= kLeafSize) return id;
  int axis;
  (hi - lo).maxCoeff(&axis);
  const auto first = entries_.begin() + begin, last = entries_.begin() + end;
  double low = std::numeric_limits<double>::infinity(), high = -low;
  for (auto it = first; it != last; ++it) {
    low = std::min(low, it->point[axis]);
    high = std::max(high, it->point[axis]);
  }
  double split = std::clamp(0.5 * (lo[axis] + hi[axis]), low, high);
  int mid = static_cast<int>(
      std::partition(first, last, [axis, split](const Entry& e) { return e.point[axis] < split; }) -
      entries_.begin());
  if (mid == begin || mid == end) {
    mid = (begin + end) / 2;
    std::nth_element(first, entries_.begin() + mid, last,
                     [axis](const Entry& a, const Entry& b) { return a.point[axis] < b.point[axis]; });
    split = entries_[static_cast<std::size_t>(mid)].point[axis];
  }
  Eigen::Vector3d left_hi = hi, right_lo = lo;
  left_hi[axis] = split;
  right_lo[axis] = split;
  const int left = Build(begin, mid, lo, left_hi);
  const int right = Build(mid, end, right_lo, hi);
  Node& node = nodes_[static_cast<std::size_t>(id)];
  node.axis = axis;
  node.split = split;
  node.left = left;
  node.right = right;
  return id;
}

NearestIndex::CellDistance NearestIndex::RootDistance(const Eigen::Vector3d& q) const {
  CellDistance cell;
  cell.offset = (lower_ - q).cwiseMax(q - upper_).cwiseMax(0.0);
  cell.squared = cell.offset.squaredNorm();
  return cell;
}

// Every point of the left child has coordinate <= split on the axis and every point of the right child >=
// split, so the far child's region lies beyond the splitting plane: its distance along the axis is |q -
// split|, which replaces the parent's (smaller) offset on that axis in the sum of squares.
void NearestIndex::Search(int id, const Eigen::Vector3d& q, CellDistance cell, Eigen::Index& best,
                          double& best_d2) const {
  const Node& node = nodes_[static_cast<std::size_t>(id)];
  if (node.axis < 0) {
    for (int i = node.begin; i < node.end; ++i) {
      const Entry& e = entries_[static_cast<std::size_t>(i)];
      const double d2 = (e.point - q).squaredNorm();
      // Among equally near points the lowest index: the answer does not depend on the tree's shape.
      if (d2 < best_d2 || (d2 == best_d2 && e.index < best)) {
        best_d2 = d2;
        best = e.index;
      }
    }
    return;
  }
  const double diff = q[node.axis] - node.split;
  Search(diff < 0 ? node.left : node.right, q, cell, best, best_d2);
  const double old_offset = cell.offset[node.axis];
  cell.squared += diff * diff - old_offset * old_offset;
  cell.offset[node.axis] = std::abs(diff);
  if (cell.squared <= best_d2) Search(diff < 0 ? node.right : node.left, q, cell, best, best_d2);
}

void NearestIndex::SearchK(int id, const Eigen::Vector3d& q, CellDistance cell, std::size_t k,
                           std::vector<std::pair<double, Eigen::Index>>& heap) const {
  const Node& node = nodes_[static_cast<std::size_t>(id)];
  if (node.axis < 0) {
    for (int i = node.begin; i < node.end; ++i) {
      const Entry& e = entries_[static_cast<std::size_t>(i)];
      const double d2 = (e.point - q).squaredNorm();
      const Eigen::Index p = e.index;
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
  SearchK(diff < 0 ? node.left : node.right, q, cell, k, heap);
  const double old_offset = cell.offset[node.axis];
  cell.squared += diff * diff - old_offset * old_offset;
  cell.offset[node.axis] = std::abs(diff);
  if (heap.size() < k || cell.squared < heap.front().first)
    SearchK(diff < 0 ? node.right : node.left, q, cell, k, heap);
}

std::vector<Eigen::Index> NearestIndex::KNearest(const Eigen::Vector3d& q, int k) const {
  std::vector<std::pair<double, Eigen::Index>> heap;  // max-heap on distance
  if (k > 0 && !nodes_.empty()) {
    heap.reserve(static_cast<std::size_t>(k));
    SearchK(0, q, RootDistance(q), static_cast<std::size_t>(k), heap);
  }
  std::sort_heap(heap.begin(), heap.end());
  std::vector<Eigen::Index> out;
  out.reserve(heap.size());
  for (const auto& h : heap) out.push_back(h.second);
  return out;
}

bool NearestIndex::NearestWithin(const Eigen::Vector3d& q, Eigen::Index& best, double& best_d2) const {
  if (nodes_.empty()) return false;
  const CellDistance root = RootDistance(q);
  if (!(root.squared < best_d2)) return false;
  // A private search state: a tie with the caller's best at exactly the bound is not an answer.
  Eigen::Index found = std::numeric_limits<Eigen::Index>::max();
  double found_d2 = best_d2;
  Search(0, q, root, found, found_d2);
  if (!(found_d2 < best_d2)) return false;
  best = found;
  best_d2 = found_d2;
  return true;
}

Eigen::Index NearestIndex::Nearest(const Eigen::Vector3d& q) const {
  Eigen::Index best = 0;
  double best_d2 = std::numeric_limits<double>::infinity();
  NearestWithin(q, best, best_d2);
  return best;
}

}  // namespace s2m
