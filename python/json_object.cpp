#include "python/json_object.h"

#include <cmath>
#include <string>

namespace s2m::python {

py::object ToPython(const nlohmann::json& j) {
  switch (j.type()) {
    case nlohmann::json::value_t::object: {
      py::dict d;
      for (const auto& [key, value] : j.items()) d[py::str(key)] = ToPython(value);
      return d;
    }
    case nlohmann::json::value_t::array: {
      py::list l(j.size());
      for (std::size_t k = 0; k < j.size(); ++k) l[k] = ToPython(j[k]);
      return l;
    }
    case nlohmann::json::value_t::string:
      return py::str(j.get_ref<const std::string&>());
    case nlohmann::json::value_t::boolean:
      return py::bool_(j.get<bool>());
    case nlohmann::json::value_t::number_integer:
      return py::int_(j.get<std::int64_t>());
    case nlohmann::json::value_t::number_unsigned:
      return py::int_(j.get<std::uint64_t>());
    case nlohmann::json::value_t::number_float: {
      const double v = j.get<double>();
      return std::isfinite(v) ? py::object(py::float_(v)) : py::object(py::none());
    }
    default:
      return py::none();
  }
}

nlohmann::json FromPython(py::handle object, const std::string& path) {
  if (object.is_none()) return nullptr;
  if (py::isinstance<py::bool_>(object)) return object.cast<bool>();
  if (py::isinstance<py::int_>(object)) return object.cast<std::int64_t>();
  if (py::isinstance<py::float_>(object)) return object.cast<double>();
  if (py::isinstance<py::str>(object)) return object.cast<std::string>();
  if (py::isinstance<py::dict>(object)) {
    nlohmann::json j = nlohmann::json::object();
    for (const auto& [key, value] : py::reinterpret_borrow<py::dict>(object)) {
      if (!py::isinstance<py::str>(key)) throw py::type_error(path + ": a key that is not a string");
      const std::string k = key.cast<std::string>();
      j[k] = FromPython(value, path + "." + k);
    }
    return j;
  }
  if (py::isinstance<py::list>(object) || py::isinstance<py::tuple>(object)) {
    nlohmann::json j = nlohmann::json::array();
    std::size_t k = 0;
    for (const py::handle item : object)
      j.push_back(FromPython(item, path + "[" + std::to_string(k++) + "]"));
    return j;
  }
  // NumPy scalars and arrays (e.g. a parameter a caller edited) through their Python equivalents.
  if (py::hasattr(object, "tolist")) return FromPython(object.attr("tolist")(), path);
  throw py::type_error(path + ": " + std::string(py::str(py::type::handle_of(object).attr("__name__"))) +
                       " is not a JSON value");
}

}  // namespace s2m::python
