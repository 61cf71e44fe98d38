// Planning aims with the geometry the user states, never the simulator's hidden truth: on a simulated imperfect rig
// (encoder zeros and a tilted pan axis the user does not know) the ideal model's views land degrees off what they
// were planned for, while stating the true geometry in the rig config's "geometry" (or passing the calibration's
// views.json with --geometry) lands every view on its requested direction. The truth is the simulator's own parse
// of its "sim" section and rig::view_direction (forward kinematics), not the planner's inverse kinematics.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>

#include "test_support.hpp"
#include "vdrig/capture/plan.hpp"
#include "vdrig/rig/bringup.hpp"
#include "vdrig/rig/geometry_config.hpp"

namespace vdrig::capture {
namespace {
namespace fs = std::filesystem;
using nlohmann::json;

/// The small simulated rig with an imperfect geometry (the truth the user does not know).
json imperfect_sim_config() {
  json rc = testing::small_sim_config();
  rc["sim"]["distance_mm"] = 2000.0;
  rc["sim"]["pan_zero_deg"] = 3.0;
  rc["sim"]["tilt_zero_deg"] = -1.5;
  rc["sim"]["pan_axis_tilt_deg"] = {0.8, -0.5};
  rc["sim"]["surface_offset_mm"] = {6.0, -4.0, 2.5};
  return rc;
}

rig::RigGeometry sim_truth(const json& rc) {
  auto config = sim::SimConfig::from_json(rc["sim"]);
  EXPECT_TRUE(config) << config.error().describe();
  return config->geometry;
}

Result<Manifest> plan(const json& rc, const std::string& scheme = "latlong:4") {
  // The stage's limits do not depend on the stated geometry, and make_rig refuses a bad "geometry" itself: the rig
  // is built without it, so that plan_manifest's own check is what the bad-geometry cases test.
  json without_geometry = rc;
  without_geometry.erase("geometry");
  auto rig = testing::make_sim_rig(without_geometry);
  EXPECT_TRUE(rig) << rig.error().describe();
  PlanRequest req;
  req.rig_config = rc;
  req.scheme = scheme;
  req.bracket = "fixed:0.01";
  req.stage = rig->stage->spec();
  return plan_manifest(req);
}

double angle_rad(const Vec3d& a, const Vec3d& b) { return std::atan2(a.cross(b).norm(), a.dot(b)); }

/// Largest angle between a planned view's requested direction and where the true rig points at its target.
double worst_miss_rad(const Manifest& m, const rig::RigGeometry& truth) {
  double worst = 0.0;
  for (const auto& v : m.views)
    worst = std::max(worst, angle_rad(v.direction.normalized(), rig::view_direction(truth, v.target)));
  return worst;
}

TEST(PlanGeometry, IdealModelMissesAndTheStatedTrueGeometryLandsOnEveryDirection) {
  const json rc = imperfect_sim_config();
  const rig::RigGeometry truth = sim_truth(rc);
  ASSERT_NEAR(truth.pan_zero_rad, deg_to_rad(3.0), 1e-12);

  // (a) No "geometry": the ideal rig at the simulator's distance, not its hidden zeros and axis tilt.
  auto ideal = plan(rc);
  ASSERT_TRUE(ideal) << ideal.error().describe();
  ASSERT_GT(ideal->views.size(), 10u);
  const double miss_ideal = worst_miss_rad(ideal.value(), truth);
  std::printf("ideal model: worst miss %.3f deg over %zu views\n", rad_to_deg(miss_ideal), ideal->views.size());
  EXPECT_GT(miss_ideal, deg_to_rad(1.0)) << "planning used the simulator's hidden truth";
  // About the size of the errors: 3 deg of pan zero, 1.5 of tilt zero, under a degree of axis tilt.
  EXPECT_LT(miss_ideal, deg_to_rad(5.0));

  // (b) The true geometry stated as the user would after calibrating: every view lands where it was asked for.
  json stated = rc;
  stated["geometry"] = {{"distance_mm", 2000.0}, {"surface_offset_mm", {6.0, -4.0, 2.5}}, {"pan_zero_deg", 3.0},
                        {"tilt_zero_deg", -1.5}, {"pan_axis_tilt_deg", {0.8, -0.5}},      {"source", "test"}};
  auto calibrated = plan(stated);
  ASSERT_TRUE(calibrated) << calibrated.error().describe();
  ASSERT_GT(calibrated->views.size(), 10u);
  const double miss_stated = worst_miss_rad(calibrated.value(), truth);
  std::printf("stated true geometry: worst miss %.3g rad\n", miss_stated);
  EXPECT_LT(miss_stated, 1e-6);
  EXPECT_EQ(calibrated->rig_config["geometry"], stated["geometry"]) << "the manifest records the geometry it used";
}

TEST(PlanGeometry, FittedGeometryFromViewsJsonIsWrittenIntoTheConfig) {
  vdrig::test::TempDir dir("plan_geometry_fit");
  fs::create_directories(dir.path());
  const json rc = imperfect_sim_config();
  const rig::RigGeometry truth = sim_truth(rc);
  const fs::path views = dir.path() / "views.json";
  testing::write_text(views, json{{"views", json::array()}, {"kinematics", rig::kinematics_to_json(truth)}}.dump(2));
  auto with = with_fitted_geometry(rc, views);
  ASSERT_TRUE(with) << with.error().describe();
  EXPECT_NEAR((*with)["geometry"]["pan_zero_deg"].get<double>(), 3.0, 1e-12);
  EXPECT_NE((*with)["geometry"]["source"].get<std::string>().find("views.json"), std::string::npos);
  auto m = plan(with.value());
  ASSERT_TRUE(m) << m.error().describe();
  EXPECT_LT(worst_miss_rad(m.value(), truth), 1e-6);

  // A missing file, a file that is not JSON, one without a fit and a malformed fit: errors naming the file.
  testing::write_text(dir.path() / "garbage.json", "{ not json");
  testing::write_text(dir.path() / "nofit.json", json{{"views", json::array()}, {"kinematics", nullptr}}.dump());
  testing::write_text(dir.path() / "badfit.json", json{{"kinematics", {{"camera_distance_mm", "far"}}}}.dump());
  for (const char* name : {"missing.json", "garbage.json", "nofit.json", "badfit.json"}) {
    auto bad = with_fitted_geometry(rc, dir.path() / name);
    ASSERT_FALSE(bad) << name;
    EXPECT_NE(bad.error().message.find(name), std::string::npos) << bad.error().message;
  }
}

/// The error of planning with `geometry` as the config's "geometry" section (empty when it plans).
std::string plan_error(const json& geometry) {
  json rc = testing::small_sim_config();
  rc["geometry"] = geometry;
  auto m = plan(rc, "latlong:2");
  return m ? std::string() : m.error().message;
}

TEST(PlanGeometry, BadGeometrySectionsAreRejectedNamingTheKey) {
  EXPECT_EQ(plan_error({{"distance_mm", 2500}}), "");
  const std::pair<json, const char*> cases[] = {
      {{{"distance_mm", 2500}, {"pan_zero_rad", 0.1}}, "pan_zero_rad"},               // unknown key (wrong unit)
      {{{"distance_mm", 2500}, {"camera_distance_mm", 2500}}, "camera_distance_mm"},  // views.json's spelling
      {{{"distance_mm", "2500"}}, "distance_mm"},                                     // wrong type
      {{{"pan_zero_deg", 1.0}}, "distance_mm"},                                       // required
      {{{"distance_mm", -5}}, "distance_mm"},                                         // out of range
      {{{"distance_mm", 2500}, {"surface_offset_mm", {1, 2}}}, "surface_offset_mm"},
      {{{"distance_mm", 2500}, {"tilt_zero_deg", 270}}, "tilt_zero_deg"},
      {{{"distance_mm", 2500}, {"pan_axis_tilt_deg", {20, 0}}}, "pan_axis_tilt_deg"},
      {{{"distance_mm", 2500}, {"pan_axis_tilt_deg", 0.5}}, "pan_axis_tilt_deg"},
      {{{"distance_mm", 100}, {"surface_offset_mm", {0, 0, 150}}}, "surface_offset_mm"},
      {json::array(), "geometry"},
  };
  for (const auto& [geometry, key] : cases) {
    const std::string why = plan_error(geometry);
    EXPECT_NE(why.find(key), std::string::npos) << geometry.dump() << " -> '" << why << "'";
    EXPECT_NE(why.find("geometry"), std::string::npos) << why;
  }
  // The simulator's distance is read with its type checked too (it used to be swallowed).
  json rc = testing::small_sim_config();
  rc["sim"]["distance_mm"] = "far";
  auto g = geometry_from_rig_config(rc);
  ASSERT_FALSE(g);
  EXPECT_NE(g.error().message.find("distance_mm"), std::string::npos) << g.error().message;
}

TEST(PlanGeometry, RigCheckValidatesTheGeometrySection) {
  rig::BackendRegistry registry;
  sim::register_backends(registry);
  json rc = testing::small_sim_config();
  rc["geometry"] = {{"distance_mm", 2500}, {"pan_axis_tilt_deg", {0.5, 0.25}}};
  auto ok = rig::check_rig_config(rc, registry);
  EXPECT_TRUE(ok.problems.empty()) << ok.problems.front();
  EXPECT_DOUBLE_EQ(ok.effective["geometry"]["pan_axis_tilt_deg"][1].get<double>(), 0.25);
  rc["geometry"]["pan_zero"] = 1;
  auto bad = rig::check_rig_config(rc, registry);
  ASSERT_EQ(bad.problems.size(), 1u);
  EXPECT_NE(bad.problems[0].find("pan_zero"), std::string::npos) << bad.problems[0];
}

TEST(CliGeometry, CaptureWithGeometryRecordsTheFitAndRejectsBadFilesLeavingNoSession) {
  vdrig::test::TempDir root("cli_geometry");
  fs::create_directories(root.path());
  const json rc = imperfect_sim_config();
  const rig::RigGeometry truth = sim_truth(rc);
  const fs::path rig_file = root.path() / "rig.json";
  testing::write_text(rig_file, rc.dump(2));
  const fs::path views = root.path() / "views.json";
  testing::write_text(views, json{{"views", json::array()}, {"kinematics", rig::kinematics_to_json(truth)}}.dump(2));
  const auto capture = [&](const fs::path& geometry, const fs::path& out) {
    return testing::run_process({testing::vdrig_cli(), "capture", "--rig", rig_file.string(), "--scheme", "latlong:2",
                                 "--bracket", "fixed:0.01", "--geometry", geometry.string(), "--out", out.string(),
                                 "--reserve-mb", "0", "--runtime-dir", (root.path() / "run").string()});
  };
  const fs::path good = root.path() / "S";
  const auto r = capture(views, good);
  ASSERT_EQ(r.exit_code, 0) << r.out << r.err;
  auto session = Session::open(good);
  ASSERT_TRUE(session) << session.error().describe();
  const json& geometry = session->manifest().rig_config["geometry"];
  EXPECT_NEAR(geometry["pan_zero_deg"].get<double>(), 3.0, 1e-9) << geometry.dump();
  EXPECT_NEAR(geometry["tilt_zero_deg"].get<double>(), -1.5, 1e-9);
  EXPECT_NEAR(geometry["pan_axis_tilt_deg"][0].get<double>(), 0.8, 1e-9);
  EXPECT_NEAR(geometry["distance_mm"].get<double>(), 2000.0, 1e-9);
  EXPECT_NE(geometry["source"].get<std::string>().find("views.json"), std::string::npos);
  ASSERT_FALSE(session->manifest().views.empty());
  EXPECT_LT(worst_miss_rad(session->manifest(), truth), 1e-6);

  testing::write_text(root.path() / "broken.json", "{\"kinematics\": {\"camera_distance_mm\": ");
  for (const char* name : {"missing.json", "broken.json"}) {
    const fs::path out = root.path() / (std::string("bad_") + name);
    const auto bad = capture(root.path() / name, out);
    EXPECT_NE(bad.exit_code, 0) << bad.out << bad.err;
    EXPECT_NE(bad.err.find("--geometry"), std::string::npos) << bad.err;
    EXPECT_NE(bad.err.find(name), std::string::npos) << bad.err;
    EXPECT_FALSE(fs::exists(out)) << "a session folder was left for a rejected --geometry";
  }
}

TEST(CliGeometry, VdrigdRefusesToStartWithABadGeometry) {
  vdrig::test::TempDir root("vdrigd_geometry");
  fs::create_directories(root.path() / "sessions");
  const fs::path rig_file = root.path() / "rig.json";
  json rc = imperfect_sim_config();
  rc["geometry"] = {{"distance_mm", 2000.0}, {"pan_zero_deg", "3"}};
  testing::write_text(rig_file, rc.dump(2));
  const std::vector<std::string> daemon = {testing::vdrigd_exe(), "--sessions-dir", (root.path() / "sessions").string(),
                                           "--runtime-dir", (root.path() / "run").string()};
  auto with = [&](std::vector<std::string> extra) {
    std::vector<std::string> argv = daemon;
    argv.insert(argv.end(), extra.begin(), extra.end());
    return testing::run_process(argv, {.timeout_s = 30.0});
  };
  const auto bad_section = with({"--rig", rig_file.string()});
  EXPECT_EQ(bad_section.exit_code, 2) << bad_section.out << bad_section.err;
  EXPECT_NE((bad_section.out + bad_section.err).find("pan_zero_deg"), std::string::npos) << bad_section.err;
  const auto missing = with({"--geometry", (root.path() / "missing.json").string()});
  EXPECT_EQ(missing.exit_code, 2) << missing.out << missing.err;
  EXPECT_NE((missing.out + missing.err).find("missing.json"), std::string::npos) << missing.err;
}

}  // namespace
}  // namespace vdrig::capture
