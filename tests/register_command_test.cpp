// `scan2model register` end to end (docs/cli.md): the views of a synthetic part registered to each other from
// poses off by 2 degrees and 2 mm, the written manifest read back; the Stanford bunny's ten real views from
// perturbed poses (skipped without the shared data); views registered to a nominal box mesh; and the errors:
// one view, views that do not overlap, bad options, unreadable files.

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <nlohmann/json.hpp>
#include <random>

#include "acquisition/e57_io.h"
#include "acquisition/mesh_io.h"
#include "acquisition/point_cloud_io.h"
#include "acquisition/recording.h"
#include "acquisition/scan_set_io.h"
#include "synthetic/synthetic_cases.h"
#include "test_meshes.h"
#include "test_paths.h"
#include "test_support.h"

namespace s2m {
namespace {

namespace fs = std::filesystem;
constexpr double kDegree = M_PI / 180.0;

test::ShellResult Register(const std::vector<std::string>& args, bool with_stderr = false) {
  std::vector<std::string> argv = {S2M_CLI_PATH, "register"};
  argv.insert(argv.end(), args.begin(), args.end());
  return test::Shell(test::Quote(argv), with_stderr);
}

RigidMotion PoseOf(const nlohmann::json& rows) {
  Eigen::Matrix4d m;
  for (int r = 0; r < 4; ++r)
    for (int c = 0; c < 4; ++c)
      m(r, c) = rows[static_cast<std::size_t>(r)][static_cast<std::size_t>(c)].get<double>();
  return RigidMotion::FromMatrix(m);
}

// The worst error of the views' poses relative to view 0 against the truth's: rotation (rad) and the RMS
// displacement of each view's points (the registration error a user sees in the merged cloud).
struct RelativeError {
  double rotation = 0, displacement = 0;
};
RelativeError WorstRelativeError(const std::vector<Eigen::Matrix3Xd>& scans,
                                 const std::vector<RigidMotion>& fitted,
                                 const std::vector<RigidMotion>& truth) {
  RelativeError worst;
  for (std::size_t k = 1; k < scans.size(); ++k) {
    const RigidMotion a = fitted[0].inverse() * fitted[k], b = truth[0].inverse() * truth[k];
    worst.rotation = std::max(worst.rotation, (a * b.inverse()).angle());
    const double rms = std::sqrt((a.apply(scans[k]) - b.apply(scans[k])).colwise().squaredNorm().mean());
    worst.displacement = std::max(worst.displacement, rms);
  }
  return worst;
}

TEST(RegisterCommand, PartViewsFromPosesOffByTwoDegreesAreRegisteredToEachOther) {
  const fs::path dir = test::FreshTempDir("register_part");
  const SyntheticCase c = MakeSyntheticCase("part");
  WriteScanSet(dir / "in" / "views.json", RecordedViews(c));
  const test::ShellResult r =
      Register({(dir / "in" / "views.json").string(), "-o", (dir / "out" / "views.json").string(), "--json"});
  ASSERT_EQ(r.exit_code, 0) << r.out;
  const nlohmann::json j = nlohmann::json::parse(r.out);
  EXPECT_EQ(j["schema"], "scan2model.registration/1");
  EXPECT_EQ(j["mode"], "scan-to-scan");
  EXPECT_TRUE(j["converged"].get<bool>());
  ASSERT_EQ(j["views"].size(), c.views.scans.size());
  std::vector<RigidMotion> fitted;
  for (const auto& v : j["views"]) {
    fitted.push_back(PoseOf(v["world_T_scan"]));
    EXPECT_GT(v["pairs"].get<long long>(), 100);
    EXPECT_TRUE(v["registered"].get<bool>());
    // Residuals at the noise level (0.02 mm along the normal), not at the pose errors' (about 2 mm).
    EXPECT_LT(v["rms"].get<double>(), 0.05);
  }
  // Relative poses: the recorded ones are off by about 2 degrees and 2 mm; the registered ones by a small
  // fraction of that (the views see the part's faces with 0.02 mm noise).
  const RelativeError before =
      WorstRelativeError(c.views.scans, c.views.model_T_scan_recorded, c.views.model_T_scan_true);
  const RelativeError after = WorstRelativeError(c.views.scans, fitted, c.views.model_T_scan_true);
  EXPECT_GT(before.rotation, 1.0 * kDegree);
  EXPECT_LT(after.rotation, 0.05 * kDegree);
  EXPECT_LT(after.displacement, 0.05);
  // The manifest holds the same poses, the per-view residuals and how they were found.
  const ScanSet written = ReadScanSet(dir / "out" / "views.json");
  ASSERT_EQ(written.scans.size(), fitted.size());
  for (std::size_t k = 0; k < fitted.size(); ++k) {
    EXPECT_LT((written.scans[k].world_T_scan.matrix() - fitted[k].matrix()).norm(), 1e-12);
    EXPECT_EQ(written.scans[k].size(), c.views.scans[k].cols());
  }
  const nlohmann::json manifest = nlohmann::json::parse(std::ifstream(dir / "out" / "views.json"));
  EXPECT_EQ(manifest["registration"]["mode"], "scan-to-scan");
  EXPECT_EQ(manifest["registration"]["method"], "tdm");
  EXPECT_EQ(manifest["views"][1]["registration"]["rms"], j["views"][1]["rms"]);
  fs::remove_all(dir);
}

TEST(RegisterCommand, BunnyViewsFromPerturbedPosesAreRecoveredWithProgress) {
  const fs::path conf = test::SharedData("stanford_bunny_scans/bun.conf");
  if (!fs::exists(conf)) GTEST_SKIP() << conf << " is absent";
  const fs::path dir = test::FreshTempDir("register_bunny");
  ScanSet set = ReadScanSet(conf);
  std::vector<RigidMotion> truth;
  std::vector<Eigen::Matrix3Xd> scans;
  std::mt19937_64 rng(11);
  std::normal_distribution<double> gauss(0, 1);
  for (std::size_t k = 0; k < set.scans.size(); ++k) {
    Scan& s = set.scans[k];
    truth.push_back(s.world_T_scan);
    scans.push_back(s.points);
    if (k == 0) continue;
    // 2 degrees about a random axis through the view's centroid, 2 mm along a random direction.
    const Eigen::Vector3d centre = s.world_T_scan * Eigen::Vector3d(s.points.rowwise().mean());
    const Eigen::Vector3d axis = Eigen::Vector3d(gauss(rng), gauss(rng), gauss(rng)).normalized();
    const Eigen::Vector3d shift = 0.002 * Eigen::Vector3d(gauss(rng), gauss(rng), gauss(rng)).normalized();
    const Eigen::Matrix3d rot = Eigen::AngleAxisd(2 * kDegree, axis).toRotationMatrix();
    s.world_T_scan = RigidMotion(rot, centre - rot * centre + shift) * s.world_T_scan;
  }
  WriteScanSet(dir / "views.json", set);
  const test::ShellResult r = Register({(dir / "views.json").string(), "--json"}, true);
  ASSERT_EQ(r.exit_code, 0) << r.out;
  EXPECT_NE(r.out.find("scan2model register: sweep 1: RMS"), std::string::npos);  // progress on stderr
  const nlohmann::json j = nlohmann::json::parse(r.out.substr(r.out.find("{\n")));
  std::vector<RigidMotion> fitted;
  for (const auto& v : j["views"]) fitted.push_back(PoseOf(v["world_T_scan"]));
  // The issue's target for all ten views: every view within 0.5 mm and 0.5 degrees of the reference poses.
  const RelativeError after = WorstRelativeError(scans, fitted, truth);
  EXPECT_LT(after.rotation, 0.5 * kDegree);
  EXPECT_LT(after.displacement, 0.0005);
  fs::remove_all(dir);
}

// The same views read from each source the command takes (a manifest, a Stanford .conf with one PLY per view,
// a recording and an E57 file) and registered with TDM and SDM: every run recovers the relative poses. PDM's
// nearest-sample pairs stall on these views (docs/registration.md): the command must not call that converged.
TEST(RegisterCommand, EveryViewSourceAndErrorTermRegistersThePartViewsOrSaysItDidNot) {
  const fs::path dir = test::FreshTempDir("register_sources");
  const SyntheticCase c = MakeSyntheticCase("part");
  const ScanSet set = RecordedViews(c);
  WriteScanSet(dir / "views.json", set);
  std::ofstream conf(dir / "views.conf");
  for (std::size_t k = 0; k < set.scans.size(); ++k) {
    const std::string ply = "view" + std::to_string(k) + ".ply";
    Scan local = set.scans[k];
    local.world_T_scan = RigidMotion();
    WritePly(dir / ply, local);
    // The Stanford convention: the quaternion of the pose's rotation transposed (scan_set_io.cpp).
    const RigidMotion& pose = set.scans[k].world_T_scan;
    const Eigen::Quaterniond q(Eigen::Matrix3d(pose.rotation().transpose()));
    conf << std::setprecision(17) << "bmesh " << ply << " " << pose.translation().transpose() << " " << q.x()
         << " " << q.y() << " " << q.z() << " " << q.w() << "\n";
  }
  conf.close();
  WriteRecording(dir / "views.s2mrec", set);
  WriteE57(dir / "views.e57", set);  // in metres, the standard's unit: the poses come back in metres
  const RelativeError before =
      WorstRelativeError(c.views.scans, c.views.model_T_scan_recorded, c.views.model_T_scan_true);
  EXPECT_GT(before.rotation, 1.0 * kDegree);
  ASSERT_EQ(set.scans[0].units, "mm");
  const std::vector<std::pair<std::string, std::string>> runs = {{"views.json", "tdm"},
                                                                 {"views.conf", "tdm"},
                                                                 {"views.s2mrec", "tdm"},
                                                                 {"views.e57", "tdm"},
                                                                 {"views.json", "sdm"}};
  for (const auto& [file, method] : runs) {
    SCOPED_TRACE(file + " " + method);
    const test::ShellResult r = Register({(dir / file).string(), "--method", method, "--json", "-q"});
    ASSERT_EQ(r.exit_code, 0) << r.out;
    const nlohmann::json j = nlohmann::json::parse(r.out);
    EXPECT_EQ(j["method"], method);
    // SDM's steps on this part keep moving a view by a few hundredths of a millimetre per sweep (the local
    // quadrics at the faces' edges: docs/registration.md) and stop at the sweep cap, saying so, with poses
    // as close as TDM's.
    if (method == "tdm") {
      EXPECT_TRUE(j["converged"].get<bool>());
    }
    ASSERT_EQ(j["views"].size(), set.scans.size());
    const double to_mm = file == "views.e57" ? 1000.0 : 1.0;
    std::vector<RigidMotion> fitted;
    for (const auto& v : j["views"]) {
      const RigidMotion pose = PoseOf(v["world_T_scan"]);
      fitted.emplace_back(pose.rotation(), to_mm * pose.translation());
    }
    const RelativeError after = WorstRelativeError(c.views.scans, fitted, c.views.model_T_scan_true);
    EXPECT_LT(after.rotation, 0.05 * kDegree);
    EXPECT_LT(after.displacement, 0.05);
  }
  // PDM: its own steps settle on these views (after about 200 sweeps) while the point-to-plane step of its
  // last pairs is still far above the tolerances; the command says the views stalled, not that they
  // converged.
  const test::ShellResult r =
      Register({(dir / "views.json").string(), "--method", "pdm", "--max-sweeps", "1000", "--json"}, true);
  ASSERT_EQ(r.exit_code, 0) << r.out;
  const nlohmann::json j = nlohmann::json::parse(r.out.substr(r.out.find("{\n")));
  EXPECT_FALSE(j["converged"].get<bool>());
  EXPECT_TRUE(j["stalled"].get<bool>());
  EXPECT_LT(j["sweeps"].get<int>(), 1000);
  EXPECT_GT(j["pending_point_to_plane_step"]["angle_deg"].get<double>(), 0.01);
  EXPECT_NE(r.out.find("point-to-point pairs stalled after"), std::string::npos) << r.out;
  fs::remove_all(dir);
}

// The box [-30, 30] x [-20, 20] x [0, 20] seen by two views, each its own points of three faces, noise 0.002,
// both recorded 0.5 degrees and 0.3 mm off the nominal's frame in different ways.
TEST(RegisterCommand, ViewsAreRegisteredToANominalMesh) {
  const fs::path dir = test::FreshTempDir("register_nominal");
  WriteStl(dir / "box.stl", test::BoxMesh(30, 20, 20), false);
  std::mt19937_64 rng(4);
  std::uniform_real_distribution<double> u(0, 1);
  std::normal_distribution<double> noise(0, 0.002);
  ScanSet set;
  std::vector<RigidMotion> truth;
  for (int view = 0; view < 2; ++view) {
    Eigen::Matrix3Xd p(3, 3000);
    for (Eigen::Index i = 0; i < p.cols(); ++i) {
      const double a = u(rng), b = u(rng), e = noise(rng);
      const double side =
          view == 0 ? 1.0 : -1.0;  // view 0 sees +x, +y and the top; view 1 -x, -y and the top
      switch (i % 3) {
        case 0:
          p.col(i) << side * (30 + e), -20 + 40 * a, 20 * b;
          break;
        case 1:
          p.col(i) << -30 + 60 * a, side * (20 + e), 20 * b;
          break;
        default:
          p.col(i) << -30 + 60 * a, -20 + 40 * b, 20 + e;
      }
    }
    // The view's scanner frame: the nominal frame moved by `scanner`; its recorded pose is off by `error`.
    const RigidMotion scanner(RotationAboutAxis(Eigen::Vector3d(1, view, 2).normalized(), 0.3 + view),
                              Eigen::Vector3d(5, -3, 40));
    const RigidMotion error(RotationAboutAxis(Eigen::Vector3d(view, 1, 1).normalized(), 0.5 * kDegree),
                            Eigen::Vector3d(0.3, -0.2 * view, 0.1));
    Scan s;
    s.points = scanner.inverse().apply(p);
    s.world_T_scan = error * scanner;
    s.units = "mm";
    set.scans.push_back(s);
    truth.push_back(scanner);
  }
  WriteScanSet(dir / "views.json", set);
  const test::ShellResult r = Register(
      {(dir / "views.json").string(), "--to", (dir / "box.stl").string(), "--method", "sdm", "--json"}, true);
  ASSERT_EQ(r.exit_code, 0) << r.out;
  // Progress on standard error: every iteration of the common registration, then of each view's.
  EXPECT_NE(r.out.find("scan2model register: all views: iteration 1: RMS"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("scan2model register: view 1: iteration 1: RMS"), std::string::npos) << r.out;
  const nlohmann::json j = nlohmann::json::parse(r.out.substr(r.out.find("{\n")));
  EXPECT_EQ(j["mode"], "to-nominal");
  EXPECT_EQ(j["nominal"]["triangles"], 12);
  for (std::size_t k = 0; k < 2; ++k) {
    const RigidMotion fitted = PoseOf(j["views"][k]["world_T_scan"]);
    const RigidMotion error = fitted * truth[k].inverse();
    // Each view's own three faces fix all six motions: the pose to well within the noise.
    EXPECT_LT(error.angle(), 0.005 * kDegree) << k;
    EXPECT_LT(std::sqrt((fitted.apply(set.scans[k].points) - truth[k].apply(set.scans[k].points))
                            .colwise()
                            .squaredNorm()
                            .mean()),
              0.002)
        << k;
    EXPECT_LT(j["views"][k]["rms"].get<double>(), 0.003) << k;
  }
  fs::remove_all(dir);
}

// The demo block's eight views (recordings/demo_block, poses off by about 2 degrees and 2 mm): the part fit
// measures the block and corrects the poses jointly; registering the same views, each on its own, to the part
// that fit measured gives the same poses to within a few of the fit's standard uncertainties of them.
TEST(RegisterCommand, ViewsAreRegisteredToThePartAFitMeasured) {
  const fs::path dir = test::FreshTempDir("register_part_fit");
  const std::string views = std::string(S2M_SOURCE_DIR) + "/recordings/demo_block/views.json";
  const std::string part = std::string(S2M_SOURCE_DIR) + "/docs/examples/counterbored_block.part.json";
  const test::ShellResult fit = test::Shell(
      test::Quote({S2M_CLI_PATH, "fit", "--model", "part:" + part, views, "-o", (dir / "fit").string()}),
      false);
  ASSERT_EQ(fit.exit_code, 0) << fit.out;
  const nlohmann::json measured = nlohmann::json::parse(std::ifstream(dir / "fit.json"));
  const test::ShellResult r = Register({views, "--to", (dir / "fit.json").string(), "--json"}, true);
  ASSERT_EQ(r.exit_code, 0) << r.out;
  EXPECT_NE(r.out.find("scan2model register: view 7: iteration 1: RMS"), std::string::npos) << r.out;
  const nlohmann::json j = nlohmann::json::parse(r.out.substr(r.out.find("{\n")));
  EXPECT_EQ(j["mode"], "to-part-fit");
  EXPECT_EQ(j["part_fit"]["parameters"], 5);
  ASSERT_EQ(j["views"].size(), measured["views"].size());
  const ScanSet input = ReadScanSet(views);
  for (std::size_t k = 0; k < j["views"].size(); ++k) {
    const RigidMotion joint = PoseOf(measured["views"][k]["world_T_scan"]);
    const RigidMotion alone = PoseOf(j["views"][k]["world_T_scan"]);
    const RigidMotion difference = alone * joint.inverse();
    const nlohmann::json& u = measured["views"][k]["pose_uncertainty"];
    double u_rotation = 0, u_translation = 0;
    for (int i = 0; i < 3; ++i) {
      u_rotation = std::max(u_rotation, u["rotation_deg"][i].get<double>());
      u_translation = std::max(u_translation, u["translation"][i].get<double>());
    }
    EXPECT_LT(difference.angle() / kDegree, 5 * u_rotation) << k;
    // The translation compared at the view's centroid (the pose's translation alone mixes in the rotation).
    const Eigen::Matrix3Xd& points = input.scans[k].points;
    const Eigen::Vector3d centre = joint * Eigen::Vector3d(points.rowwise().mean());
    EXPECT_LT((difference * centre - centre).norm(), 5 * u_translation) << k;
    EXPECT_LT(j["views"][k]["rms"].get<double>(), 2 * measured["views"][k]["rms"].get<double>()) << k;
  }
  // A primitive's fit cannot place views: refused with the reason.
  std::ofstream(dir / "plane.json") << R"({"schema": "scan2model.fit/1", "model": "plane"})";
  const test::ShellResult refused = Register({views, "--to", (dir / "plane.json").string()}, true);
  EXPECT_EQ(refused.exit_code, 3) << refused.out;
  EXPECT_NE(refused.out.find("scan2model.fit/1"), std::string::npos) << refused.out;
  // A part fit document without its members, or naming a part file that is not there.
  std::ofstream(dir / "empty_part_fit.json") << R"({"schema": "scan2model.part_fit/1"})";
  test::ShellResult bad = Register({views, "--to", (dir / "empty_part_fit.json").string()}, true);
  EXPECT_EQ(bad.exit_code, 3) << bad.out;
  EXPECT_NE(bad.out.find("malformed part fit document"), std::string::npos) << bad.out;
  std::ofstream(dir / "lost_part.json")
      << R"({"schema": "scan2model.part_fit/1", "part": {"file": "no_such.part.json"}, "parameters": []})";
  bad = Register({views, "--to", (dir / "lost_part.json").string()}, true);
  EXPECT_EQ(bad.exit_code, 3) << bad.out;
  EXPECT_NE(bad.out.find("no_such.part.json"), std::string::npos) << bad.out;
  fs::remove_all(dir);
}

// A free-form height field without symmetry (a skewed bump on a tilted saddle): any patch of it fixes all six
// motions of a view.
double FreeFormHeight(double x, double y) {
  return 1.5 * std::exp(-((x - 0.7) * (x - 0.7) / 0.8 + (y + 0.4) * (y + 0.4) / 0.5)) + 0.25 * x * x -
         0.2 * x * y + 0.08 * y * y;
}

// Points of z = height(x, y) in the disk of `radius` about `centre`, with isotropic noise.
Eigen::Matrix3Xd HeightFieldPoints(double (*height)(double, double), const Eigen::Vector2d& centre,
                                   double radius, int count, double noise, std::mt19937_64& rng) {
  std::uniform_real_distribution<double> u(-1, 1);
  std::normal_distribution<double> gauss(0, noise);
  Eigen::Matrix3Xd p(3, count);
  for (int i = 0; i < count;) {
    const Eigen::Vector2d q(u(rng), u(rng));
    if (q.norm() > 1) continue;
    const Eigen::Vector2d xy = centre + radius * q;
    p.col(i++) =
        Eigen::Vector3d(xy.x() + gauss(rng), xy.y() + gauss(rng), height(xy.x(), xy.y()) + gauss(rng));
  }
  return p;
}

// Views of a part registered to the FE surface fitted to a scan of it: each view on its own, its points
// beyond the patch's edge left out; a view of a flat patch (it can slide along it) is not registered.
TEST(RegisterCommand, ViewsAreRegisteredToAFittedFreeFormSurface) {
  const fs::path dir = test::FreshTempDir("register_fe_surface");
  std::mt19937_64 rng(11);
  {
    // The scan the surface is fitted to: the square [-3, 3]^2 (its convex hull is the patch).
    std::uniform_real_distribution<double> u(-3, 3);
    std::normal_distribution<double> gauss(0, 0.002);
    std::ofstream out(dir / "scan.xyz");
    out.precision(12);
    for (int i = 0; i < 4000; ++i) {
      const double x = u(rng), y = u(rng);
      out << x + gauss(rng) << " " << y + gauss(rng) << " " << FreeFormHeight(x, y) + gauss(rng) << "\n";
    }
  }
  const test::ShellResult fit =
      test::Shell(test::Quote({S2M_CLI_PATH, "fit", "--model", "fe-surface", (dir / "scan.xyz").string(),
                               "-o", (dir / "surface").string()}),
                  false);
  ASSERT_EQ(fit.exit_code, 0) << fit.out;
  // Three views: the third reaches 1.7 beyond the patch's edge x = 3.
  const std::vector<Eigen::Vector2d> centres = {{-1, -1}, {1, 0.5}, {2.7, -0.5}};
  ScanSet set;
  std::vector<RigidMotion> truth;
  for (std::size_t k = 0; k < centres.size(); ++k) {
    const Eigen::Matrix3Xd p = HeightFieldPoints(FreeFormHeight, centres[k], 2.0, 1500, 0.002, rng);
    const RigidMotion scanner(
        RotationAboutAxis(Eigen::Vector3d(1, double(k), 2).normalized(), 0.4 + double(k)),
        Eigen::Vector3d(0.5, -0.3, 6));
    const RigidMotion error(RotationAboutAxis(Eigen::Vector3d(double(k), 1, 1).normalized(), 1.0 * kDegree),
                            Eigen::Vector3d(0.04, -0.02 * double(k), 0.03));
    Scan s;
    s.points = scanner.inverse().apply(p);
    s.world_T_scan = error * scanner;
    set.scans.push_back(s);
    truth.push_back(scanner);
  }
  WriteScanSet(dir / "views.json", set);
  const test::ShellResult r =
      Register({(dir / "views.json").string(), "--to", (dir / "surface.json").string(), "--json", "-q", "-o",
                (dir / "registered" / "views.json").string()});
  ASSERT_EQ(r.exit_code, 0) << r.out;
  const nlohmann::json j = nlohmann::json::parse(r.out);
  EXPECT_EQ(j["mode"], "to-fe-surface");
  EXPECT_TRUE(fs::exists(dir / "registered" / "views.json"));
  for (std::size_t k = 0; k < centres.size(); ++k) {
    const nlohmann::json& v = j["views"][k];
    EXPECT_TRUE(v["registered"].get<bool>()) << k;
    const RigidMotion fitted = PoseOf(v["world_T_scan"]);
    const Eigen::Matrix3Xd& points = set.scans[k].points;
    const double before = std::sqrt(
        (set.scans[k].world_T_scan.apply(points) - truth[k].apply(points)).colwise().squaredNorm().mean());
    const double after =
        std::sqrt((fitted.apply(points) - truth[k].apply(points)).colwise().squaredNorm().mean());
    std::printf(
        "view %zu: %lld of %lld points on the patch, conditioning %.3g, RMS %.5f, points displaced "
        "%.4f -> %.5f, rotation error %.4f deg\n",
        k, v["points_on_patch"].get<long long>(), v["points"].get<long long>(),
        v["conditioning"].get<double>(), v["rms"].get<double>(), before, after,
        (fitted * truth[k].inverse()).angle() / kDegree);
    // The views inside the patch: their points displaced by less than the scan's noise (from 0.056-0.078
    // before). The view over the edge keeps 57 % of its points and is held less well (conditioning 0.005
    // against 0.02-0.05): within three times the noise (0.0052 measured, from 0.088).
    EXPECT_LT(after, k < 2 ? 0.002 : 0.006) << k;
    EXPECT_LT(after, 0.1 * before) << k;
    // The distances of isotropic noise of 0.002 to the surface.
    EXPECT_NEAR(v["rms"].get<double>(), 0.002, 0.0005) << k;
  }
  // The third view's points beyond x = 3 are left out: 59.5 % of its disk lies inside x < 3, a little less
  // inside the fitted patch (the convex hull of the scan's points).
  const double share = j["views"][2]["points_on_patch"].get<double>() / 1500.0;
  EXPECT_GT(share, 0.5);
  EXPECT_LT(share, 0.62);

  // A flat patch holds no view: it is reported, keeps its pose, and no manifest is written.
  {
    std::uniform_real_distribution<double> u(-3, 3);
    std::ofstream out(dir / "flat.xyz");
    for (int i = 0; i < 600; ++i) out << u(rng) << " " << u(rng) << " " << 1.0 << "\n";
  }
  ASSERT_EQ(
      test::Shell(test::Quote({S2M_CLI_PATH, "fit", "--model", "fe-surface", (dir / "flat.xyz").string(),
                               "--elements", "40", "-o", (dir / "flat").string()}),
                  false)
          .exit_code,
      0);
  ScanSet flat_view;
  Scan s;
  s.points = HeightFieldPoints([](double, double) { return 1.0; }, {0, 0}, 2, 500, 0.002, rng);
  flat_view.scans = {s};
  WriteScanSet(dir / "flat_view.json", flat_view);
  const test::ShellResult flat =
      Register({(dir / "flat_view.json").string(), "--to", (dir / "flat.json").string(), "-o",
                (dir / "flat_registered.json").string()},
               true);
  EXPECT_EQ(flat.exit_code, 4) << flat.out;
  EXPECT_NE(flat.out.find("NOT REGISTERED"), std::string::npos) << flat.out;
  EXPECT_NE(flat.out.find("leave a motion free"), std::string::npos) << flat.out;
  EXPECT_FALSE(fs::exists(dir / "flat_registered.json"));
  // An FE surface document without a usable mesh.
  std::ofstream(dir / "no_mesh.json") << R"({"schema": "scan2model.fe-surface/1", "mesh": {"triangles": 3}})";
  const test::ShellResult bad =
      Register({(dir / "flat_view.json").string(), "--to", (dir / "no_mesh.json").string()}, true);
  EXPECT_EQ(bad.exit_code, 3) << bad.out;
  EXPECT_NE(bad.out.find("malformed fe-surface document"), std::string::npos) << bad.out;
  fs::remove_all(dir);
}

TEST(RegisterCommand, ErrorsNameTheProblemAndWriteNothing) {
  const fs::path dir = test::FreshTempDir("register_errors");
  const SyntheticCase c = MakeSyntheticCase("part");
  ScanSet set = RecordedViews(c);
  // Two views of the part, the second moved 1000 mm away: no pair links them.
  ScanSet apart;
  apart.scans = {set.scans[0], set.scans[1]};
  apart.scans[1].world_T_scan =
      RigidMotion(Eigen::Matrix3d::Identity(), Eigen::Vector3d(1000, 0, 0)) * apart.scans[1].world_T_scan;
  WriteScanSet(dir / "apart" / "views.json", apart);
  test::ShellResult r =
      Register({(dir / "apart" / "views.json").string(), "-o", (dir / "out.json").string()}, true);
  EXPECT_EQ(r.exit_code, 4) << r.out;
  EXPECT_NE(r.out.find("view(s) 1 are not registered: they do not overlap"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("NOT REGISTERED"), std::string::npos) << r.out;
  EXPECT_FALSE(fs::exists(dir / "out.json"));
  // One view.
  ScanSet one;
  one.scans = {set.scans[0]};
  WriteScanSet(dir / "one" / "views.json", one);
  r = Register({(dir / "one" / "views.json").string()}, true);
  EXPECT_EQ(r.exit_code, 3) << r.out;
  EXPECT_NE(r.out.find("needs two or more"), std::string::npos) << r.out;
  // Bad options and files.
  r = Register({(dir / "apart" / "views.json").string(), "--method", "gn"}, true);
  EXPECT_EQ(r.exit_code, 2) << r.out;
  r = Register({(dir / "apart" / "views.json").string(), "--fixed-view", "5"}, true);
  EXPECT_EQ(r.exit_code, 2) << r.out;
  r = Register({(dir / "missing.json").string()}, true);
  EXPECT_EQ(r.exit_code, 3) << r.out;
  EXPECT_NE(r.out.find("missing.json"), std::string::npos) << r.out;
  std::ofstream(dir / "broken.stl") << "solid x\n facet normal 0 0 1\n";
  r = Register({(dir / "apart" / "views.json").string(), "--to", (dir / "broken.stl").string()}, true);
  EXPECT_EQ(r.exit_code, 3) << r.out;
  EXPECT_NE(r.out.find("broken.stl"), std::string::npos) << r.out;
  fs::remove_all(dir);
}

}  // namespace
}  // namespace s2m
