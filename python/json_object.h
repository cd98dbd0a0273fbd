#pragma once
// Result documents (nlohmann::json, the schemas of docs/schemas/) as Python objects and back.

#include <pybind11/pybind11.h>

#include <nlohmann/json.hpp>

namespace s2m::python {

namespace py = pybind11;

// dict, list, str, int, float, bool or None; a number that is not finite becomes None, as in the JSON text.
py::object ToPython(const nlohmann::json& j);
// The inverse for dicts (string keys), lists, tuples, str, int, float, bool and None; throws py::type_error
// naming the path of anything else.
nlohmann::json FromPython(py::handle object, const std::string& path = "document");

}  // namespace s2m::python
