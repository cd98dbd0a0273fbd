// The scan2model.part/1 reader (acquisition/part_file.h, docs/parts.md): the documented example, linear
// expressions, angle units, and an error naming the face or parameter for every kind of bad file.

#include "acquisition/part_file.h"

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "acquisition/format_error.h"
#include "fitting/part_model.h"
#include "synthetic/synthetic_cases.h"

namespace s2m {
namespace {

constexpr double kDegree = M_PI / 180.0;

std::string Example() {
  return std::string(S2M_SOURCE_DIR) + "/docs/examples/counterbored_block.part.json";
}

// A part file from its "parameters" object and its "faces" array (JSON text).
std::string PartText(const std::string& parameters, const std::string& faces) {
  return R"({"format": "scan2model.part/1", "name": "test part", "units": "mm", "parameters": )" +
         parameters + R"(, "faces": )" + faces + "}";
}

// One face using `expression` for the plane's offset, with parameters a = 10, b = 4, c = 3 (fixed).
PartFile PlaneWithOffset(const std::string& expression) {
  return ParsePartFile(
      PartText(R"({"a": 10, "b": 4, "c": {"value": 3, "fixed": true}})",
               R"([{"name": "p", "type": "plane", "normal": [0, 0, 1], "offset": ")" + expression + R"("}])"),
      "test.part.json");
}

double OffsetAtNominal(const PartFile& f) {
  PartModel model(f.definition);
  return f.definition.faces[0].offset.Evaluate(model.parameters());
}

const PartFace& Face(const PartFile& f, const std::string& name) {
  for (const PartFace& face : f.definition.faces) {
    if (face.name == name) return face;
  }
  throw std::runtime_error("no face " + name);
}

TEST(PartFile, TheDocumentedExampleParses) {
  const PartFile f = ReadPartFile(Example());
  EXPECT_EQ(f.definition.name, "block with a through bore and a counterbore");
  EXPECT_EQ(f.units, "mm");
  // Five free parameters in the file's order; the height is fixed.
  const std::vector<std::string> names = {"width", "depth", "bore_diameter", "counterbore_diameter",
                                          "counterbore_depth"};
  const std::vector<double> values = {60, 40, 10, 18, 6};
  ASSERT_EQ(f.definition.parameters.size(), names.size());
  for (std::size_t i = 0; i < names.size(); ++i) {
    EXPECT_EQ(f.definition.parameters[i].name, names[i]);
    EXPECT_EQ(f.definition.parameters[i].value, values[i]);
    EXPECT_FALSE(f.definition.parameters[i].angle);
  }
  ASSERT_EQ(f.fixed_parameters.size(), 1u);
  EXPECT_EQ(f.fixed_parameters[0].name, "height");
  EXPECT_EQ(f.fixed_parameters[0].value, 20.0);

  ASSERT_EQ(f.definition.faces.size(), 9u);
  const PartModel model(f.definition);
  const Eigen::VectorXd p = model.parameters();
  struct Expected {
    const char* name;
    FaceType type;
    Eigen::Vector3d axis;
    double value;  // planes: the offset; cylinders: the radius
  };
  const std::vector<Expected> expected = {
      {"top", FaceType::kPlane, Eigen::Vector3d::UnitZ(), 20},
      {"bottom", FaceType::kPlane, -Eigen::Vector3d::UnitZ(), 0},
      {"right", FaceType::kPlane, Eigen::Vector3d::UnitX(), 30},
      {"left", FaceType::kPlane, -Eigen::Vector3d::UnitX(), 30},
      {"back", FaceType::kPlane, Eigen::Vector3d::UnitY(), 20},
      {"front", FaceType::kPlane, -Eigen::Vector3d::UnitY(), 20},
      {"bore", FaceType::kCylinder, Eigen::Vector3d::UnitZ(), 5},
      {"counterbore", FaceType::kCylinder, Eigen::Vector3d::UnitZ(), 9},
      {"counterbore floor", FaceType::kPlane, Eigen::Vector3d::UnitZ(), 14},
  };
  for (std::size_t i = 0; i < expected.size(); ++i) {
    const PartFace& face = f.definition.faces[i];
    const Expected& e = expected[i];
    EXPECT_EQ(face.name, e.name);
    EXPECT_EQ(face.type, e.type) << e.name;
    EXPECT_LT((face.frame.col(2) - e.axis).norm(), 1e-15) << e.name;
    EXPECT_NEAR((face.frame.transpose() * face.frame - Eigen::Matrix3d::Identity()).norm(), 0.0, 1e-14);
    const double value = e.type == FaceType::kPlane ? face.offset.Evaluate(p) : face.radius.Evaluate(p);
    EXPECT_DOUBLE_EQ(value, e.value) << e.name;
  }
  // The floor's offset "height - counterbore_depth": the fixed height is a constant, the depth a term.
  const LinearExpression& floor = Face(f, "counterbore floor").offset;
  EXPECT_EQ(floor.constant, 20.0);
  ASSERT_EQ(floor.terms.size(), 1u);
  EXPECT_EQ(floor.terms[0].first, 4);  // counterbore_depth
  EXPECT_EQ(floor.terms[0].second, -1.0);
  const LinearExpression& bore = Face(f, "bore").radius;
  ASSERT_EQ(bore.terms.size(), 1u);
  EXPECT_EQ(bore.terms[0].first, 2);  // bore_diameter
  EXPECT_EQ(bore.terms[0].second, 0.5);
  EXPECT_TRUE(Face(f, "top").offset.terms.empty());  // the height is fixed
}

TEST(PartFile, ExpressionsAreLinearInTheParameters) {
  // a = 10, b = 4, c = 3 (fixed).
  EXPECT_DOUBLE_EQ(OffsetAtNominal(PlaneWithOffset("a")), 10);
  EXPECT_DOUBLE_EQ(OffsetAtNominal(PlaneWithOffset("(a - 2 * b) / 2")), 1);
  EXPECT_DOUBLE_EQ(OffsetAtNominal(PlaneWithOffset("-(b - a)")), 6);
  EXPECT_DOUBLE_EQ(OffsetAtNominal(PlaneWithOffset("a - -b")), 14);
  EXPECT_DOUBLE_EQ(OffsetAtNominal(PlaneWithOffset("+a / 4 / 5")), 0.5);
  EXPECT_DOUBLE_EQ(OffsetAtNominal(PlaneWithOffset("2 * (a + b) - 3 * a + c")), 1);
  EXPECT_DOUBLE_EQ(OffsetAtNominal(PlaneWithOffset("  ( ( a ) )  ")), 10);
  EXPECT_DOUBLE_EQ(OffsetAtNominal(PlaneWithOffset("1.5e1 - a * 0.5")), 10);
  EXPECT_DOUBLE_EQ(OffsetAtNominal(PlaneWithOffset("c * c")), 9);  // fixed parameters are numbers
  EXPECT_DOUBLE_EQ(OffsetAtNominal(PlaneWithOffset("a / c * 3")), 10);

  // The coefficients, merged per parameter: (a - 2 b) / 2 + a = 1.5 a - b.
  const PartFile f = PlaneWithOffset("(a - 2 * b) / 2 + a + 0.25");
  const LinearExpression& e = f.definition.faces[0].offset;
  EXPECT_EQ(e.constant, 0.25);
  ASSERT_EQ(e.terms.size(), 2u);
  EXPECT_EQ(e.terms[0], (std::pair<int, double>{0, 1.5}));
  EXPECT_EQ(e.terms[1], (std::pair<int, double>{1, -1.0}));
  // Plain numbers work as well as expression strings.
  const PartFile n = ParsePartFile(
      PartText("{}", R"([{"name": "p", "type": "plane", "normal": [0, 0, 2], "offset": -1.25}])"), "n");
  EXPECT_TRUE(n.definition.parameters.empty());
  EXPECT_EQ(n.definition.faces[0].offset.constant, -1.25);
  EXPECT_LT((n.definition.faces[0].frame.col(2) - Eigen::Vector3d::UnitZ()).norm(), 1e-15);  // normalized
}

TEST(PartFile, AnglesAreWrittenInDegreesAndHeldInRadians) {
  const PartFile f = ParsePartFile(
      PartText(R"({"half": {"value": 30, "unit": "deg"}, "r": 12, "tilt": {"value": 10, "unit": "deg",
                   "fixed": true}, "len": {"value": 5, "unit": "length"}})",
               R"([{"name": "countersink", "type": "cone", "axis": [0, 0, 1], "point": [0, 0, "len"],
                    "radius": "r / 2", "half_angle_deg": "half"},
                   {"name": "chamfer", "type": "cone", "axis": [0, 0, 1], "point": [0, 0, 0], "radius": 4,
                    "half_angle_deg": "half + 15"},
                   {"name": "fixed cone", "type": "cone", "axis": [0, 0, 1], "point": [0, 0, 0], "radius": 4,
                    "half_angle_deg": "2 * tilt"},
                   {"name": "numeric cone", "type": "cone", "axis": [0, 0, 1], "point": [0, 0, 0],
                    "radius": 4, "half_angle_deg": 45}])"),
      "angles.part.json");
  ASSERT_EQ(f.definition.parameters.size(), 3u);
  EXPECT_EQ(f.definition.parameters[0].name, "half");
  EXPECT_TRUE(f.definition.parameters[0].angle);
  EXPECT_DOUBLE_EQ(f.definition.parameters[0].value, 30 * kDegree);
  EXPECT_FALSE(f.definition.parameters[1].angle);
  EXPECT_EQ(f.definition.parameters[2].name, "len");
  EXPECT_FALSE(f.definition.parameters[2].angle);
  ASSERT_EQ(f.fixed_parameters.size(), 1u);
  EXPECT_TRUE(f.fixed_parameters[0].angle);
  EXPECT_DOUBLE_EQ(f.fixed_parameters[0].value, 10 * kDegree);

  const PartModel model(f.definition);
  const Eigen::VectorXd p = model.parameters();
  EXPECT_DOUBLE_EQ(Face(f, "countersink").half_angle.Evaluate(p), 30 * kDegree);
  EXPECT_EQ(Face(f, "countersink").half_angle.terms[0].second, 1.0);  // acts on radians
  EXPECT_DOUBLE_EQ(Face(f, "countersink").radius.Evaluate(p), 6.0);
  EXPECT_DOUBLE_EQ(Face(f, "countersink").origin[2].Evaluate(p), 5.0);
  EXPECT_DOUBLE_EQ(Face(f, "chamfer").half_angle.Evaluate(p), 45 * kDegree);
  EXPECT_DOUBLE_EQ(Face(f, "fixed cone").half_angle.Evaluate(p), 20 * kDegree);
  EXPECT_DOUBLE_EQ(Face(f, "numeric cone").half_angle.Evaluate(p), 45 * kDegree);
}

TEST(PartFile, SpheresAndToriParse) {
  const PartFile f =
      ParsePartFile(PartText(R"({"R": 20, "r": 3})",
                             R"([{"name": "ball", "type": "sphere", "center": [1, 2, "R + 3"], "radius": "r"},
                   {"name": "ring", "type": "torus", "axis": [1, 0, 0], "center": [0, 0, 0],
                    "major_radius": "R", "minor_radius": "r"}])"),
                    "round.part.json");
  const PartModel model(f.definition);
  const Eigen::VectorXd p = model.parameters();
  EXPECT_EQ(Face(f, "ball").type, FaceType::kSphere);
  EXPECT_DOUBLE_EQ(Face(f, "ball").origin[2].Evaluate(p), 23.0);
  EXPECT_EQ(Face(f, "ring").type, FaceType::kTorus);
  EXPECT_DOUBLE_EQ(Face(f, "ring").radius.Evaluate(p), 20.0);
  EXPECT_DOUBLE_EQ(Face(f, "ring").minor_radius.Evaluate(p), 3.0);
  EXPECT_LT((Face(f, "ring").frame.col(2) - Eigen::Vector3d::UnitX()).norm(), 1e-15);
}

// docs/examples/freeform_plate.part.json is the synthetic "freeform" case's plate: the same parameters in the
// same order (width, depth, then one displacement per control point, generated), the same surface.
TEST(PartFile, TheFreeformExampleIsTheSyntheticPlate) {
  const PartFile f = ReadPartFile(std::string(S2M_SOURCE_DIR) + "/docs/examples/freeform_plate.part.json");
  const SyntheticCase c = MakeSyntheticCase("freeform");
  PartModel model(f.definition);
  ASSERT_EQ(model.num_parameters(), c.truth->num_parameters());
  for (int i = 0; i < model.num_parameters(); ++i)
    EXPECT_EQ(model.parameter_name(i), c.truth->parameter_name(i));
  EXPECT_EQ(model.parameter_name(2), "top[0,0]");
  EXPECT_EQ(model.parameter_name(17), "top[3,3]");
  EXPECT_EQ(Face(f, "top").type, FaceType::kSplinePatch);
  EXPECT_EQ(Face(f, "top").patch->u.degree(), 3);
  ASSERT_EQ(f.fixed_parameters.size(), 1u);
  EXPECT_EQ(f.fixed_parameters[0].name, "height");
  model.set_parameters(c.truth->parameters());  // the true relief
  LocalGeometry a, b;
  for (const ParamT& t : model.SampleParameters()) {
    model.Evaluate(t, 1, a);
    c.truth->Evaluate(t, 1, b);
    EXPECT_LT((a.point - b.point).norm(), 1e-12);
    EXPECT_LT((a.d1 - b.d1).norm(), 1e-12);
  }
}

TEST(PartFile, SplinePatchesTakeDegreesKnotsAndExpressions) {
  // A quadratic x linear patch, 3 x 2 control points, explicit knots along u, corner (2, 1) tied to a.
  const PartFile f = ParsePartFile(PartText(R"({"a": 4})", R"([{"name": "skin", "type": "spline_patch",
                   "degree": [2, 1], "knots_u": [0, 0, 0, 2, 2, 2],
                   "control_points": [[[0, 0, 0], [0, 1, 0]], [[1, 0, 1], [1, 1, 1]], [[2, 0, 0], [2, 1, "a / 2"]]]}])"),
                                   "skin.part.json");
  const PartFace& skin = Face(f, "skin");
  ASSERT_TRUE(skin.patch.has_value());
  EXPECT_EQ(skin.patch->u.order(), 3);
  EXPECT_EQ(skin.patch->v.order(), 2);
  EXPECT_DOUBLE_EQ(skin.patch->u.hi(), 2.0);
  EXPECT_DOUBLE_EQ(skin.patch->v.hi(), 1.0);      // default knots: uniform on [0, 1]
  ASSERT_EQ(f.definition.parameters.size(), 1u);  // no free_along: no generated parameters
  const PartModel model(f.definition);
  LocalGeometry g;
  model.Evaluate({2.0, 1.0, 0.0}, 0, g);  // a clamped patch interpolates its corners
  EXPECT_LT((g.point - Eigen::Vector3d(2, 1, 2)).norm(), 1e-14);
  std::vector<JacobianEntry> entries;
  model.ShapeJacobian({2.0, 1.0, 0.0}, false, entries);
  ASSERT_EQ(entries.size(), 1u);
  EXPECT_LT((entries[0].column - Eigen::Vector3d(0, 0, 0.5)).norm(), 1e-14);  // d(a / 2)/da at that corner
}

void ExpectError(const std::string& text, const std::vector<std::string>& needles);

TEST(PartFile, SplinePatchErrorsNameTheFaceAndTheProblem) {
  auto patch = [](const std::string& members) {
    return PartText("{}", R"([{"name": "skin", "type": "spline_patch", )" + members + "}]");
  };
  const std::string net2x2 = R"("control_points": [[[0, 0, 0], [0, 1, 0]], [[1, 0, 0], [1, 1, 0]]])";
  ExpectError(patch(R"("degree": 1)"), {"face 'skin'", "a spline_patch needs \"control_points\""});
  ExpectError(patch(R"("control_points": [])"), {"face 'skin' control_points", "expected rows"});
  ExpectError(patch(net2x2),
              {"face 'skin' control_points", "degree 3 needs at least 4 control points along u"});
  ExpectError(patch(R"("degree": 1, "control_points": [[[0, 0, 0], [0, 1, 0]], [[1, 0, 0]]])"),
              {"face 'skin' control_points", "row 1 must hold 2 points"});
  ExpectError(patch(R"("degree": 1, "control_points": [[[0, 0, 0], [0, 1]], [[1, 0, 0], [1, 1, 0]]])"),
              {"face 'skin' control_points[0][1]", "expected [x, y, z]"});
  ExpectError(patch(R"("degree": 1, "control_points": [[[0, 0, 0], [0, 1, "q"]], [[1, 0, 0], [1, 1, 0]]])"),
              {"face 'skin' control_points[0][1][2]", "unknown parameter 'q'"});
  ExpectError(patch(R"("degree": "cubic", )" + net2x2), {"face 'skin' degree", "expected an integer"});
  ExpectError(patch(R"("degree": 9, )" + net2x2), {"face 'skin' degree", "must lie in 1..7"});
  ExpectError(patch(R"("degree": 1, "knots_u": [0, 1, 1, 2], )" + net2x2), {"face 'skin' knots_u"});
  ExpectError(patch(R"("degree": 1, "knots_u": [0, 0, 1, 1, 1], )" + net2x2), {"face 'skin'"});
  ExpectError(patch(R"("degree": 1, "free_along": [0, 0, 0], )" + net2x2),
              {"face 'skin' free_along", "non-zero"});
}

// Expects ParsePartFile(text) to throw a FormatError whose message contains every one of `needles`.
void ExpectError(const std::string& text, const std::vector<std::string>& needles) {
  try {
    ParsePartFile(text, "bad.part.json");
    ADD_FAILURE() << "no error for " << text;
  } catch (const FormatError& e) {
    const std::string message = e.what();
    EXPECT_EQ(e.file(), "bad.part.json");
    EXPECT_EQ(message.rfind("bad.part.json: ", 0), 0u) << message;
    for (const std::string& needle : needles) EXPECT_NE(message.find(needle), std::string::npos) << message;
  }
}

std::string OnePlane(const std::string& offset) {
  return PartText(R"({"a": 10, "b": 4, "angle": {"value": 20, "unit": "deg"}})",
                  R"([{"name": "lid", "type": "plane", "normal": [0, 0, 1], "offset": )" + offset + "}]");
}

TEST(PartFile, ExpressionErrorsNameTheFaceAndTheProblem) {
  ExpectError(OnePlane(R"("a + z")"), {"face 'lid' offset", "unknown parameter 'z'"});
  ExpectError(OnePlane(R"("a * b")"), {"face 'lid' offset", "'a * b'", "product of two parameters"});
  ExpectError(OnePlane(R"x("(a + 1) * (b - 1)")x"), {"face 'lid'", "product of two parameters"});
  ExpectError(OnePlane(R"("10 / a")"), {"face 'lid'", "dividing by a parameter"});
  ExpectError(OnePlane(R"x("a / (b - 4)")x"), {"face 'lid'", "dividing by a parameter"});
  ExpectError(OnePlane(R"("a / 0")"), {"face 'lid'", "division by zero"});
  ExpectError(OnePlane(R"("(a + b")"), {"face 'lid'", "missing ')'"});
  ExpectError(OnePlane(R"x("a + b)")x"), {"face 'lid'", "unexpected ')'"});
  ExpectError(OnePlane(R"("a +")"), {"face 'lid'", "ends too early"});
  ExpectError(OnePlane(R"("")"), {"face 'lid'", "ends too early"});
  ExpectError(OnePlane(R"("a $ b")"), {"face 'lid'", "unexpected '$'"});
  ExpectError(OnePlane(R"("a b")"), {"face 'lid'", "unexpected 'b'"});
  ExpectError(OnePlane(R"("a + angle")"), {"face 'lid' offset", "a length cannot use an angle parameter"});
  ExpectError(OnePlane("true"), {"face 'lid' offset", "expected a number or an expression string"});
  ExpectError(OnePlane("[1]"), {"face 'lid' offset", "expected a number or an expression string"});
  ExpectError(PartText(R"({"a": 10})", R"([{"name": "sink", "type": "cone", "axis": [0, 0, 1],
                          "point": [0, 0, 0], "radius": 3, "half_angle_deg": "a"}])"),
              {"face 'sink' half_angle_deg", "an angle cannot use a length parameter"});
}

TEST(PartFile, FaceErrorsNameTheFace) {
  ExpectError(PartText("{}", R"([{"name": "knob", "type": "ellipsoid"}])"),
              {"face 'knob'", "unknown face type \"ellipsoid\"", "spline_patch"});
  ExpectError(PartText("{}", R"([{"name": "lid", "type": "plane", "normal": [0, 0, 1]}])"),
              {"face 'lid'", "a plane needs \"offset\""});
  ExpectError(PartText("{}", R"([{"name": "lid", "type": "plane", "normal": [0, 0], "offset": 1}])"),
              {"face 'lid' normal", "expected a direction"});
  ExpectError(PartText("{}", R"([{"name": "lid", "type": "plane", "normal": [0, 0, 0], "offset": 1}])"),
              {"face 'lid' normal", "non-zero"});
  ExpectError(PartText("{}", R"([{"name": "lid", "type": "plane", "normal": [0, "z", 1], "offset": 1}])"),
              {"face 'lid' normal", "must be numbers"});
  ExpectError(PartText("{}", R"([{"name": "hole", "type": "cylinder", "axis": [0, 0, 1], "point": [0, 0],
                                  "radius": 2}])"),
              {"face 'hole' point", "expected [x, y, z]"});
  ExpectError(PartText("{}", R"([{"name": "hole", "type": "cylinder", "axis": [0, 0, 1], "point": [0, 0, 0],
                                  "radius": -2}])"),
              {"face 'hole'", "the radius must be positive"});
  ExpectError(PartText("{}", R"([{"name": "sink", "type": "cone", "axis": [0, 0, 1], "point": [0, 0, 0],
                                  "radius": 2, "half_angle_deg": 95}])"),
              {"face 'sink'", "half angle must lie in (0, 90) degrees"});
  ExpectError(PartText("{}", R"([{"name": "ring", "type": "torus", "axis": [0, 0, 1], "center": [0, 0, 0],
                                  "major_radius": 2, "minor_radius": 3}])"),
              {"face 'ring'", "minor radius must be positive and below the major radius"});
  ExpectError(PartText("{}", R"([{"type": "plane", "normal": [0, 0, 1], "offset": "q"}])"),
              {"face 'face 0' offset", "unknown parameter 'q'"});  // unnamed faces are numbered
  ExpectError(PartText("{}", R"([{"name": "lid"}])"), {"face 'lid'", "with a \"type\""});
  ExpectError(PartText("{}", "[7]"), {"face 'face 0'", "with a \"type\""});
  ExpectError(PartText("{}", "[]"), {"faces", "non-empty \"faces\" array"});
  ExpectError(R"({"format": "scan2model.part/1"})", {"faces", "non-empty \"faces\" array"});
}

TEST(PartFile, ParameterAndDocumentErrorsNameTheProblem) {
  const std::string lid = R"([{"name": "lid", "type": "plane", "normal": [0, 0, 1], "offset": 1}])";
  ExpectError(PartText(R"({"w": "wide"})", lid), {"parameter 'w'", "expected a number or {"});
  ExpectError(PartText(R"({"w": {"fixed": true}})", lid), {"parameter 'w'", "expected a number or {"});
  ExpectError(PartText(R"({"w": {"value": 3, "unit": "inch"}})", lid),
              {"parameter 'w'", "unit must be \"deg\"", "not \"inch\""});
  ExpectError(PartText("[1, 2]", lid), {"parameters", "expected an object of named parameters"});
  ExpectError(R"({"format": "scan2model.part/2", "faces": [] })", {"format", "not a scan2model.part/1 file"});
  ExpectError(R"([1, 2])", {"format", "not a scan2model.part/1 file"});
  ExpectError(R"({"format": "scan2model.part/1", "faces": [)", {"not valid JSON"});
  ExpectError("", {"not valid JSON"});
  // Members of the wrong type are named (the first found by coverage-guided fuzzing: a face whose name is an
  // array, tests/data/fuzz/part_file/).
  ExpectError(PartText("{}", R"([{"name": [0, 0, 1], "type": "plane", "normal": [0, 0, 1], "offset": 1}])"),
              {"face 0", "\"name\" must be a string"});
  ExpectError(PartText(R"({"w": {"value": 3, "fixed": "yes"}})", lid),
              {"parameter 'w'", "\"fixed\" must be true or false"});
  ExpectError(PartText(R"({"w": {"value": 3, "unit": 7}})", lid),
              {"parameter 'w'", "\"unit\" must be a string"});
  ExpectError(R"({"format": ["scan2model.part/1"], "faces": []})",
              {"format", "not a scan2model.part/1 file"});
  ExpectError(R"({"format": "scan2model.part/1", "units": 1, "faces": []})", {"units", "must be a string"});
}

TEST(PartFile, MissingFileIsAFormatErrorNamingIt) {
  const std::string missing = "/nonexistent/block.part.json";
  try {
    ReadPartFile(missing);
    ADD_FAILURE() << "no error";
  } catch (const FormatError& e) {
    EXPECT_EQ(e.file(), missing);
    EXPECT_NE(std::string(e.what()).find("cannot open"), std::string::npos) << e.what();
  }
  // And the file's path is what errors name.
  const auto path = std::filesystem::temp_directory_path() / "s2m_part_file_test.part.json";
  std::ofstream(path) << OnePlane(R"("a * b")");
  try {
    ReadPartFile(path.string());
    ADD_FAILURE() << "no error";
  } catch (const FormatError& e) {
    EXPECT_EQ(e.file(), path.string());
    EXPECT_NE(std::string(e.what()).find("face 'lid'"), std::string::npos) << e.what();
  }
  std::filesystem::remove(path);
}

}  // namespace
}  // namespace s2m
