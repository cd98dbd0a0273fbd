#pragma once
// Inspection against a nominal mesh (docs/metrology.md section 5): the scan views are registered to the
// nominal, a fixed model (fitting/model_registration.h, SDM or TDM to the triangles: TriangleMeshModel), then
// each point's signed deviation from the nominal and the deviation statistics of each face group.
//
// Registration: (1) all views together as one rigid body (their recorded relative poses kept) to the nominal,
// which removes the common placement error; (2) each view on its own from there (per_view), which removes
// each view's own pose error (a turntable's angle and axis errors). With datum groups, both steps use only
// the points whose foot lies inside a datum group's faces (not on their edges), matched to those faces alone,
// re-selected over `datum_rounds` rounds (a view whose datum points leave a motion free keeps step (1)'s
// pose): the part is aligned on its datum features, and the other faces'
// deviations are measured in that frame (a least-squares datum system over the named faces; ISO 5459's
// sequential primary/secondary/tertiary constraints are not modelled).

#include <Eigen/Core>
#include <functional>
#include <limits>
#include <string>
#include <vector>

#include "fitting/model_registration.h"
#include "fitting/triangle_mesh.h"
#include "registration/rigid_motion.h"

namespace s2m {

struct NominalInspectionOptions {
  ModelRegistrationOptions registration;  // ErrorTerm::kSdm by default (TDM on the flat facets)
  bool per_view = true;                   // step (2) above
  std::vector<int> datum_groups;          // face groups of the nominal to align on; empty: every face
  int datum_rounds = 3;
  // Called after every iteration of every registration with the view (-1: all views as one body, step (1)),
  // the iteration (from 1) and the RMS distance to the nominal (input units); may be empty.
  // registration.progress, when set, is called as well.
  std::function<void(int view, int iteration, double rms)> progress;
  bool IsValid(std::string* why = nullptr) const;
};

// Deviation statistics of the points whose feet lie on one face group (input units).
struct RegionDeviation {
  int group = 0;
  std::string name;
  double nominal_area = 0.0;
  Eigen::Index count = 0;
  double mean = 0.0, standard_deviation = 0.0, rms = 0.0;
  double min = 0.0, max = 0.0;  // signed: min the deepest below, max the highest above the nominal
};

struct NominalInspection {
  std::vector<RigidMotion> nominal_T_scan;            // final pose of each view
  RigidMotion common_correction;                      // step (1): applied to every recorded pose
  std::vector<ModelRegistrationResult> registration;  // step (2) per view (step (1)'s when !per_view)
  Eigen::Matrix3Xd points;                            // every view's points in the nominal frame
  std::vector<Eigen::Index> view_of_point;            // which view each point came from
  Eigen::VectorXd deviations;                         // signed, positive outside the nominal
  std::vector<Eigen::Index> triangle;                 // each point's foot triangle
  std::vector<int> group;                             // its face group
  Eigen::Matrix3Xd normals;                           // the nominal's outward normal at each foot
  std::vector<RegionDeviation> regions;               // one per face group (groups with no point too)
  Eigen::Index registration_points = 0;               // points that the registration used
  // Views whose datum points do not fix all six motions (e.g. they see two datum planes only): they keep the
  // common pose of step (1).
  int views_on_common_pose = 0;
};

// `scans`: each view's points in its own coordinates; `nominal_T_scan_initial`: the recorded poses placing
// them in the nominal's frame. Throws std::invalid_argument for inconsistent inputs or invalid options.
NominalInspection InspectAgainstNominal(const TriangleMeshModel& nominal,
                                        const std::vector<Eigen::Matrix3Xd>& scans,
                                        const std::vector<RigidMotion>& nominal_T_scan_initial,
                                        const NominalInspectionOptions& options = {});

// The statistics of the deviations by group (used by InspectAgainstNominal; exposed for re-evaluation).
std::vector<RegionDeviation> RegionStatistics(const TriangleMesh& mesh, const Eigen::VectorXd& deviations,
                                              const std::vector<int>& group);

// The standard uncertainty of each point's normal deviation due to its view's registered pose (the law of
// propagation from the pose's covariance s^2 H^-1 of the point-to-plane normal equations at the final feet,
// s^2 = sum d^2 / (n - 6)): u_i^2 = a_i^T V a_i, a_i = [x_i x n_i; n_i] (docs/metrology.md eq. 15).
Eigen::VectorXd PoseDeviationUncertainty(const NominalInspection& inspection);

}  // namespace s2m
