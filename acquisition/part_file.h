#pragma once
// Part files (format "scan2model.part/1", JSON; docs/parts.md): the faces of a constrained part and the named
// parameters they share. Face quantities are numbers or linear expressions such as "height - cb_depth" or
// "bore_diameter / 2" (+, -, *, / by numbers, parentheses). Angles are written in degrees in the file and
// held in radians in the model.

#include <map>
#include <string>
#include <vector>

#include "fitting/part_model.h"

namespace s2m {

struct PartFile {
  PartDefinition definition;                    // the free parameters in the order the file lists them
  std::vector<PartParameter> fixed_parameters;  // with their values (angles in radians), for reports
  std::string units;                            // of the lengths, as the file states ("" when it does not)
  // Optional symmetric tolerances by parameter name ({"value": 60, "tolerance": 0.1}: 60 +- 0.1), in the
  // file's units (degrees for angles); docs/batch.md.
  std::map<std::string, double> tolerances;
};

// Throws FormatError naming the file, the face or parameter, and the problem.
PartFile ReadPartFile(const std::string& path);
// The same from text (`source` names it in errors).
PartFile ParsePartFile(const std::string& text, const std::string& source);

}  // namespace s2m
