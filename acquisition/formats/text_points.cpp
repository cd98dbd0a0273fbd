// Plain text point lists (XYZ, CSV, PTS-like) and the NIST .ds format of the NIST Algorithm Testing System.

#include <algorithm>
#include <cctype>
#include <cmath>
#include <string>
#include <vector>

#include "acquisition/format_error.h"
#include "acquisition/formats/readers.h"
#include "acquisition/formats/text_util.h"

namespace s2m::formats {
namespace {

bool IsComment(std::string_view text) {
  const auto first = text.find_first_not_of(" \t");
  return first == std::string_view::npos || text[first] == '#' || text.substr(first, 2) == "//";
}

std::string Lower(std::string_view s) {
  std::string out(s);
  std::transform(out.begin(), out.end(), out.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return out;
}

struct Columns {
  int x = 0, y = 1, z = 2, nx = -1, ny = -1, nz = -1, weight = -1;
  std::size_t count = 0;
};

Columns ColumnsFromHeader(const std::vector<std::string_view>& names, const std::string& file,
                          std::size_t line) {
  Columns c;
  c.x = c.y = c.z = -1;
  c.count = names.size();
  for (int i = 0; i < static_cast<int>(names.size()); ++i) {
    const std::string n = Lower(names[static_cast<std::size_t>(i)]);
    if (n == "x")
      c.x = i;
    else if (n == "y")
      c.y = i;
    else if (n == "z")
      c.z = i;
    else if (n == "nx" || n == "normal_x")
      c.nx = i;
    else if (n == "ny" || n == "normal_y")
      c.ny = i;
    else if (n == "nz" || n == "normal_z")
      c.nz = i;
    else if (n == "weight" || n == "w")
      c.weight = i;
  }
  if (c.x < 0 || c.y < 0 || c.z < 0)
    throw FormatError(file, AtLine(line), "the header names no x, y and z columns");
  if (c.nx < 0 || c.ny < 0 || c.nz < 0) c.nx = c.ny = c.nz = -1;
  return c;
}

// Without a header: the first three columns are x y z; with exactly 6 or 7 columns, columns 4-6 are the
// normal.
Columns ColumnsFromCount(std::size_t count) {
  Columns c;
  c.count = count;
  if (count == 6 || count == 7) c.nx = 3, c.ny = 4, c.nz = 5;
  return c;
}

}  // namespace

Scan ParseTextPoints(const std::string& bytes, const std::string& file) {
  LineReader lines(bytes);
  Line line;
  std::vector<std::string_view> tok;
  std::optional<Columns> columns;
  std::vector<double> xyz, normals, weights;
  while (lines.Next(line)) {
    if (IsComment(line.text)) continue;
    Tokenize(line.text, tok, /*csv=*/true);
    if (tok.empty()) continue;
    double v;
    if (!columns && !ParseDouble(tok[0], v)) {  // a header line of column names
      columns = ColumnsFromHeader(tok, file, line.number);
      continue;
    }
    if (!columns) {
      if (tok.size() < 3)
        throw FormatError(file, AtLine(line.number),
                          "expected at least 3 values (x y z), found " + std::to_string(tok.size()));
      columns = ColumnsFromCount(tok.size());
    }
    if (tok.size() != columns->count) {
      throw FormatError(
          file, AtLine(line.number),
          "expected " + std::to_string(columns->count) + " values, found " + std::to_string(tok.size()));
    }
    auto number = [&](int c, const char* what) {
      double value;
      const std::string_view t = tok[static_cast<std::size_t>(c)];
      if (!ParseDouble(t, value)) throw FormatError(file, AtLine(line.number), "not a number: " + Quoted(t));
      if (!std::isfinite(value))
        throw FormatError(file, AtLine(line.number),
                          std::string(what) + " is not finite (" + std::string(t) + ")");
      return value;
    };
    xyz.insert(xyz.end(), {number(columns->x, "x"), number(columns->y, "y"), number(columns->z, "z")});
    if (columns->nx >= 0)
      normals.insert(normals.end(),
                     {number(columns->nx, "nx"), number(columns->ny, "ny"), number(columns->nz, "nz")});
    if (columns->weight >= 0) weights.push_back(number(columns->weight, "weight"));
  }
  if (xyz.empty()) throw FormatError(file, "", "empty point set: no data lines");
  Scan scan;
  const auto n = static_cast<Eigen::Index>(xyz.size() / 3);
  scan.points = Eigen::Map<const Eigen::Matrix3Xd>(xyz.data(), 3, n);
  if (!normals.empty()) scan.normals = Eigen::Map<const Eigen::Matrix3Xd>(normals.data(), 3, n);
  if (!weights.empty()) scan.weights = Eigen::Map<const Eigen::VectorXd>(weights.data(), n);
  scan.metadata.device = "file";
  scan.metadata.source = file;
  return scan;
}

Scan ParseNistDs(const std::string& bytes, const std::string& file) {
  LineReader lines(bytes);
  Line line;
  std::vector<std::string_view> tok;
  std::size_t declared = 0;
  bool have_count = false;
  std::vector<double> xyz;
  while (lines.Next(line)) {
    Tokenize(line.text, tok);
    if (tok.empty()) continue;
    const std::string where = AtLine(line.number);
    if (!have_count) {
      if (tok.size() != 1 || !ParseInteger(tok[0], declared)) {
        throw FormatError(file, where,
                          "expected the point count on the first line, found " + Quoted(line.text));
      }
      if (declared == 0) throw FormatError(file, where, "empty point set: the count is 0");
      have_count = true;
      xyz.reserve(3 * std::min<std::size_t>(declared, bytes.size() / 6));
      continue;
    }
    if (xyz.size() / 3 == declared) {
      throw FormatError(file, where,
                        "more data lines than the declared " + std::to_string(declared) + " points");
    }
    if (tok.size() != 3)
      throw FormatError(file, where, "expected 3 values (x y z), found " + std::to_string(tok.size()));
    for (const std::string_view t : tok) {
      double v;
      if (!ParseDouble(t, v)) throw FormatError(file, where, "not a number: " + Quoted(t));
      if (!std::isfinite(v))
        throw FormatError(file, where, "coordinate is not finite (" + std::string(t) + ")");
      xyz.push_back(v);
    }
  }
  if (!have_count) throw FormatError(file, "", "empty file: no point count");
  if (xyz.size() / 3 != declared) {
    throw FormatError(file, AtLine(lines.line_number() + 1),
                      "truncated: " + std::to_string(declared) + " points declared, " +
                          std::to_string(xyz.size() / 3) + " present");
  }
  Scan scan;
  scan.points = Eigen::Map<const Eigen::Matrix3Xd>(xyz.data(), 3, static_cast<Eigen::Index>(declared));
  scan.metadata.device = "file";
  scan.metadata.source = file;
  return scan;
}

}  // namespace s2m::formats
