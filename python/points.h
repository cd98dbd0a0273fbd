#pragma once
// NumPy arrays of points and the core's 3 x N matrices (docs/python.md). An N x 3 float64 C-contiguous array
// holds x, y, z of each point one after the other: exactly the memory of a column-major 3 x N Eigen matrix,
// so the fits read it in place through an Eigen::Map. Other arrays (float32, integers, Fortran order,
// strided views, lists) are converted to such a copy, with a ConversionWarning saying so.

#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>

#include <Eigen/Core>
#include <memory>

#include "registration/scan.h"

namespace s2m::python {

namespace py = pybind11;

// The warning category of a converted array (scan2model.ConversionWarning), set when the module loads.
void SetConversionWarning(py::handle category);

// The points of an argument: a Scan (its points, in place), an N x 3 float64 C-contiguous array (in place)
// or anything NumPy converts to N x 3 float64 (a copy, with a ConversionWarning for arrays). Throws
// py::value_error naming `what` for another shape.
class PointsArg {
 public:
  PointsArg(py::handle object, const char* what);
  // The points as the core reads them; valid while this object lives.
  Eigen::Map<const Eigen::Matrix3Xd> map() const;
  // The array the map reads: the caller's own, or the converted copy.
  const py::array_t<double>& array() const { return array_; }

 private:
  py::array_t<double> array_;
};

// An N x 3 array over the 3 x N matrix `m`, no copy: `owner` (the Python object that owns `m`) stays alive as
// long as the array does. Writes through the array change `m`.
py::array_t<double> MatrixView(Eigen::Matrix3Xd& m, py::handle owner);
// An N x 3 array that owns `m` (moved, no copy).
py::array_t<double> MatrixArray(Eigen::Matrix3Xd&& m);
// A copy of the N x 3 points of an argument into a 3 x N matrix (for the Scan a fit document needs).
Eigen::Matrix3Xd CopyPoints(py::handle object, const char* what);

}  // namespace s2m::python
