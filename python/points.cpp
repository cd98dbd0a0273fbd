#include "python/points.h"

#include <string>

namespace s2m::python {
namespace {

py::handle conversion_warning = PyExc_UserWarning;

std::string ShapeText(const py::array& a) {
  std::string text = "(";
  for (py::ssize_t k = 0; k < a.ndim(); ++k) text += (k ? ", " : "") + std::to_string(a.shape(k));
  return text + (a.ndim() == 1 ? ",)" : ")");
}

void CheckShape(const py::array& a, const char* what) {
  if (a.ndim() != 2 || a.shape(1) != 3) {
    throw py::value_error(std::string(what) +
                          ": expected an N x 3 array of x, y, z (one point per row), got shape " +
                          ShapeText(a));
  }
}

}  // namespace

void SetConversionWarning(py::handle category) {
  conversion_warning = category;
}

PointsArg::PointsArg(py::handle object, const char* what) {
  if (py::isinstance<Scan>(object)) {
    array_ = MatrixView(object.cast<Scan&>().points, object);
    return;
  }
  std::string note;
  if (py::isinstance<py::array>(object)) {
    const auto a = py::reinterpret_borrow<py::array>(object);
    CheckShape(a, what);
    const bool float64 = a.dtype().is(py::dtype::of<double>());
    const bool c_contiguous = (a.flags() & py::array::c_style) != 0;
    if (float64 && c_contiguous) {
      array_ = py::reinterpret_borrow<py::array_t<double>>(object);
      return;
    }
    note = std::string(what) + ": " +
           (float64 ? "a float64" : "a " + std::string(py::str(a.dtype())) + " array") +
           (float64 ? " array that is not C-contiguous" : "") +
           " was converted to a float64 copy (an N x 3 float64 C-contiguous array is read in place; "
           "np.ascontiguousarray(points, dtype=np.float64) converts once)";
  }
  auto converted = py::array_t<double, py::array::c_style | py::array::forcecast>::ensure(object);
  if (!converted) {
    throw py::value_error(std::string(what) +
                          ": expected an N x 3 array of x, y, z (a NumPy array, a Scan or a "
                          "sequence of 3-sequences), got " +
                          std::string(py::str(py::type::handle_of(object).attr("__name__"))));
  }
  CheckShape(converted, what);
  if (!note.empty() && PyErr_WarnEx(conversion_warning.ptr(), note.c_str(), 2) != 0)
    throw py::error_already_set();
  array_ = std::move(converted);
}

Eigen::Map<const Eigen::Matrix3Xd> PointsArg::map() const {
  return {array_.data(), 3, array_.shape(0)};
}

py::array_t<double> MatrixView(Eigen::Matrix3Xd& m, py::handle owner) {
  if (m.cols() == 0) return py::array_t<double>(std::vector<py::ssize_t>{0, 3});
  return py::array_t<double>(
      {static_cast<py::ssize_t>(m.cols()), py::ssize_t{3}},
      {static_cast<py::ssize_t>(3 * sizeof(double)), static_cast<py::ssize_t>(sizeof(double))}, m.data(),
      owner);
}

py::array_t<double> MatrixArray(Eigen::Matrix3Xd&& m) {
  auto* owned = new Eigen::Matrix3Xd(std::move(m));
  py::capsule owner(owned, [](void* p) { delete static_cast<Eigen::Matrix3Xd*>(p); });
  return MatrixView(*owned, owner);
}

Eigen::Matrix3Xd CopyPoints(py::handle object, const char* what) {
  const PointsArg points(object, what);
  return points.map();
}

}  // namespace s2m::python
