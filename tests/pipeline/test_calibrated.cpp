// Calibrated geometry on a simulated session: markers -> per-view extrinsics -> kinematic fit -> calib/ ->
// session_geometry -> observation map, against the simulator's ground truth (write_true_calibration: the truth as
// calib/, the reference), on a perfect and an imperfect rig; an uncalibrated session is refused, never given the
// truth.
#include <gtest/gtest.h>

#include <cstdio>
#include <filesystem>
#include <optional>

#include "vdrig/pipeline/pipeline.hpp"
#include "vdrig/rig/geometry_config.hpp"
#include "vdrig/rig/kinematics_model.hpp"
#include "vdrig/sim/sim_rig.hpp"
#include "vdrig/test/temp_dir.hpp"
#include "vdrig/test/true_calibration.hpp"

namespace vdrig::pipeline {
namespace {
namespace fs = std::filesystem;
namespace model = rig::model;

class Calibrated : public ::testing::Test {
 protected:
  const test::TempDir dir_{"calibrated"};
};

/// What one simulated session gives when calibrated from its markers, against the simulator's ground truth.
struct CalibratedRun {
  int views = 0;
  std::optional<calib::KinematicFit> fit;
  rig::RigGeometry truth;
  double worst_marker_rot_deg = 0, worst_marker_t_mm = 0;  // views posed by their markers
  double worst_model_rot_deg = 0, worst_model_t_mm = 0;    // views posed by the fitted model (80 deg: no markers)
  int model_posed = 0;
  double mean_rel = 0;  // observation maps, calibrated vs ground truth: mean relative radiance difference
  size_t count = 0;
};

/// Captures latlong:3 (31 views; 18 up to 53 deg tilt, 13 at 80 deg) with the simulator's default camera (640x480,
/// distortion on; at the end-to-end test's quarter size the markers are under 5 px in radius and 60 deg views miss
/// the 0.5 mm target) and the rig of `sim_section`, calibrates it and compares with the truth.
void calibrate_simulated(const fs::path& dir, nlohmann::json sim_section, CalibratedRun* run) {
  CaptureRequest req;
  req.out_dir = dir;
  sim_section["scene"] = "patchwork";
  sim_section["camera"] = {{"width", 640}, {"height", 480}};
  req.rig_config = sim::sim_rig_config(sim_section);
  // Aimed with the true geometry, as a session aimed with an earlier calibration (`--geometry views.json`) is: the
  // views land where planned on both rigs, so their figures compare (aimed with the ideal rig, the imperfect rig's
  // 80 deg views move and some find their markers at grazing angles, posed 0.1 deg / 1.2 mm off).
  req.rig_config["geometry"] = rig::geometry_section(sim::SimConfig::from_json(req.rig_config["sim"])->geometry,
                                                     "the simulator's truth (test_calibrated)");
  req.scheme = "latlong:3";
  req.exposures_s = {1.0, 0.25};
  auto session = capture_session(req);
  ASSERT_TRUE(session) << session.error().describe();
  const int n = static_cast<int>(session->manifest().views.size());
  run->views = n;
  ASSERT_GE(n, 10);
  // The pipeline never takes the simulator's truth: an uncalibrated session stops, naming the command to run.
  const auto uncalibrated = session_geometry(session.value());
  ASSERT_FALSE(uncalibrated);
  EXPECT_EQ(uncalibrated.error().code, ErrorCode::kNotFound);
  EXPECT_NE(uncalibrated.error().message.find("vdrig calib extrinsics"), std::string::npos)
      << uncalibrated.error().message;
  const auto unmerged = merge_session_hdr(session.value());
  ASSERT_FALSE(unmerged);
  EXPECT_EQ(unmerged.error().code, ErrorCode::kNotFound);
  EXPECT_NE(unmerged.error().message.find("vdrig calib response"), std::string::npos) << unmerged.error().message;

  // The reference: the simulator's truth written as calib/ (write_true_calibration), and its observation map.
  ASSERT_TRUE(vdrig::test::write_true_calibration(session.value()));
  ASSERT_TRUE(merge_session_hdr(session.value()));
  auto truth = session_geometry(session.value());
  ASSERT_TRUE(truth) << truth.error().describe();
  auto truth_map = build_session_obsmap(session.value(), 32, 32);
  ASSERT_TRUE(truth_map) << truth_map.error().describe();
  // The calibration under test starts from the images alone (the true response is kept: this measures geometry).
  fs::remove(session->layout().views_file());
  fs::remove(session->layout().camera_file());

  auto sc = sim::SimConfig::from_json(req.rig_config["sim"]);
  ASSERT_TRUE(sc);
  run->truth = sc->geometry;
  GeometryCalibrationOptions options;
  options.camera = sc->camera;  // the intrinsics are test_session_calibration's subject; here the true ones
  auto cal = calibrate_session_geometry(session.value(), options);
  ASSERT_TRUE(cal) << cal.error().describe();
  EXPECT_TRUE(fs::exists(session->layout().views_file()));
  EXPECT_TRUE(fs::exists(session->layout().camera_file()));
  // Every view up to 60 deg tilt gives a marker pose; near-grazing ones (80 deg) may not (markers 1/6 as tall).
  int steep = 0;
  for (const auto& rec : cal->views.views) {
    if (rad_to_deg(rec.measured.tilt_rad) <= 65.0) {
      EXPECT_TRUE(rec.usable()) << "view " << rec.index << ": " << rec.error;
    } else {
      ++steep;
    }
  }
  EXPECT_LT(steep, n / 2);
  ASSERT_TRUE(cal->kinematics);
  run->fit = cal->kinematics;

  auto geometry = session_geometry(session.value());
  ASSERT_TRUE(geometry) << geometry.error().describe();
  ASSERT_EQ(geometry->poses.size(), truth->poses.size());
  for (int v = 0; v < n; ++v) {
    EXPECT_FALSE(geometry->excluded[v]) << "kept by default, posed by markers or by the kinematic fit";
    const double rot = rad_to_deg(Eigen::AngleAxisd(geometry->poses[v].R * truth->poses[v].R.transpose()).angle());
    const double dt = (geometry->poses[v].t - truth->poses[v].t).norm();
    if (geometry->kinematic_pose[v]) {
      ++run->model_posed;
      run->worst_model_rot_deg = std::max(run->worst_model_rot_deg, rot);
      run->worst_model_t_mm = std::max(run->worst_model_t_mm, dt);
    } else {
      EXPECT_LT(rot, 0.1) << "view " << v;
      EXPECT_LT(dt, 0.5) << "view " << v;
      run->worst_marker_rot_deg = std::max(run->worst_marker_rot_deg, rot);
      run->worst_marker_t_mm = std::max(run->worst_marker_t_mm, dt);
    }
  }

  // The observation map from the calibrated geometry samples the same radiance as the ground truth's.
  auto map = build_session_obsmap(session.value(), 32, 32);
  ASSERT_TRUE(map) << map.error().describe();
  double sum_rel = 0;
  for (int t = 0; t < 32; ++t)
    for (int s = 0; s < 32; ++s)
      for (int v = 0; v < n; ++v) {
        Eigen::Vector3f a, b, da, db;
        if (truth_map->observation(s, t, v, &a, &da) != fitting::kObsValid) continue;
        if (map->observation(s, t, v, &b, &db) != fitting::kObsValid) continue;
        if (!(a.sum() > 1e-6f)) continue;
        sum_rel += std::abs(b.sum() - a.sum()) / a.sum();
        ++run->count;
      }
  ASSERT_GT(run->count, 1000u);
  run->mean_rel = sum_rel / run->count;

  // --exclude-unposed (recorded in views.json) leaves exactly the kinematically posed views out of the map.
  auto views = calib::read_views_json(session->layout().views_file());
  ASSERT_TRUE(views) << views.error().describe();
  views->exclude_unposed = true;
  ASSERT_TRUE(calib::write_views_json(session->layout().views_file(), views.value()));
  auto strict = session_geometry(session.value());
  ASSERT_TRUE(strict) << strict.error().describe();
  EXPECT_EQ(strict->excluded, geometry->kinematic_pose);

  // Corrupt calibration files are errors, not silent fallbacks to the ground truth.
  ASSERT_TRUE(write_file_atomic(session->layout().views_file(), "{\"format_version\": 1"));
  EXPECT_FALSE(session_geometry(session.value()));
}

void print(const char* what, const CalibratedRun& r) {
  const model::Params p = model::to_params(r.fit->geometry), want = model::to_params(r.truth);
  const model::Params s = r.fit->sigma ? *r.fit->sigma : model::Params{};
  const char* names[] = {"D mm",         "offset x mm",   "offset y mm",     "offset z mm",
                         "pan zero deg", "tilt zero deg", "axis tilt x deg", "axis tilt y deg"};
  std::printf("%s: %d views, %d posed by the model\n", what, r.views, r.model_posed);
  for (int i = 0; i < model::kParamCount; ++i) {
    const double k = i >= model::kPanZero ? rad_to_deg(1.0) : 1.0;
    std::printf("  %-16s truth %9.4f  fitted %9.4f +- %.4f\n", names[i], want[i] * k, p[i] * k, s[i] * k);
  }
  std::printf(
      "  marker poses vs truth: worst %.4f deg, %.3f mm; model-posed views: worst %.4f deg, %.3f mm\n"
      "  observation maps: mean relative radiance difference %.4f %% over %zu observations\n",
      r.worst_marker_rot_deg, r.worst_marker_t_mm, r.worst_model_rot_deg, r.worst_model_t_mm, 100 * r.mean_rel,
      r.count);
}

TEST_F(Calibrated, MarkerPosesReplaceGroundTruthOnAPerfectAndAnImperfectRig) {
  // A perfect rig but for the surface off its axes, and the same with the imperfections: encoder zeros of
  // 0.3 deg and the pan axis tilted 0.5 deg from the surface normal.
  const nlohmann::json perfect = {{"surface_offset_mm", {8.0, -12.0, 5.0}}};
  nlohmann::json imperfect = perfect;
  imperfect["pan_zero_deg"] = 0.3;
  imperfect["tilt_zero_deg"] = 0.3;
  imperfect["pan_axis_tilt_deg"] = {0.3, 0.4};
  CalibratedRun p, q;
  {
    SCOPED_TRACE("perfect rig");
    calibrate_simulated(dir_ / "perfect", perfect, &p);
    if (HasFatalFailure()) return;
    print("perfect rig", p);
  }
  {
    SCOPED_TRACE("imperfect rig");
    calibrate_simulated(dir_ / "imperfect", imperfect, &q);
    if (HasFatalFailure()) return;
    print("imperfect rig", q);
  }
  for (const CalibratedRun* r : {&p, &q}) {
    const model::Params got = model::to_params(r->fit->geometry), want = model::to_params(r->truth);
    EXPECT_LT((r->fit->geometry.surface_offset_mm - r->truth.surface_offset_mm).norm(), 1.0);
    EXPECT_NEAR(got[model::kDistance], want[model::kDistance], 1.0);
    for (int i = model::kPanZero; i < model::kParamCount; ++i)
      EXPECT_NEAR(rad_to_deg(got[i]), rad_to_deg(want[i]), 0.02) << "parameter " << i;  // the target
    EXPECT_TRUE(r->fit->sigma.has_value());
    // The 80 deg views have no markers and are posed by the fitted model; the radiance figure hardly judges them
    // (few texels in view): their pose is asserted here. A model without the axis tilt or the zeros poses them 0.2-0.5
    // deg off.
    EXPECT_GT(r->model_posed, 0);
    EXPECT_LT(r->worst_model_rot_deg, 0.01);
    EXPECT_LT(r->worst_model_t_mm, 1.0);
    EXPECT_LT(r->mean_rel, 0.01);
  }
  // The imperfect rig, calibrated, gives an observation map as close to the truth as the perfect rig's.
  EXPECT_LT(q.mean_rel, 1.25 * p.mean_rel);
}

}  // namespace
}  // namespace vdrig::pipeline
