#include "acquisition/part_file.h"

#include <Eigen/Geometry>
#include <cctype>
#include <cmath>
#include <map>
#include <nlohmann/json.hpp>
#include <optional>

#include "acquisition/format_error.h"
#include "acquisition/formats/readers.h"
#include "fitting/primitives.h"

namespace s2m {
namespace {

constexpr double kDegree = M_PI / 180.0;
// Members in the file's order: the free parameters are numbered (and reported) as the file lists them.
using Json = nlohmann::ordered_json;

struct ParameterInfo {
  int index = -1;      // among the free parameters; -1 when fixed
  double value = 0.0;  // file units (degrees for angles)
  bool angle = false;
};
using ParameterTable = std::map<std::string, ParameterInfo>;

// Recursive descent over + - * / ( ) numbers and names; every value stays linear in the free parameters.
class ExpressionParser {
 public:
  ExpressionParser(const std::string& text, const ParameterTable& table) : text_(text), table_(table) {}

  LinearExpression Parse() {
    LinearExpression e = Sum();
    Skip();
    if (pos_ != text_.size()) Fail("unexpected '" + text_.substr(pos_, 1) + "'");
    return e;
  }
  bool uses_angle = false, uses_length = false;

 private:
  [[noreturn]] void Fail(const std::string& problem) const {
    throw std::invalid_argument("'" + text_ + "': " + problem);
  }
  void Skip() {
    while (pos_ < text_.size() && std::isspace(static_cast<unsigned char>(text_[pos_]))) ++pos_;
  }
  bool Accept(char c) {
    Skip();
    if (pos_ < text_.size() && text_[pos_] == c) {
      ++pos_;
      return true;
    }
    return false;
  }
  static LinearExpression Scaled(LinearExpression e, double k) {
    e.constant *= k;
    for (auto& term : e.terms) term.second *= k;
    return e;
  }
  static LinearExpression Plus(LinearExpression a, const LinearExpression& b) {
    a.constant += b.constant;
    for (const auto& [index, coefficient] : b.terms) {
      bool merged = false;
      for (auto& term : a.terms) {
        if (term.first == index) {
          term.second += coefficient;
          merged = true;
        }
      }
      if (!merged) a.terms.emplace_back(index, coefficient);
    }
    return a;
  }
  LinearExpression Sum() {
    LinearExpression e = Product();
    for (;;) {
      if (Accept('+')) {
        e = Plus(e, Product());
      } else if (Accept('-')) {
        e = Plus(e, Scaled(Product(), -1.0));
      } else {
        return e;
      }
    }
  }
  LinearExpression Product() {
    LinearExpression e = Factor();
    for (;;) {
      if (Accept('*')) {
        const LinearExpression f = Factor();
        if (!e.terms.empty() && !f.terms.empty()) Fail("a product of two parameters is not linear");
        e = e.terms.empty() ? Scaled(f, e.constant) : Scaled(e, f.constant);
      } else if (Accept('/')) {
        const LinearExpression f = Factor();
        if (!f.terms.empty()) Fail("dividing by a parameter is not linear");
        if (f.constant == 0.0) Fail("division by zero");
        e = Scaled(e, 1.0 / f.constant);
      } else {
        return e;
      }
    }
  }
  LinearExpression Factor() {
    Skip();
    if (Accept('-')) return Scaled(Factor(), -1.0);
    if (Accept('+')) return Factor();
    if (Accept('(')) {
      LinearExpression e = Sum();
      if (!Accept(')')) Fail("missing ')'");
      return e;
    }
    if (pos_ >= text_.size()) Fail("ends too early");
    const char c = text_[pos_];
    if (std::isdigit(static_cast<unsigned char>(c)) || c == '.') {
      std::size_t used = 0;
      double v = 0.0;
      try {
        v = std::stod(text_.substr(pos_), &used);
      } catch (const std::exception&) {
        Fail("bad number");
      }
      pos_ += used;
      return {v, {}};
    }
    if (std::isalpha(static_cast<unsigned char>(c)) || c == '_') {
      const std::size_t begin = pos_;
      while (pos_ < text_.size() &&
             (std::isalnum(static_cast<unsigned char>(text_[pos_])) || text_[pos_] == '_'))
        ++pos_;
      const std::string name = text_.substr(begin, pos_ - begin);
      const auto it = table_.find(name);
      if (it == table_.end()) Fail("unknown parameter '" + name + "'");
      (it->second.angle ? uses_angle : uses_length) = true;
      if (it->second.index < 0) return {it->second.value, {}};
      return {0.0, {{it->second.index, 1.0}}};
    }
    Fail("unexpected '" + std::string(1, c) + "'");
  }

  std::string text_;
  const ParameterTable& table_;
  std::size_t pos_ = 0;
};

class Reader {
 public:
  Reader(std::string source) : source_(std::move(source)) {}

  [[noreturn]] void Fail(const std::string& where, const std::string& problem) const {
    throw FormatError(source_, where, problem);
  }

  // An optional member of an object that must be a string (bool) when present: `fallback` when absent, a
  // FormatError naming it when of another type (Json::value would throw its own type_error).
  std::string OptionalText(const Json& object, const char* key, const std::string& fallback,
                           const std::string& where) const {
    if (!object.contains(key)) return fallback;
    if (!object[key].is_string()) Fail(where, std::string("\"") + key + "\" must be a string");
    return object[key].get<std::string>();
  }
  bool OptionalFlag(const Json& object, const char* key, bool fallback, const std::string& where) const {
    if (!object.contains(key)) return fallback;
    if (!object[key].is_boolean()) Fail(where, std::string("\"") + key + "\" must be true or false");
    return object[key].get<bool>();
  }

  LinearExpression Expression(const Json& value, const std::string& where, bool angle) {
    if (value.is_number()) {
      const double v = value.get<double>();
      if (!std::isfinite(v)) Fail(where, "not a finite number");
      return {angle ? v * kDegree : v, {}};
    }
    if (!value.is_string()) Fail(where, "expected a number or an expression string");
    try {
      ExpressionParser parser(value.get<std::string>(), table_);
      LinearExpression e = parser.Parse();
      if (angle && parser.uses_length) Fail(where, "an angle cannot use a length parameter");
      if (!angle && parser.uses_angle) Fail(where, "a length cannot use an angle parameter");
      if (angle) e.constant *= kDegree;  // coefficients act on parameters already held in radians
      return e;
    } catch (const std::invalid_argument& e) {
      Fail(where, e.what());
    }
  }

  Eigen::Vector3d Direction(const Json& value, const std::string& where) {
    if (!value.is_array() || value.size() != 3) Fail(where, "expected a direction [x, y, z]");
    Eigen::Vector3d d;
    for (int i = 0; i < 3; ++i) {
      if (!value[static_cast<std::size_t>(i)].is_number()) Fail(where, "direction entries must be numbers");
      d[i] = value[static_cast<std::size_t>(i)].get<double>();
    }
    if (!d.allFinite() || d.norm() == 0.0) Fail(where, "the direction must be finite and non-zero");
    return d.normalized();
  }

  // A spline patch: "control_points" rows along u of points along v, each coordinate a number or an
  // expression; "degree" (3) or [du, dv]; optional clamped "knots_u"/"knots_v" (default uniform on [0, 1]);
  // optional "free_along": a direction along which every control point gets its own free displacement
  // parameter "<face>[i,j]" (nominal 0), which makes the face free-form while the rest stays tied to the
  // named parameters.
  SplinePatch Patch(const Json& fj, const Json& net, const std::string& where, const std::string& face,
                    std::vector<PartParameter>& free_parameters) {
    const std::string net_where = where + " control_points";
    if (!net.is_array() || net.empty() || !net[0].is_array() || net[0].empty())
      Fail(net_where, "expected rows (along u) of [x, y, z] points (along v)");
    const std::size_t nu = net.size(), nv = net[0].size();
    std::array<int, 2> degree{3, 3};
    if (fj.contains("degree")) {
      const Json& d = fj["degree"];
      if (d.is_number_integer()) {
        degree = {d.get<int>(), d.get<int>()};
      } else if (d.is_array() && d.size() == 2 && d[0].is_number_integer() && d[1].is_number_integer()) {
        degree = {d[0].get<int>(), d[1].get<int>()};
      } else {
        Fail(where + " degree", "expected an integer or [degree_u, degree_v]");
      }
    }
    auto basis = [&](const char* key, const char* direction, int deg, std::size_t count) {
      const std::string w = where + " " + key;
      if (deg < 1 || deg + 1 > BSplineBasis::kMaxOrder)
        Fail(where + " degree", "must lie in 1.." + std::to_string(BSplineBasis::kMaxOrder - 1));
      if (static_cast<int>(count) < deg + 1) {
        Fail(net_where, "degree " + std::to_string(deg) + " needs at least " + std::to_string(deg + 1) +
                            " control points along " + direction + ", not " + std::to_string(count));
      }
      try {
        if (!fj.contains(key)) return BSplineBasis::ClampedUniform(deg + 1, static_cast<int>(count));
        if (!fj[key].is_array()) Fail(w, "expected an array of knots");
        std::vector<double> knots;
        for (const Json& k : fj[key]) {
          if (!k.is_number() || !std::isfinite(k.get<double>())) Fail(w, "knots must be finite numbers");
          knots.push_back(k.get<double>());
        }
        return BSplineBasis::Clamped(deg + 1, std::move(knots));
      } catch (const std::invalid_argument& e) {
        Fail(w, e.what());
      }
    };
    SplinePatch patch{basis("knots_u", "u", degree[0], nu), basis("knots_v", "v", degree[1], nv), {}};
    if (patch.u.num_control() != static_cast<int>(nu) || patch.v.num_control() != static_cast<int>(nv)) {
      Fail(where, "the knot vectors are for " + std::to_string(patch.u.num_control()) + " x " +
                      std::to_string(patch.v.num_control()) + " control points, the net has " +
                      std::to_string(nu) + " x " + std::to_string(nv));
    }
    std::optional<Eigen::Vector3d> free_along;
    if (fj.contains("free_along")) {
      free_along = Direction(fj["free_along"], where + " free_along");
      patch.free_along = *free_along;
      patch.first_displacement = static_cast<int>(free_parameters.size());
    }
    for (std::size_t i = 0; i < nu; ++i) {
      if (!net[i].is_array() || net[i].size() != nv)
        Fail(net_where,
             "row " + std::to_string(i) + " must hold " + std::to_string(nv) + " points like row 0");
      for (std::size_t j = 0; j < nv; ++j) {
        const std::string pw = net_where + "[" + std::to_string(i) + "][" + std::to_string(j) + "]";
        const Json& p = net[i][j];
        if (!p.is_array() || p.size() != 3) Fail(pw, "expected [x, y, z]");
        std::array<LinearExpression, 3> point;
        for (std::size_t c = 0; c < 3; ++c)
          point[c] = Expression(p[c], pw + "[" + std::to_string(c) + "]", false);
        if (free_along) {
          const int index = static_cast<int>(free_parameters.size());
          free_parameters.push_back(
              {face + "[" + std::to_string(i) + "," + std::to_string(j) + "]", 0.0, false});
          for (int c = 0; c < 3; ++c) {
            if ((*free_along)[c] != 0.0)
              point[static_cast<std::size_t>(c)].terms.emplace_back(index, (*free_along)[c]);
          }
        }
        patch.control_points.push_back(std::move(point));
      }
    }
    return patch;
  }

  PartFile Parse(const std::string& text) {
    Json j;
    try {
      j = Json::parse(text);
    } catch (const nlohmann::json::parse_error& e) {
      Fail("byte " + std::to_string(e.byte), std::string("not valid JSON: ") + e.what());
    } catch (const nlohmann::json::out_of_range& e) {  // a number beyond double's range
      Fail("", std::string("not valid JSON: ") + e.what());
    }
    if (!j.is_object() || !j.contains("format") || !j["format"].is_string() ||
        j["format"].get<std::string>() != "scan2model.part/1")
      Fail("format", "not a scan2model.part/1 file (its \"format\" must be \"scan2model.part/1\")");
    PartFile out;
    out.definition.name = OptionalText(j, "name", std::string(), "name");
    out.units = OptionalText(j, "units", std::string(), "units");
    if (j.contains("parameters")) {
      if (!j["parameters"].is_object()) Fail("parameters", "expected an object of named parameters");
      for (const auto& [name, spec] : j["parameters"].items()) {
        const std::string where = "parameter '" + name + "'";
        ParameterInfo info;
        bool fixed = false;
        if (spec.is_number()) {
          info.value = spec.get<double>();
        } else if (spec.is_object() && spec.contains("value") && spec["value"].is_number()) {
          info.value = spec["value"].get<double>();
          fixed = OptionalFlag(spec, "fixed", false, where);
          const std::string unit = OptionalText(spec, "unit", std::string(), where);
          if (unit == "deg") {
            info.angle = true;
          } else if (!unit.empty() && unit != "length") {
            Fail(where, "unit must be \"deg\" (an angle) or \"length\", not \"" + unit + "\"");
          }
          if (spec.contains("tolerance")) {
            const Json& t = spec["tolerance"];
            if (!t.is_number() || !std::isfinite(t.get<double>()) || t.get<double>() < 0)
              Fail(where, "the tolerance must be a non-negative number (value +- tolerance)");
            out.tolerances[name] = t.get<double>();
          }
        } else {
          Fail(where, "expected a number or {\"value\": number, \"unit\": \"deg\", \"fixed\": bool}");
        }
        if (!std::isfinite(info.value)) Fail(where, "the value is not finite");
        const PartParameter held{name, info.angle ? info.value * kDegree : info.value, info.angle};
        if (fixed) {
          out.fixed_parameters.push_back(held);
        } else {
          info.index = static_cast<int>(out.definition.parameters.size());
          out.definition.parameters.push_back(held);
        }
        table_[name] = info;
      }
    }
    if (!j.contains("faces") || !j["faces"].is_array() || j["faces"].empty())
      Fail("faces", "a part needs a non-empty \"faces\" array");
    for (std::size_t i = 0; i < j["faces"].size(); ++i) {
      const Json& fj = j["faces"][i];
      PartFace f;
      f.name = "face " + std::to_string(i);
      if (fj.is_object()) f.name = OptionalText(fj, "name", f.name, f.name);
      const std::string where = "face '" + f.name + "'";
      if (!fj.is_object() || !fj.contains("type") || !fj["type"].is_string())
        Fail(where, "each face is an object with a \"type\"");
      const std::string type = fj["type"].get<std::string>();
      auto need = [&](const char* key) -> const Json& {
        if (!fj.contains(key)) Fail(where, std::string("a ") + type + " needs \"" + key + "\"");
        return fj[key];
      };
      auto point = [&](const char* key) {
        const Json& p = need(key);
        if (!p.is_array() || p.size() != 3) Fail(where + " " + key, "expected [x, y, z]");
        for (std::size_t c = 0; c < 3; ++c)
          f.origin[c] = Expression(p[c], where + " " + key + "[" + std::to_string(c) + "]", false);
      };
      if (type == "plane") {
        f.type = FaceType::kPlane;
        f.frame = FrameWithAxis(Direction(need("normal"), where + " normal"));
        f.offset = Expression(need("offset"), where + " offset", false);
      } else if (type == "cylinder" || type == "cone") {
        f.type = type == "cylinder" ? FaceType::kCylinder : FaceType::kCone;
        f.frame = FrameWithAxis(Direction(need("axis"), where + " axis"));
        point("point");
        f.radius = Expression(need("radius"), where + " radius", false);
        if (f.type == FaceType::kCone)
          f.half_angle = Expression(need("half_angle_deg"), where + " half_angle_deg", true);
      } else if (type == "sphere") {
        f.type = FaceType::kSphere;
        point("center");
        f.radius = Expression(need("radius"), where + " radius", false);
      } else if (type == "torus") {
        f.type = FaceType::kTorus;
        f.frame = FrameWithAxis(Direction(need("axis"), where + " axis"));
        point("center");
        f.radius = Expression(need("major_radius"), where + " major_radius", false);
        f.minor_radius = Expression(need("minor_radius"), where + " minor_radius", false);
      } else if (type == "spline_patch") {
        f.type = FaceType::kSplinePatch;
        f.patch = Patch(fj, need("control_points"), where, f.name, out.definition.parameters);
      } else {
        Fail(where,
             "unknown face type \"" + type + "\" (plane, cylinder, cone, sphere, torus, spline_patch)");
      }
      out.definition.faces.push_back(std::move(f));
    }
    try {
      PartModel check(out.definition);  // ranges and consistency at the given values
    } catch (const std::invalid_argument& e) {
      Fail("faces", e.what());
    }
    return out;
  }

 private:
  std::string source_;
  ParameterTable table_;
};

}  // namespace

PartFile ParsePartFile(const std::string& text, const std::string& source) {
  try {
    return Reader(source).Parse(text);
  } catch (const nlohmann::json::exception& e) {
    // A member of a type the reader does not check by name: still the file's error, said with the library's
    // words (the members the reader reads are checked by name above).
    throw FormatError(source, "", std::string("a member of an unexpected type: ") + e.what());
  }
}

PartFile ReadPartFile(const std::string& path) {
  return ParsePartFile(formats::ReadFileBytes(path), path);
}

}  // namespace s2m
