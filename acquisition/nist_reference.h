#pragma once
// NIST reference fits (.fit files of the NIST Algorithm Testing System / ASME B89.4.10 data sets), converted
// into scan2model's primitive types. Layouts: plane = point, unit normal; sphere = centre, DIAMETER; cylinder
// = point on axis, axis direction, DIAMETER; cone = point on axis, axis direction (towards increasing
// radius), orthogonal distance from that point to the surface, full apex angle in degrees.

#include <filesystem>
#include <vector>

#include "fitting/primitives.h"

namespace s2m {

// All numbers of a .fit file; throws FormatError when the count differs from `expected` or a value is not
// finite.
std::vector<double> ReadNistFitValues(const std::filesystem::path& path, std::size_t expected);

Plane ReadNistPlaneFit(const std::filesystem::path& path);
Sphere ReadNistSphereFit(const std::filesystem::path& path);
Cylinder ReadNistCylinderFit(const std::filesystem::path& path);
Cone ReadNistConeFit(const std::filesystem::path& path);

// Our shapes in the NIST layouts above (the numbers a NIST comparison expects).
std::vector<double> ToNistLayout(const Plane& s);
std::vector<double> ToNistLayout(const Sphere& s);
std::vector<double> ToNistLayout(const Cylinder& s);
std::vector<double> ToNistLayout(const Cone& s);
// The ISO 10360-6 features without NIST files, in the same spirit (docs/metrology.md): line = point, unit
// direction; circle = centre, unit normal, DIAMETER; torus = centre, unit axis, major DIAMETER (of the tube's
// centre circle), minor DIAMETER (of the tube).
std::vector<double> ToNistLayout(const Line3d& s);
std::vector<double> ToNistLayout(const Circle3d& s);
std::vector<double> ToNistLayout(const Torus& s);

}  // namespace s2m
