// The model checker (fitting/model_checker.h) on every model family of the tree, one line each
// (S2M_CHECK_MODEL_FAMILY), and on deliberately wrong models, which it must fail on the check that covers
// the fault and pass on the others.

#include "fitting/model_checker.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>
#include <functional>
#include <memory>

#include "acquisition/part_file.h"
#include "fitting/bspline_models.h"
#include "fitting/hermite_curve.h"
#include "fitting/kinematic_surfaces.h"
#include "fitting/part_model.h"
#include "fitting/primitive_models.h"
#include "test_models.h"

namespace s2m {
namespace {

// Clamped knots at the integers, spans of length 1 (order k, n control points).
BSplineBasis UnitSpacedClamped(int order, int n) {
  std::vector<double> knots;
  for (int i = 0; i < order; ++i) knots.push_back(0.0);
  for (int i = 1; i < n - order + 1; ++i) knots.push_back(i);
  for (int i = 0; i < order; ++i) knots.push_back(n - order + 1);
  return BSplineBasis::Clamped(order, knots);
}

// The checker's verdict on one model: every check passes, and the checks every model has ran.
void ExpectModelPasses(const ParametricModel& model) {
  // Other seeds draw other samples and perturbations: the verdict must not depend on them.
  for (const std::uint32_t seed : {1u, 2u, 3u, 4u, 5u, 6u, 7u, 8u}) {
    ModelCheckOptions options;
    options.seed = seed;
    const ModelCheckReport other = CheckModel(model, options);
    EXPECT_TRUE(other.ok()) << "seed " << seed << "\n" << other.ToString();
  }
  const ModelCheckReport report = CheckModel(model);
  EXPECT_TRUE(report.ok()) << report.ToString();
  for (const char* name :
       {kCheckFirstDerivatives, kCheckSecondDerivatives, kCheckShapeJacobian, kCheckShapeJacobianDt,
        kCheckPrincipalFrame, kCheckSimilarity, kCheckCloneCopy, kCheckParameterRoundTrip, kCheckApplyStep}) {
    const ModelCheck* check = report.Find(name);
    ASSERT_NE(check, nullptr) << name;
    EXPECT_TRUE(check->applicable) << name;
    EXPECT_GT(check->evaluations, 0) << name;
  }
}

// One line registers a model family: `factory` returns a std::unique_ptr<ParametricModel>.
#define S2M_CHECK_MODEL_FAMILY(name, factory)                   \
  TEST(ModelFamilyCheck, name) {                                \
    const std::unique_ptr<ParametricModel> model = (factory)(); \
    ExpectModelPasses(*model);                                  \
  }

std::unique_ptr<ParametricModel> OpenCurve2d() {
  Eigen::MatrixXd p(2, 6);
  p << 0, 1, 2, 3, 4, 5, 0, 1.5, -0.5, 1, 0.2, 0.8;
  return std::make_unique<BSplineCurve>(UnitSpacedClamped(4, 6), p);
}
std::unique_ptr<ParametricModel> OpenCurve3dQuadratic() {
  Eigen::MatrixXd p(3, 5);
  p << 0, 1, 2, 3, 4, 0, 1, 0, -1, 0, 0, 0.5, 1, 0.5, 0;
  return std::make_unique<BSplineCurve>(UnitSpacedClamped(3, 5), p);
}
std::unique_ptr<ParametricModel> ClosedCurve2d() {
  Eigen::MatrixXd p(2, 7);
  for (int i = 0; i < 7; ++i) p.col(i) << (1 + 0.3 * (i % 2)) * std::cos(i * 0.9), std::sin(i * 0.9);
  return std::make_unique<BSplineCurve>(BSplineBasis::PeriodicUniform(4, 7, 0.0, 7.0), p);
}
std::unique_ptr<ParametricModel> ClosedCurve3d() {
  Eigen::MatrixXd p(3, 8);
  for (int i = 0; i < 8; ++i)
    p.col(i) << 2 * std::cos(i * M_PI / 4), std::sin(i * M_PI / 4), 0.4 * std::sin(i * M_PI / 2);
  return std::make_unique<BSplineCurve>(BSplineBasis::PeriodicUniform(4, 8), p);
}
std::unique_ptr<ParametricModel> Surface() {
  Eigen::Matrix3Xd p(3, 25);
  for (int i = 0; i < 5; ++i)
    for (int j = 0; j < 5; ++j) p.col(i * 5 + j) << i, j, 0.3 * std::sin(i + 2.0 * j);
  return std::make_unique<BSplineSurface>(UnitSpacedClamped(4, 5), UnitSpacedClamped(3, 5), p);
}
std::unique_ptr<ParametricModel> BicubicSurface() {  // the per-patch power-form path (order 4 x 4)
  Eigen::Matrix3Xd p(3, 36);
  for (int i = 0; i < 6; ++i)
    for (int j = 0; j < 6; ++j) p.col(i * 6 + j) << i, j, 0.4 * std::cos(0.7 * i - 1.1 * j);
  return std::make_unique<BSplineSurface>(UnitSpacedClamped(4, 6), UnitSpacedClamped(4, 6), p);
}
std::unique_ptr<ParametricModel> PeriodicSurface() {
  Eigen::Matrix3Xd p(3, 24);
  for (int i = 0; i < 6; ++i)
    for (int j = 0; j < 4; ++j)
      p.col(i * 4 + j) << (2 + 0.2 * j) * std::cos(i), (2 + 0.1 * i) * std::sin(i), j;
  return std::make_unique<BSplineSurface>(BSplineBasis::PeriodicUniform(4, 6, 0.0, 6.0),
                                          UnitSpacedClamped(4, 4), p);
}
std::unique_ptr<ParametricModel> Ellipse() {
  return std::make_unique<Ellipse3D>(
      Eigen::Vector3d(1, 2, 3),
      Eigen::AngleAxisd(0.7, Eigen::Vector3d(1, 2, 3).normalized()).toRotationMatrix(), 2.0, 0.7);
}
std::unique_ptr<ParametricModel> Circle() {
  return std::make_unique<Ellipse3D>(Eigen::Vector3d(0, 0, 1),
                                     Eigen::AngleAxisd(0.3, Eigen::Vector3d::UnitY()).toRotationMatrix(), 1.5,
                                     1.5, true);
}
std::unique_ptr<ParametricModel> CylinderFamily() {
  return std::make_unique<CylinderModel>(Cylinder{{1, 2, 3}, Eigen::Vector3d(1, -1, 2).normalized(), 1.5});
}
std::unique_ptr<ParametricModel> SphereFamily() {
  return std::make_unique<SphereModel>(Sphere{{1, -2, 0.5}, 2.0},
                                       Eigen::AngleAxisd(0.4, Eigen::Vector3d(1, 0, 0)).toRotationMatrix());
}
std::unique_ptr<ParametricModel> LineFamily() {
  return std::make_unique<LineModel>(Line3d{{1, -2, 3}, Eigen::Vector3d(0.3, 1, -0.5).normalized()});
}
std::unique_ptr<ParametricModel> TorusFamily() {
  return std::make_unique<TorusModel>(Torus{{0.5, 1, -1}, Eigen::Vector3d(1, 2, 2).normalized(), 3.0, 0.8});
}
KinematicSurface Vase() {
  Eigen::Matrix2Xd profile(2, 6);
  profile << 1.0, 1.4, 1.8, 1.5, 1.2, 1.6, 0.0, 0.5, 1.2, 2.0, 2.6, 3.2;
  return KinematicSurface::Revolution(UnitSpacedClamped(4, 6), profile);
}
std::unique_ptr<ParametricModel> Revolution() {
  return std::make_unique<KinematicSurface>(Vase());
}
// The planar generatrix a surface of revolution's feet reduce to (a model of its own, FootPointReduction).
std::unique_ptr<ParametricModel> RevolutionGeneratrix() {
  const KinematicSurface vase = Vase();
  const std::unique_ptr<FootPointReduction> reduction = vase.MakeFootPointReduction();
  return reduction->reduced_model().Clone();
}
std::unique_ptr<ParametricModel> Helical() {
  Eigen::Matrix2Xd profile(2, 5);
  profile << 0.5, 0.8, 1.0, 0.9, 0.6, -0.2, -0.1, 0.0, 0.1, 0.2;
  return std::make_unique<KinematicSurface>(
      KinematicSurface::Helical(UnitSpacedClamped(3, 5), profile, 0.15, 2.0));
}
std::unique_ptr<ParametricModel> Spiral() {
  Eigen::Matrix2Xd profile(2, 5);
  profile << 1.0, 1.3, 1.5, 1.3, 1.0, -0.4, -0.2, 0.0, 0.2, 0.4;
  return std::make_unique<SpiralSurface>(UnitSpacedClamped(4, 5), profile, 0.12, -2.0, 6.0);
}
// The nested model of the allometry test (docs/shells.md eq. S1): the growth rate changing along the coil
// and the axial scale outgrowing the radial one.
std::unique_ptr<ParametricModel> AllometricSpiral() {
  Eigen::Matrix2Xd profile(2, 5);
  profile << 1.0, 1.3, 1.5, 1.3, 1.0, -0.4, -0.2, 0.3, 0.6, 0.8;
  return std::make_unique<SpiralSurface>(
      SpiralSurface(UnitSpacedClamped(4, 5), profile, 0.12, -2.0, 6.0).WithAllometry(0.01, -0.03));
}
std::unique_ptr<ParametricModel> PartFromExample(const std::string& file) {
  const PartFile part = ReadPartFile(std::string(S2M_SOURCE_DIR) + "/docs/examples/" + file);
  return std::make_unique<PartModel>(part.definition);
}
// A part with one face of every type in tilted frames, its quantities linear expressions of several
// parameters (lengths and an angle), and a spline patch whose control points depend on both lengths.
std::unique_ptr<ParametricModel> PartWithEveryFaceType() {
  PartDefinition d;
  d.name = "every face type";
  d.parameters = {{"a", 2.0, false}, {"b", 0.5, false}, {"angle", 0.35, true}};
  std::vector<PartFace> faces;
  const FaceType types[] = {FaceType::kPlane,  FaceType::kCylinder, FaceType::kCone,
                            FaceType::kSphere, FaceType::kTorus,    FaceType::kSplinePatch};
  int k = 0;
  for (FaceType type : types) {
    PartFace f = test::TiltedTestFace(type, k, -4.0);
    f.name = ToString(type);
    faces.push_back(f);
    ++k;
  }
  d.faces = faces;
  return std::make_unique<PartModel>(d);
}

// Hermite curves (fitting/hermite_curve.h): nodal values of a generic analytic curve (an epitrochoid-like
// loop lifted into 3D), non-uniform knots, so that no derivative vanishes by accident.
std::unique_ptr<ParametricModel> HermiteFamily(int degree, int dimension, bool closed, bool c2) {
  const int elements = 5, per_node = (degree + 1) / 2, nodes = closed ? elements : elements + 1;
  std::vector<double> knots = {0.0, 0.17, 0.41, 0.58, 0.79, 1.0};
  Eigen::MatrixXd dofs(dimension, nodes * per_node);
  for (int i = 0; i < nodes; ++i) {
    const double a = 2.0 * M_PI * knots[static_cast<std::size_t>(i)];
    // w(u) = (3 cos a + 0.7 cos 3a, 2 sin a - 0.5 sin 2a, 0.8 sin a + 0.3 cos 2a), a = 2 pi u.
    const double da = 2.0 * M_PI;
    const Eigen::Vector3d p(3 * std::cos(a) + 0.7 * std::cos(3 * a), 2 * std::sin(a) - 0.5 * std::sin(2 * a),
                            0.8 * std::sin(a) + 0.3 * std::cos(2 * a));
    const Eigen::Vector3d d1 =
        da * Eigen::Vector3d(-3 * std::sin(a) - 2.1 * std::sin(3 * a), 2 * std::cos(a) - std::cos(2 * a),
                             0.8 * std::cos(a) - 0.6 * std::sin(2 * a));
    const Eigen::Vector3d d2 =
        da * da *
        Eigen::Vector3d(-3 * std::cos(a) - 6.3 * std::cos(3 * a), -2 * std::sin(a) + 2 * std::sin(2 * a),
                        -0.8 * std::sin(a) - 1.2 * std::cos(2 * a));
    dofs.col(i * per_node) = p.head(dimension);
    dofs.col(i * per_node + 1) = d1.head(dimension);
    if (per_node == 3) dofs.col(i * per_node + 2) = d2.head(dimension);
  }
  return std::make_unique<HermiteCurve>(degree, knots, dofs, closed, c2);
}

S2M_CHECK_MODEL_FAMILY(OpenCurve2d, OpenCurve2d)
S2M_CHECK_MODEL_FAMILY(OpenCurve3dQuadratic, OpenCurve3dQuadratic)
S2M_CHECK_MODEL_FAMILY(ClosedCurve2d, ClosedCurve2d)
S2M_CHECK_MODEL_FAMILY(ClosedCurve3d, ClosedCurve3d)
S2M_CHECK_MODEL_FAMILY(SplineSurface, Surface)
S2M_CHECK_MODEL_FAMILY(BicubicSplineSurface, BicubicSurface)
S2M_CHECK_MODEL_FAMILY(PeriodicSplineSurface, PeriodicSurface)
S2M_CHECK_MODEL_FAMILY(Ellipse3d, Ellipse)
S2M_CHECK_MODEL_FAMILY(Circle3d, Circle)
S2M_CHECK_MODEL_FAMILY(Cylinder, CylinderFamily)
S2M_CHECK_MODEL_FAMILY(Sphere, SphereFamily)
S2M_CHECK_MODEL_FAMILY(Line3d, LineFamily)
S2M_CHECK_MODEL_FAMILY(Torus, TorusFamily)
S2M_CHECK_MODEL_FAMILY(SurfaceOfRevolution, Revolution)
S2M_CHECK_MODEL_FAMILY(RevolutionGeneratrix, RevolutionGeneratrix)
S2M_CHECK_MODEL_FAMILY(HelicalSurface, Helical)
S2M_CHECK_MODEL_FAMILY(SpiralSurface, Spiral)
S2M_CHECK_MODEL_FAMILY(AllometricSpiralSurface, AllometricSpiral)
S2M_CHECK_MODEL_FAMILY(PartCounterboredBlock, [] { return PartFromExample("counterbored_block.part.json"); })
S2M_CHECK_MODEL_FAMILY(PartFreeformPlate, [] { return PartFromExample("freeform_plate.part.json"); })
S2M_CHECK_MODEL_FAMILY(PartEveryFaceType, PartWithEveryFaceType)
S2M_CHECK_MODEL_FAMILY(HermiteOpenCubic2d, [] { return HermiteFamily(3, 2, false, false); })
S2M_CHECK_MODEL_FAMILY(HermiteClosedQuintic3d, [] { return HermiteFamily(5, 3, true, false); })
S2M_CHECK_MODEL_FAMILY(HermiteOpenQuintic2d, [] { return HermiteFamily(5, 2, false, false); })
S2M_CHECK_MODEL_FAMILY(HermiteClosedC2Cubic2d, [] { return HermiteFamily(3, 2, true, true); })
S2M_CHECK_MODEL_FAMILY(HermiteOpenC2Cubic3d, [] { return HermiteFamily(3, 3, false, true); })

// The checks that apply only to some models ran where they should.
TEST(ModelChecker, OptionalChecksRunWhereTheModelProvidesThem) {
  const ModelCheckReport revolution = CheckModel(*Revolution());
  EXPECT_TRUE(revolution.Find(kCheckFactoredJacobian)->applicable);
  EXPECT_TRUE(revolution.Find(kCheckInvariantMotions)->applicable);
  EXPECT_TRUE(revolution.Find(kCheckCommonMotions)->applicable);
  EXPECT_TRUE(revolution.Find(kCheckClosedFormFeet)->applicable);  // the meridian-plane reduction
  const ModelCheckReport cylinder = CheckModel(*CylinderFamily());
  EXPECT_TRUE(cylinder.Find(kCheckClosedFormFeet)->applicable);
  EXPECT_TRUE(cylinder.Find(kCheckInvariantMotions)->applicable);
  // The ISO 10360-6 curves and the torus check their closed-form feet and invariant motions.
  for (const auto& make : {Circle, LineFamily, TorusFamily}) {
    const ModelCheckReport report = CheckModel(*make());
    EXPECT_TRUE(report.Find(kCheckClosedFormFeet)->applicable) << report.model_name;
  }
  EXPECT_TRUE(CheckModel(*TorusFamily()).Find(kCheckInvariantMotions)->applicable);
  EXPECT_TRUE(CheckModel(*LineFamily()).Find(kCheckInvariantMotions)->applicable);
  EXPECT_FALSE(CheckModel(*Ellipse()).Find(kCheckClosedFormFeet)->applicable);
  const ModelCheckReport spiral = CheckModel(*Spiral());
  EXPECT_TRUE(spiral.Find(kCheckCommonMotions)->applicable);
  EXPECT_FALSE(spiral.Find(kCheckInvariantMotions)->applicable);
  const ModelCheckReport part = CheckModel(*PartWithEveryFaceType());
  EXPECT_TRUE(part.Find(kCheckClosedFormFeet)->applicable);
  // B-spline curves and surfaces (up to bicubic) factor their shape Jacobians; an ellipse does not.
  const ModelCheckReport curve = CheckModel(*OpenCurve2d());
  EXPECT_TRUE(curve.Find(kCheckFactoredJacobian)->applicable);
  EXPECT_TRUE(CheckModel(*BicubicSurface()).Find(kCheckFactoredJacobian)->applicable);
  EXPECT_FALSE(CheckModel(*Ellipse()).Find(kCheckFactoredJacobian)->applicable);
  EXPECT_FALSE(curve.Find(kCheckClosedFormFeet)->applicable);
  // n/a checks pass and say so.
  EXPECT_TRUE(curve.Find(kCheckClosedFormFeet)->passed);
  EXPECT_NE(curve.ToString().find("n/a  closed-form feet"), std::string::npos) << curve.ToString();
}

TEST(ModelChecker, InvalidOptionsAreRejected) {
  ModelCheckOptions o;
  std::string why;
  EXPECT_TRUE(o.IsValid(&why)) << why;
  o.sample_count = 0;
  EXPECT_FALSE(o.IsValid(&why));
  EXPECT_NE(why.find("sample_count"), std::string::npos);
  o = {};
  o.derivative_tolerance = -1;
  EXPECT_FALSE(o.IsValid(&why));
  o = {};
  o.second_derivative_step = 0.01;  // the stencils would reach past the jitter off a knot
  EXPECT_FALSE(o.IsValid(&why));
  EXPECT_THROW(CheckModel(*OpenCurve2d(), o), std::invalid_argument);
}

// ---- Deliberately wrong models
// ----------------------------------------------------------------------------------------

enum class Fault {
  kJacobianColumn,    // one shape-Jacobian column 0.1 % too long
  kJacobianDt,        // one column's t-derivative 0.1 % too long
  kFirstDerivative,   // Evaluate's d1 rotated a little within the model's space
  kSecondDerivative,  // Evaluate's d2 0.1 % too long
  kFactored,          // the factored Jacobian's weights 0.1 % too large
  kInvariantMotion,   // declares a rotation about x the model is not invariant to
  kCommonMotion,      // declares that a shape change absorbs a common translation along x
  kApplyStep,         // ApplyStep takes 1.001 x the step
  kSimilarity,        // ApplySimilarity forgets the offset
  kFoot,              // the fast foot's parameter off by 1e-4
};

// A model forwarded call by call, with one fault.
class Faulty final : public ParametricModel {
 public:
  Faulty(std::unique_ptr<ParametricModel> model, Fault fault) : model_(std::move(model)), fault_(fault) {}
  Faulty(const Faulty& other) : ParametricModel(other), model_(other.model_->Clone()), fault_(other.fault_) {}
  std::unique_ptr<ParametricModel> Clone() const override { return std::make_unique<Faulty>(*this); }
  void CopyFrom(const ParametricModel& other) override {
    model_->CopyFrom(*dynamic_cast<const Faulty&>(other).model_);
  }
  std::string name() const override { return "faulty " + model_->name(); }
  int ambient_dimension() const override { return model_->ambient_dimension(); }
  ParameterDomain domain() const override { return model_->domain(); }
  int num_parameters() const override { return model_->num_parameters(); }
  std::string parameter_name(int index) const override { return model_->parameter_name(index); }
  Eigen::VectorXd parameters() const override { return model_->parameters(); }
  void set_parameters(const Eigen::VectorXd& p) override { model_->set_parameters(p); }
  void ApplyStep(const Eigen::VectorXd& step) override {
    model_->ApplyStep(fault_ == Fault::kApplyStep ? Eigen::VectorXd(1.001 * step) : step);
  }
  void ApplySimilarity(double scale, const VecS& offset) override {
    model_->ApplySimilarity(scale, fault_ == Fault::kSimilarity ? VecS(VecS::Zero(offset.size())) : offset);
  }
  bool SupportsTranslation() const override { return model_->SupportsTranslation(); }
  std::vector<Motion6> InvariantMotions() const override {
    std::vector<Motion6> out = model_->InvariantMotions();
    if (fault_ == Fault::kInvariantMotion) out.push_back((Motion6() << 1, 0, 0, 0, 0, 0).finished());
    return out;
  }
  std::vector<Motion6> CommonMotionsAbsorbedByShape() const override {
    std::vector<Motion6> out = model_->CommonMotionsAbsorbedByShape();
    if (fault_ == Fault::kCommonMotion) out.push_back((Motion6() << 0, 0, 0, 1, 0, 0).finished());
    return out;
  }
  void Evaluate(const ParamT& t, int derivatives, LocalGeometry& out) const override {
    model_->Evaluate(t, derivatives, out);
    if (fault_ == Fault::kFirstDerivative && derivatives >= 1)
      out.d1.col(0) += 1e-3 * out.d1.col(0).reverse();
    if (fault_ == Fault::kSecondDerivative && derivatives >= 2) out.d2 *= 1.001;
  }
  void ShapeJacobian(const ParamT& t, bool with_dt, std::vector<JacobianEntry>& out) const override {
    model_->ShapeJacobian(t, with_dt, out);
    if (fault_ == Fault::kJacobianColumn) out[out.size() / 2].column *= 1.001;
    if (fault_ == Fault::kJacobianDt && with_dt) out[out.size() / 2].dcolumn_dt[0] *= 1.001;
  }
  bool FactoredShapeJacobian(const ParamT& t, FactoredJacobian& out) const override {
    if (!model_->FactoredShapeJacobian(t, out)) return false;
    if (fault_ == Fault::kFactored)
      for (double& w : out.weights) w *= 1.001;
    return true;
  }
  Eigen::MatrixXd FairnessMatrix(const FairnessWeights& weights) const override {
    return model_->FairnessMatrix(weights);
  }
  std::vector<ParamT> SampleParameters() const override { return model_->SampleParameters(); }
  bool ClosedFormFootPoint(const VecS& x, ParamT& t) const override {
    if (!model_->ClosedFormFootPoint(x, t)) return false;
    if (fault_ == Fault::kFoot) t[0] += 1e-4;
    return true;
  }
  // Through the default, so that the faulty ClosedFormFootPoint is what the engine sees.
  bool FootPointOnBoundary(const VecS& x, const ParamT& t) const override {
    return model_->FootPointOnBoundary(x, t);
  }
  bool AmbiguousFootPoint(const VecS& x, const ParamT& t) const override {
    return model_->AmbiguousFootPoint(x, t);
  }
  std::unique_ptr<FootPointReduction> MakeFootPointReduction() const override {
    return model_->MakeFootPointReduction();
  }

 private:
  std::unique_ptr<ParametricModel> model_;
  Fault fault_;
};

// The forwarding itself is faithful: without a fault (kSimilarity on a model that takes no translation
// changes nothing) every check passes.
TEST(ModelChecker, ForwardingWithoutAFaultPasses) {
  const Faulty faithful(Revolution(), Fault::kSimilarity);
  const ModelCheckReport report = CheckModel(faithful);
  EXPECT_TRUE(report.ok()) << report.ToString();
}

struct FaultCase {
  const char* label;
  std::function<std::unique_ptr<ParametricModel>()> make;
  Fault fault;
  const char* caught_by;
};

TEST(ModelChecker, DeliberatelyWrongModelsAreCaught) {
  const FaultCase cases[] = {
      {"jacobian column, spline surface", Surface, Fault::kJacobianColumn, kCheckShapeJacobian},
      {"jacobian column, cylinder", CylinderFamily, Fault::kJacobianColumn, kCheckShapeJacobian},
      {"jacobian column, part", PartWithEveryFaceType, Fault::kJacobianColumn, kCheckShapeJacobian},
      {"jacobian dt, ellipse", Ellipse, Fault::kJacobianDt, kCheckShapeJacobianDt},
      {"first derivative, curve", OpenCurve3dQuadratic, Fault::kFirstDerivative, kCheckFirstDerivatives},
      {"second derivative, spiral", Spiral, Fault::kSecondDerivative, kCheckSecondDerivatives},
      {"factored jacobian, revolution", Revolution, Fault::kFactored, kCheckFactoredJacobian},
      {"invariant motion, helical", Helical, Fault::kInvariantMotion, kCheckInvariantMotions},
      {"common motion, revolution", Revolution, Fault::kCommonMotion, kCheckCommonMotions},
      {"apply step, sphere", SphereFamily, Fault::kApplyStep, kCheckApplyStep},
      {"similarity, closed curve", ClosedCurve2d, Fault::kSimilarity, kCheckSimilarity},
      {"closed-form foot, cylinder", CylinderFamily, Fault::kFoot, kCheckClosedFormFeet},
      {"closed-form foot, torus", TorusFamily, Fault::kFoot, kCheckClosedFormFeet},
      {"jacobian column, torus", TorusFamily, Fault::kJacobianColumn, kCheckShapeJacobian},
      {"jacobian dt, torus", TorusFamily, Fault::kJacobianDt, kCheckShapeJacobianDt},
  };
  for (const FaultCase& c : cases) {
    const Faulty model(c.make(), c.fault);
    const ModelCheckReport report = CheckModel(model);
    EXPECT_FALSE(report.ok()) << c.label << "\n" << report.ToString();
    const ModelCheck* check = report.Find(c.caught_by);
    ASSERT_NE(check, nullptr) << c.label;
    EXPECT_TRUE(check->applicable) << c.label;
    EXPECT_FALSE(check->passed) << c.label << "\n" << report.ToString();
    EXPECT_GT(check->worst_error, check->tolerance) << c.label;
  }
}

}  // namespace
}  // namespace s2m
