#include <Geom2dAPI_PointsToBSpline.hxx>
#include <Geom2d_BSplineCurve.hxx>
#include <Standard_Failure.hxx>
#include <TColStd_Array1OfReal.hxx>
#include <TColgp_Array1OfPnt2d.hxx>
#include <vector>

#include "bench/curve_baselines.h"

namespace s2m::bench {

bool OcctAvailable(std::string* why) {
  if (why) why->clear();
  return true;
}

std::optional<BSplineCurve> OcctSmoothing(const Eigen::Matrix2Xd& points, double tension, double flexion,
                                          double jerk, int max_degree, double tolerance) {
  try {
    TColgp_Array1OfPnt2d array(1, static_cast<int>(points.cols()));
    for (Eigen::Index i = 0; i < points.cols(); ++i)
      array.SetValue(static_cast<int>(i) + 1, gp_Pnt2d(points(0, i), points(1, i)));
    Geom2dAPI_PointsToBSpline fit(array, tension, flexion, jerk, max_degree, GeomAbs_C2, tolerance);
    if (!fit.IsDone()) return std::nullopt;
    const Handle(Geom2d_BSplineCurve)& c = fit.Curve();
    if (c.IsNull() || c->IsRational()) return std::nullopt;
    TColStd_Array1OfReal flat(1, c->NbPoles() + c->Degree() + 1);
    c->KnotSequence(flat);
    std::vector<double> knots;
    for (int i = flat.Lower(); i <= flat.Upper(); ++i) knots.push_back(flat.Value(i));
    Eigen::MatrixXd poles(2, c->NbPoles());
    for (int i = 1; i <= c->NbPoles(); ++i) {
      const gp_Pnt2d p = c->Pole(i);
      poles(0, i - 1) = p.X();
      poles(1, i - 1) = p.Y();
    }
    return BSplineCurve(BSplineBasis::Clamped(c->Degree() + 1, knots), poles);
  } catch (const Standard_Failure&) {
    return std::nullopt;
  } catch (const std::exception&) {
    return std::nullopt;
  }
}

}  // namespace s2m::bench
