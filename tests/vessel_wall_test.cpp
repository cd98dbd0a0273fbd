// `scan2model fit --model revolution --wall` (pipeline/vessel_wall.cpp, docs/archaeology.md section 10),
// through the command's own path (ComputeFit): a whole vessel scanned inside and out, two-surface rim
// sherds with their breaks, and data that show one surface only.

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <memory>
#include <nlohmann/json.hpp>
#include <set>
#include <string>

#include "one_cloud_fit.h"
#include "pipeline/batch.h"
#include "pipeline/domain_measures.h"
#include "pipeline/exit_code.h"
#include "pipeline/fit_options.h"
#include "registration/scan.h"
#include "synthetic/synthetic_cases.h"

namespace s2m {
namespace {

pipeline::FitOptions WallOptions(const Eigen::Matrix3Xd& points, const std::string& name) {
  pipeline::FitOptions o = test::OneCloudFitOptions(points, name, "revolution");
  o.wall = true;
  return o;
}

// A rim sherd scanned inside and out with its fracture faces, placed rim down.
SherdSpec TwoSurfaceRimSherd(double arc_fraction, double noise, int seed) {
  SherdSpec spec;
  spec.arc_fraction = arc_fraction;
  spec.rim = true;
  spec.inner_surface = true;
  spec.fracture_faces = true;
  spec.upside_down = true;
  spec.noise = noise;
  spec.seed = static_cast<std::uint64_t>(seed);
  return spec;
}

double Number(const nlohmann::json& j) {
  return j.is_number() ? j.get<double>() : std::nan("");
}

// A whole vessel, outer and inner surfaces all round, 0.05 mm noise: the wall 6 mm thick at every height
// within the noise, each row within 4 of its standard uncertainties; the capacity within 3 standard
// uncertainties of the truth's (the inner surface's volume between its ends, by quadrature); both faces
// found with their own points; adequate.
TEST(VesselWall, WholeVesselThicknessAndCapacity) {
  const double noise = 0.05;
  const WallTruth truth = MakeTwoSurfaceVessel(noise, 6000, 7);
  const pipeline::FitOutcome outcome = pipeline::ComputeFit(WallOptions(truth.cloud.points, "vessel"));
  const nlohmann::json& d = outcome.document;
  ASSERT_TRUE(d.contains("wall")) << d.dump().substr(0, 400);
  const nlohmann::json& w = d["wall"];
  EXPECT_EQ(d["adequacy"]["adequate"], true);
  EXPECT_FALSE(w["fragment"].get<bool>());
  EXPECT_TRUE(w["base_thickness"].is_null());  // open at the bottom: no base to measure
  EXPECT_TRUE(w["split"]["base"].is_null());
  // Each face holds about its own 6000 points (a few left out near the rim, where normals mix both).
  EXPECT_GT(w["outer"]["points"].get<int>(), 5500);
  EXPECT_GT(w["inner"]["points"].get<int>(), 5500);
  EXPECT_LT(w["left_out"].get<int>(), 600);
  const nlohmann::json& rows = w["thickness"]["rows"];
  ASSERT_GE(rows.size(), 9u);
  for (const nlohmann::json& row : rows) {
    const double t = row[1].get<double>(), u = Number(row[2]);
    EXPECT_NEAR(t, truth.thickness, noise) << row.dump();
    EXPECT_LT(std::abs(t - truth.thickness), 4 * u) << row.dump();
    EXPECT_LT(u, 0.2 * noise) << row.dump();
  }
  const double capacity = w["capacity"]["value"].get<double>();
  const double capacity_u = Number(w["capacity"]["uncertainty"]);
  EXPECT_LT(std::abs(capacity - truth.capacity), 3 * capacity_u) << capacity << " truth " << truth.capacity;
  EXPECT_LT(std::abs(capacity - truth.capacity), 1e-3 * truth.capacity);
  // The material is the difference of the outer and the inner volumes.
  EXPECT_NEAR(w["material_volume"]["value"].get<double>(),
              w["outer_volume"]["value"].get<double>() - capacity, 1e-6 * capacity);
  // The batch table's columns (docs/batch.md).
  std::set<std::string> columns;
  for (const nlohmann::json& c : pipeline::FlatParameters(d)) columns.insert(c["name"].get<std::string>());
  for (const char* name : {"wall_thickness_min", "wall_thickness_max", "wall_thickness_mean", "capacity",
                           "material_volume", "rim_diameter"})
    EXPECT_TRUE(columns.count(name)) << name;
  EXPECT_NE(outcome.text.find("  capacity          "), std::string::npos);
  EXPECT_NE(outcome.text.find("  wall              thickness "), std::string::npos);
  // The drawing's section through the wall (docs/archaeology.md section 6): the inner surface sampled as the
  // outer, read back from the JSON; at every height both reach, the radial gap between them is at least the
  // wall's thickness (measured along the normal, the shortest way across); the SVG fills the section and the
  // DXF has it as a closed outline.
  const pipeline::VesselMeasures vessel = pipeline::VesselMeasures::FromJson(d["vessel"]);
  ASSERT_EQ(vessel.inner_profile.size(), 51u);
  int compared = 0;
  for (const pipeline::ProfileSample& in : vessel.inner_profile) {
    for (std::size_t i = 1; i < vessel.profile.size(); ++i) {
      const pipeline::ProfileSample &a = vessel.profile[i - 1], &b = vessel.profile[i];
      if (in.height_above_base < a.height_above_base || in.height_above_base > b.height_above_base) continue;
      const double f = (in.height_above_base - a.height_above_base) /
                       std::max(b.height_above_base - a.height_above_base, 1e-12);
      EXPECT_GT(a.radius + f * (b.radius - a.radius) - in.radius, truth.thickness - 3 * noise)
          << "at height " << in.height_above_base;
      ++compared;
      break;
    }
  }
  EXPECT_GT(compared, 40);
  EXPECT_EQ(pipeline::WallSection(vessel).size(), 102u);
  EXPECT_NE(pipeline::ProfileSvg(vessel).find("<polygon"), std::string::npos);
  EXPECT_NE(pipeline::ProfileDxf(vessel).find("POLYLINE\n8\nSECTION\n66\n1\n70\n1\n"), std::string::npos);
  std::printf("whole vessel: thickness %.4f-%.4f, capacity %.1f +- %.1f (truth %.1f)\n",
              w["thickness"]["min"].get<double>(), w["thickness"]["max"].get<double>(), capacity, capacity_u,
              truth.capacity);
}

// A straight-walled pot with its base, scanned inside and out (0.05 mm noise): across the base the radius is
// no function of height, so the underside and the floor are split by their axial offsets (eq. A23b). Each
// face holds its own points, the walls and the base (eq. A21c) are 6 mm thick within the noise, the capacity
// (from the floor up) is within 3 standard uncertainties of the truth's, the floor 6 mm above the underside,
// and the fit is adequate. Split by radial offsets alone (before eq. A23b), the same points gave a fit judged
// not adequate with the floor 16.2 mm up and the capacity 14 % low.
TEST(VesselWall, BaseIsSplitIntoUndersideAndFloor) {
  const double noise = 0.05;
  const WallTruth truth = MakeTwoSurfaceVessel(noise, 6000, 5, true);
  const pipeline::FitOutcome outcome =
      pipeline::ComputeFit(WallOptions(truth.cloud.points, "vessel with a base"));
  const nlohmann::json& d = outcome.document;
  ASSERT_TRUE(d.contains("wall")) << d.dump().substr(0, 400);
  const nlohmann::json& w = d["wall"];
  EXPECT_EQ(d["adequacy"]["adequate"], true) << d["adequacy"].dump();
  ASSERT_TRUE(w["split"]["base"].is_object());
  // The base's two groups (lower, higher): the level points of each surface, the underside's about a fifth
  // of its area (about 1150 points), the floor's fewer (it ends at a smaller radius); the outside's foot
  // beyond the radii the floor reaches belongs to neither group.
  EXPECT_GT(w["split"]["base"]["points"][0].get<int>(), 800);
  EXPECT_GT(w["split"]["base"]["points"][1].get<int>(), 800);
  // Each face holds nearly all of its own 6000 points (eq. 77 leaves out some all along the height, where
  // the estimated normals mix both surfaces, as on the vessel without a base).
  EXPECT_GT(w["outer"]["points"].get<int>(), 5500);
  EXPECT_GT(w["inner"]["points"].get<int>(), 5500);
  const nlohmann::json& rows = w["thickness"]["rows"];
  ASSERT_GE(rows.size(), 9u);
  for (const nlohmann::json& row : rows) {
    const double t = row[1].get<double>(), u = Number(row[2]);
    EXPECT_NEAR(t, truth.thickness, noise) << row.dump();
    EXPECT_LT(std::abs(t - truth.thickness), 4 * u) << row.dump();
  }
  const double capacity = w["capacity"]["value"].get<double>();
  const double capacity_u = Number(w["capacity"]["uncertainty"]);
  EXPECT_LT(std::abs(capacity - truth.capacity), 3 * capacity_u) << capacity << " truth " << truth.capacity;
  // (Not also within 0.1 %: the rim plane at the last points' height is short of the true rim by about
  // their spacing, so the capacity runs low, by 0.5 u on average over 12 seeds and 0.11 % on one of them;
  // docs/archaeology.md section 10.)
  // The inside's bottom is its floor, 6 mm above the underside; the base's thickness near the axis is 6 mm
  // within the noise and 3 of its standard uncertainties (eq. A21c).
  EXPECT_NEAR(w["inner_bottom_height_above_base"].get<double>(), truth.thickness, 3 * noise);
  ASSERT_TRUE(w["base_thickness"].is_object()) << w.dump().substr(0, 400);
  const double base_t = w["base_thickness"]["value"].get<double>();
  const double base_u = Number(w["base_thickness"]["uncertainty"]);
  EXPECT_NEAR(base_t, truth.thickness, noise);
  EXPECT_LT(std::abs(base_t - truth.thickness), 3 * base_u) << base_t << " +- " << base_u;
  EXPECT_LT(w["base_thickness"]["radius"].get<double>(), 4.2);  // within a tenth of the rim radius
  EXPECT_NE(outcome.text.find("  base              thickness "), std::string::npos);
  EXPECT_NE(outcome.text.find("the base split into underside and floor"), std::string::npos);
  std::printf(
      "vessel with a base: thickness %.4f-%.4f, base %.4f +- %.4f at %.3f, capacity %.1f +- %.1f "
      "(truth %.1f), floor %.4f, points %d + %d (base %d + %d), %d left out\n",
      w["thickness"]["min"].get<double>(), w["thickness"]["max"].get<double>(), base_t, base_u,
      w["base_thickness"]["radius"].get<double>(), capacity, capacity_u, truth.capacity,
      w["inner_bottom_height_above_base"].get<double>(), w["outer"]["points"].get<int>(),
      w["inner"]["points"].get<int>(), w["split"]["base"]["points"][0].get<int>(),
      w["split"]["base"]["points"][1].get<int>(), w["left_out"].get<int>());
}

// The points of a pot with its base (`truth`, MakeTwoSurfaceVessel with its base) without one surface's
// points below `height` in the pot's own frame, as where part of its base was not scanned: the outside's
// when `outside`, else the inside's.
Eigen::Matrix3Xd PotWithout(const WallTruth& truth, bool outside, double height) {
  const Eigen::Matrix3Xd local = truth.cloud.world_T_model.inverse().apply(truth.cloud.points);
  std::vector<Eigen::Index> kept;
  for (Eigen::Index j = 0; j < local.cols(); ++j)
    if ((j < truth.cloud.surface_points) != outside || local(2, j) > height) kept.push_back(j);
  return truth.cloud.points(Eigen::all, kept);
}

// The same pot whose floor was not scanned (a narrow opening): the base shows the underside only, so eq.
// A23b's two groups of axial offsets would cut one surface in two by its noise; they lie too close for two
// surfaces (as eq. A23 judges the wall), the base is not split but given whole to the outer surface (its rim
// lies well below where both walls begin), and no base thickness is reported. The outer face holds its
// points and the wall's rows stay right. (The fit says it is not adequate: the inner generatrix folds back
// by eq. A21b near its free lower end; not examined.)
TEST(VesselWall, BaseWithoutItsFloorIsNotSplit) {
  const double noise = 0.05;
  const WallTruth truth = MakeTwoSurfaceVessel(noise, 6000, 5, true);
  // The inside's points up to 12 mm above the underside: its floor (6 mm up) and the foot's turn inside.
  const Eigen::Matrix3Xd points = PotWithout(truth, false, 12.0);
  const pipeline::FitOutcome outcome = pipeline::ComputeFit(WallOptions(points, "pot without its floor"));
  const nlohmann::json& d = outcome.document;
  ASSERT_TRUE(d.contains("wall")) << d.dump().substr(0, 400);
  const nlohmann::json& w = d["wall"];
  EXPECT_TRUE(w["split"]["base"].is_null()) << w["split"].dump();
  EXPECT_TRUE(w["base_thickness"].is_null());
  EXPECT_GT(w["outer"]["points"].get<int>(), 5500);
  for (const nlohmann::json& row : w["thickness"]["rows"])
    EXPECT_NEAR(row[1].get<double>(), truth.thickness, noise) << row.dump();
  std::printf("pot without its floor: adequate %d, %zu points, outer %d, inner %d, thickness %.4f-%.4f\n",
              d["adequacy"]["adequate"].get<bool>() ? 1 : 0, static_cast<std::size_t>(points.cols()),
              w["outer"]["points"].get<int>(), w["inner"]["points"].get<int>(),
              w["thickness"]["min"].get<double>(), w["thickness"]["max"].get<double>());
}

// The same pot standing on a table: its underside (the outside's points less than 4 mm up) was not scanned.
// The base shows the floor only and goes whole to the inner face (its rim lies where both walls begin), so
// the capacity, inside the complete inner surface, is right within 3 standard uncertainties and the fit
// adequate; no base thickness without the underside.
TEST(VesselWall, BaseWithoutItsUndersideGoesToTheFloor) {
  const double noise = 0.05;
  const WallTruth truth = MakeTwoSurfaceVessel(noise, 6000, 5, true);
  const Eigen::Matrix3Xd points = PotWithout(truth, true, 4.0);
  const pipeline::FitOutcome outcome = pipeline::ComputeFit(WallOptions(points, "pot without its underside"));
  const nlohmann::json& d = outcome.document;
  ASSERT_TRUE(d.contains("wall")) << d.dump().substr(0, 400);
  const nlohmann::json& w = d["wall"];
  EXPECT_EQ(d["adequacy"]["adequate"], true) << d["adequacy"].dump().substr(0, 600);
  EXPECT_TRUE(w["split"]["base"].is_null()) << w["split"].dump();
  EXPECT_TRUE(w["base_thickness"].is_null());
  EXPECT_GT(w["inner"]["points"].get<int>(), 5500);
  for (const nlohmann::json& row : w["thickness"]["rows"])
    EXPECT_NEAR(row[1].get<double>(), truth.thickness, noise) << row.dump();
  const double capacity = w["capacity"]["value"].get<double>();
  const double capacity_u = Number(w["capacity"]["uncertainty"]);
  EXPECT_LT(std::abs(capacity - truth.capacity), 3 * capacity_u) << capacity << " truth " << truth.capacity;
  std::printf(
      "pot without its underside: adequate %d, %zu points, outer %d, inner %d, thickness %.4f-%.4f, "
      "capacity %.1f +- %.1f (truth %.1f)\n",
      d["adequacy"]["adequate"].get<bool>() ? 1 : 0, static_cast<std::size_t>(points.cols()),
      w["outer"]["points"].get<int>(), w["inner"]["points"].get<int>(), w["thickness"]["min"].get<double>(),
      w["thickness"]["max"].get<double>(), capacity, capacity_u, truth.capacity);
}

// The same vessel without noise: eq. A21a's band is then narrower than the gaps between the points, so it is
// widened by the gap they leave; the rows are kept but where eq. 77, whose band is then the spline's own
// error, left out most of a face's points (one of eleven, measured), and the wall is 6 mm.
TEST(VesselWall, NoiseFreeVesselRowsAreKeptAndRight) {
  const WallTruth truth = MakeTwoSurfaceVessel(0.0, 6000, 7);
  const pipeline::FitOutcome outcome = pipeline::ComputeFit(WallOptions(truth.cloud.points, "vessel"));
  const nlohmann::json& thickness = outcome.document["wall"]["thickness"];
  EXPECT_LE(thickness["unobserved_rows"].get<int>(), 1);
  ASSERT_GE(thickness["rows"].size(), 10u);
  for (const nlohmann::json& row : thickness["rows"])
    EXPECT_NEAR(row[1].get<double>(), truth.thickness, 0.01) << row.dump();
}

// Two-surface rim sherds with fracture faces (breaks across the wall), 0.05 mm noise, placed rim down, 40,
// 20 and 10 % of the circumference (S2M_WALL_SEEDS seeds each, default 1). Every fit must be right or say
// that it is not: a fit judged adequate has its rim told and drawn up, the rim diameter and the preserved
// fraction within 3 standard uncertainties of the truth and the wall 6 mm within the noise. The 40 % sherd
// of seed 1 must be adequate. Measured over seeds 1-3 (S2M_WALL_SEEDS=3): adequate 3, 3 and 2 of 3 at 40,
// 20 and 10 %, every adequate one right; the other says it is not adequate (docs/archaeology.md
// section 10).
TEST(VesselWall, TwoSurfaceRimSherds) {
  const double noise = 0.05;
  const int seeds = std::getenv("S2M_WALL_SEEDS") ? std::atoi(std::getenv("S2M_WALL_SEEDS")) : 1;
  // S2M_WALL_FIRST_SEED=k runs seeds k .. k + seeds - 1 (to look again at one seed of a long run).
  const int first = std::getenv("S2M_WALL_FIRST_SEED") ? std::atoi(std::getenv("S2M_WALL_FIRST_SEED")) : 1;
  // S2M_WALL_ARC=f runs the sherds of that fraction only.
  const double only_arc = std::getenv("S2M_WALL_ARC") ? std::atof(std::getenv("S2M_WALL_ARC")) : 0.0;
  for (const double arc : {0.4, 0.2, 0.1}) {
    if (only_arc > 0 && std::abs(arc - only_arc) > 1e-9) continue;
    for (int seed = first; seed < first + seeds; ++seed) {
      const SherdTruth truth = MakeSherd(TwoSurfaceRimSherd(arc, noise, seed));
      pipeline::FitOutcome outcome;
      try {
        outcome = pipeline::ComputeFit(WallOptions(truth.cloud.points, "sherd"));
      } catch (const pipeline::FitFailure& e) {  // refused, with its reason: not a wrong number
        std::printf("arc %.2f seed %d: refused: %s\n", arc, seed, e.what());
        EXPECT_LT(arc, 0.3) << e.what();
        continue;
      }
      const nlohmann::json& d = outcome.document;
      const nlohmann::json& w = d["wall"];
      const nlohmann::json& v = d["vessel"];
      const bool adequate = d["adequacy"]["adequate"].get<bool>();
      const double rim = v["rim_diameter"].get<double>(), rim_u = Number(v["rim_diameter_uncertainty"]);
      const auto truth_arc = truth.arc(truth.profile_hi - 1e-9);
      ASSERT_TRUE(truth_arc.has_value());
      const double truth_fraction = (truth_arc->second - truth_arc->first) / (2 * M_PI);
      const nlohmann::json s = v.contains("sherd") ? v["sherd"] : nlohmann::json::object();
      const double fraction = Number(s.value("preserved_fraction", nlohmann::json()));
      const double fraction_u = Number(s.value("preserved_fraction_uncertainty", nlohmann::json()));
      std::printf(
          "arc %.2f seed %d: adequate %d, rim %s, rim diameter %.4f +- %.4f (truth %.4f), thickness "
          "%.4f-%.4f, preserved %.4f +- %.4f (truth %.4f); axis from %s\n",
          arc, seed, adequate ? 1 : 0, s.value("up_from", std::string("-")).c_str(), rim, rim_u,
          truth.rim_diameter, Number(w["thickness"]["min"]), Number(w["thickness"]["max"]), fraction,
          fraction_u, truth_fraction, d["start"]["source"].get<std::string>().c_str());
      if (!adequate) std::printf("  not adequate: %s\n", d["adequacy"].dump().substr(0, 600).c_str());
      if (arc > 0.3 && seed == 1) {
        EXPECT_TRUE(adequate) << "arc " << arc << " seed " << seed << "\n" << outcome.text;
      }
      if (!adequate) continue;
      // With the rim not told, `rim_diameter` is that of the end up in the world (docs/archaeology.md
      // section 9), on these sherds placed rim down the break: only the failure to tell it counts.
      const bool rim_told = s.value("up_from", std::string()) == "rim";
      EXPECT_TRUE(rim_told) << "arc " << arc << " seed " << seed;
      if (rim_told) {
        EXPECT_LT(std::abs(rim - truth.rim_diameter), 3 * rim_u) << "arc " << arc << " seed " << seed;
        EXPECT_LT(std::abs(fraction - truth_fraction), 3 * fraction_u) << "arc " << arc << " seed " << seed;
      }
      EXPECT_NEAR(Number(w["thickness"]["min"]), truth.wall_thickness, noise)
          << "arc " << arc << " seed " << seed << " rows " << w["thickness"]["rows"].dump();
      EXPECT_NEAR(Number(w["thickness"]["max"]), truth.wall_thickness, noise)
          << "arc " << arc << " seed " << seed << " rows " << w["thickness"]["rows"].dump();
    }
  }
}

// Seed 24 of the 40 % rim sherds: without eq. A21a the outer face's free end, bent along the lower break's
// points, gave a thickness row 0.31 mm thin (5.69 mm at 5.6 of its standard uncertainties) in a fit judged
// adequate. The rows where a face is not observed by its own surface's points are left out, counted and
// said; every row left is the wall within the noise.
TEST(VesselWall, RowsWhereAFaceIsNotObservedAreLeftOut) {
  const double noise = 0.05;
  const SherdTruth truth = MakeSherd(TwoSurfaceRimSherd(0.4, noise, 24));
  const pipeline::FitOutcome outcome = pipeline::ComputeFit(WallOptions(truth.cloud.points, "sherd"));
  const nlohmann::json& thickness = outcome.document["wall"]["thickness"];
  EXPECT_GE(thickness["unobserved_rows"].get<int>(), 1);
  ASSERT_GE(thickness["rows"].size(), 8u);
  for (const nlohmann::json& row : thickness["rows"])
    EXPECT_NEAR(row[1].get<double>(), truth.wall_thickness, noise) << row.dump();
  bool said = false;
  for (const std::string& note : outcome.notes)
    said = said || note.find("thickness rows left out: a face is not observed there") != std::string::npos;
  EXPECT_TRUE(said);
}

// Seed 43 of the 10 % rim sherds: the upper break's points carry the inner generatrix into the wall, where it
// doubles back on itself; its own group's points (some of them the break's, put in the group by their radial
// offset) observe the fold, so a row 4.45 mm thin passed (A21a). Eq. A21b tells the fold from the generatrix
// itself: the fit is not adequate, and says which face folds.
TEST(VesselWall, AFoldedGeneratrixIsNotAdequate) {
  const SherdTruth truth = MakeSherd(TwoSurfaceRimSherd(0.1, 0.05, 43));
  const pipeline::FitOutcome outcome = pipeline::ComputeFit(WallOptions(truth.cloud.points, "sherd"));
  const nlohmann::json& adequacy = outcome.document["adequacy"];
  EXPECT_FALSE(adequacy["adequate"].get<bool>());
  bool said = false;
  for (const nlohmann::json& s : adequacy["suggestions"])
    said = said || s.get<std::string>().find("inner surface's generatrix folds back") != std::string::npos;
  EXPECT_TRUE(said) << adequacy.dump();
}

// Data that show one surface (the outside only): refused with a message that says why, not a wall.
TEST(VesselWall, OneSurfaceIsRefused) {
  SherdSpec spec;
  spec.arc_fraction = 1.0;
  spec.rim = true;
  spec.irregular_breaks = false;
  const SherdTruth truth = MakeSherd(spec);
  try {
    pipeline::ComputeFit(WallOptions(truth.cloud.points, "outside.ply"));
    ADD_FAILURE() << "a single surface was fitted as a wall";
  } catch (const pipeline::FitFailure& e) {
    EXPECT_EQ(e.exit_code(), pipeline::kFitError);
    EXPECT_NE(std::string(e.what()).find("outside.ply: --wall: the points do not show two surfaces"),
              std::string::npos)
        << e.what();
  }
  pipeline::FitOptions helical = WallOptions(truth.cloud.points, "outside.ply");
  helical.model = "helical";
  try {
    pipeline::ComputeFit(helical);
    ADD_FAILURE() << "--wall accepted for a helical surface";
  } catch (const pipeline::FitFailure& e) {
    EXPECT_EQ(e.exit_code(), pipeline::kUsage);
  }
}

}  // namespace
}  // namespace s2m
