#pragma once
// Glyph outlines from UFO .glif files (Unified Font Object, glyph format 2): real 2D contours for curve
// fitting.

#include <Eigen/Core>
#include <filesystem>
#include <vector>

namespace s2m {

// Each closed contour sampled along its segments (lines, cubic and quadratic Beziers), `samples_per_segment`
// points per segment, segment ends included once. Throws FormatError for malformed files or files without
// contours.
std::vector<Eigen::Matrix2Xd> ReadGlifContours(const std::filesystem::path& path,
                                               int samples_per_segment = 20);

}  // namespace s2m
