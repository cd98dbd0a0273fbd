#pragma once
// Options of `scan2model fit`, shared by the primitive and the spline paths.

#include <Eigen/Core>
#include <cstdint>
#include <functional>
#include <memory>
#include <nlohmann/json.hpp>
#include <stdexcept>
#include <string>
#include <vector>

#include "fitting/primitive_fit.h"
#include "fitting/robust_loss.h"
#include "pipeline/exit_code.h"
#include "registration/scan.h"

namespace s2m::pipeline {

struct FitOptions {
  std::string file;
  // The input in memory instead of `file` (the Python bindings, docs/python.md); `file` then only names it
  // in messages and documents. Primitives, curves and spline surfaces fit its views merged in the world
  // frame; the multi-view fits take its views with their poses.
  std::shared_ptr<const ScanSet> views;
  std::string model;
  std::string method;  // default per model family: tdm for primitives, sdm for splines
  std::string reference;
  std::string history;
  std::string units;
  int max_iterations = 200;
  bool json = false;
  bool verbose = false;  // print the per-iteration history table
  // Told the progress of long work (the Monte Carlo trials of a multi-view fit) as a line that replaces the
  // previous one; empty: silent.
  std::function<void(const std::string&)> progress;
  bool joint = false;              // multi-view: the joint method, stated explicitly (it is the default)
  bool alternating = false;        // multi-view: the alternating baseline instead of the joint method
  bool register_then_fit = false;  // multi-view: one shared motion only (fit the pre-registered cloud)
  // Splines.
  std::string control_points;  // curve: "N"; surface: "NUxNV"
  int order = 4;
  bool closed = false;  // closed (periodic) curve; for surfaces: periodic in u over a fitted cylinder
  double stretch = 0.0;
  double bending = 1e-3;
  bool bending_given = false;  // fe-surface has its own default (docs/fe-surfaces.md eq. P6)
  // fe-surface (docs/fe-surfaces.md): the domain's outline (a point file, in order) or auto, and the
  // triangles' edge length (0: from --elements).
  std::string boundary = "auto";
  double size = 0.0;
  std::string projection = "plane";  // fe-surface: the chart, plane or cylinder
  // Kinematic surfaces (revolution, helical, spiral): where the joint fit starts (docs/method.md section 19):
  // "auto" (the normals' start, and the global search only when that fit does not reach the noise band),
  // "normals" (the normals' start only), "global" (the global search always, the normals' start among its
  // candidates).
  std::string start = "auto";
  // A pitch (helical) or growth (spiral) the user knows, to centre both searches on instead of the
  // normals' estimate; 0: none.
  double pitch = 0.0;
  double growth = 0.0;
  // Revolution: the vessel's volume also up to this height above the base (data units); 0: only to the rim.
  double fill_height = 0.0;
  // Revolution: the data hold the inner and the outer surface; fit the wall (docs/archaeology.md section 10).
  bool wall = false;
  std::string step_control = "lm";
  RobustLoss loss;  // --loss: the robust loss of every fit (fitting/robust_loss.h)
  // Whether --loss (or a manifest's "loss") was given; otherwise ComputeFit chooses the default for the
  // input's kind (ResolveDefaultLoss, fit_option_table.h) and says why in `loss_reason`.
  bool loss_given = false;
  std::string loss_reason;
  // Primitives: the criterion of the form evaluation besides least squares (fitting/minimum_zone.h): lsq,
  // minzone, inscribed or circumscribed (docs/metrology.md).
  std::string criterion = "lsq";
  // Primitives: how the derived quantities' uncertainties are evaluated (fitting/measurement_uncertainty.h):
  // none, linear or monte-carlo:N (docs/metrology.md sections 6-8).
  std::string uncertainty = "none";
  // Primitives: detect the dominant instance first (pipeline/detect.h), fit its inliers, count the rest.
  bool robust = false;
  std::uint64_t seed = 1;
  std::string rejected_output;  // --robust: the rejected points as a PLY
  std::string output;           // prefix for PREFIX.json, PREFIX.ply, PREFIX_history.csv
  int contour = 0;              // .glif inputs: which contour
  std::string initial;  // a scan2model.bspline/1 JSON to start from instead of the automatic initial model
  // Hermite curves (`--model hermite-curve`, docs/fair-curves.md).
  int degree = 5;
  std::string elements = "auto";  // N, or auto (adaptive)
  bool interpolate = false;
  bool c2 = false;
  double alpha1 = 0.0, alpha2 = 0.0, alpha3 = 1e-8, beta2 = 0.0, beta3 = 0.0;
  // Whether --alpha3 was given: B-spline curves, surfaces and generatrices take it (and beta2, beta3) as
  // their curvature-variation and jump weights (docs/fair-curves.md section 8), 0 unless given.
  bool alpha3_given = false;
  double tolerance = 0.0;            // target RMS in data units (0: the weights as given)
  double fairness_fraction = 0.0;    // scale-free fairness fraction in (0, 1) (0: the weights as given)
  double geometric_variation = 0.0;  // share of alpha3 on the arc-length curvature variation (plane curves)
  bool relative_variation = false;   // the geometric share measured relative to the curvature (eq. F34)
  int efd_harmonics = 0;             // revolution: elliptic Fourier descriptors of the outline (0: none)
  // Show the iterations on a terminal as they run (splines); `batch` turns it off for its objects.
  bool interactive = true;
};

// What a fit produced: the result document (`--json`, schemas in docs/cli.md), the text output, and the
// readers' notes (standard error in `fit`). `scan2model fit` prints it; `scan2model batch` stores it: both
// run the same code (ComputeFit).
struct FitOutcome {
  nlohmann::json document;
  std::string text;
  std::vector<std::string> notes;
};

// A fit that could not be computed: the message and the exit code of pipeline/exit_code.h (kUsage,
// kInputError, kFitError).
class FitFailure : public std::runtime_error {
 public:
  FitFailure(int exit_code, const std::string& message)
      : std::runtime_error(message), exit_code_(exit_code) {}
  int exit_code() const { return exit_code_; }

 private:
  int exit_code_;
};

// Runs the fit `o` describes (any model of `scan2model fit`); throws FitFailure. Writes the files options
// ask for (-o PREFIX, --history), nothing on standard output or error.
FitOutcome ComputeFit(const FitOptions& o);

// The members of a scan2model.fit/1 document that a primitive fit alone determines (docs/cli.md): model,
// method, parameters, nist_layout, uncertainties (lengths in `units`), residuals, iterations, stop_reason,
// history. ComputeFit's documents and the Python bindings' direct fits (docs/python.md) share it; defined for
// Plane, Sphere, Cylinder, Cone, Line3d, Circle3d and Torus.
template <class Shape>
nlohmann::json PrimitiveFitJson(const std::string& model, ErrorTerm method, const PrimitiveFit<Shape>& fit,
                                const std::string& units);

// The fits ComputeFit dispatches to; each throws FitFailure.
// A B-spline curve or surface fit.
FitOutcome ComputeSplineFit(const FitOptions& options);
// A Hermite finite-element curve fit with Fang's fairness energy (pipeline/hermite_fit.cpp).
FitOutcome ComputeHermiteFit(const FitOptions& options);
// The points of a curve or spline fit's input: a point cloud, or one contour (--contour) of a .glif glyph;
// sets the format's name, the units, the reader's notes and the device. Throws FitFailure (kUsage) for a
// contour out of range, FormatError for unreadable files.
Eigen::MatrixXd ReadFitPoints(const FitOptions& o, std::string& format, std::string& units,
                              std::vector<std::string>& notes, std::string& device);
// A fair triangular finite-element surface fit (pipeline/fe_surface_fit.cpp, docs/fe-surfaces.md).
FitOutcome ComputeFeSurfaceFit(const FitOptions& options);
// A joint multi-view fit (surface of revolution, helical or spiral surface).
FitOutcome ComputeMultiViewFit(const FitOptions& options);
// A vessel's wall (`--model revolution --wall`, docs/archaeology.md section 10): its inner and outer
// surfaces of revolution fitted jointly with the views' poses about one axis (pipeline/vessel_wall.cpp).
FitOutcome ComputeWallFit(const FitOptions& options);
// A joint multi-view fit of a constrained part (`--model part:FILE`, docs/parts.md).
FitOutcome ComputePartFit(const FitOptions& options);

}  // namespace s2m::pipeline
