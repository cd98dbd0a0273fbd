#include "registration/scan.h"

namespace s2m {

Eigen::Index ScanSet::TotalPoints() const {
  Eigen::Index n = 0;
  for (const Scan& s : scans) n += s.size();
  return n;
}

Eigen::Matrix3Xd ScanSet::MergedWorldPoints() const {
  Eigen::Matrix3Xd merged(3, TotalPoints());
  Eigen::Index offset = 0;
  for (const Scan& s : scans) {
    merged.middleCols(offset, s.size()) = s.WorldPoints();
    offset += s.size();
  }
  return merged;
}

Bounds ComputeBounds(const Eigen::Matrix3Xd& points) {
  Bounds b;
  if (points.cols() == 0) return b;
  b.min = points.rowwise().minCoeff();
  b.max = points.rowwise().maxCoeff();
  return b;
}

}  // namespace s2m
