// Calibrated geometry on a simulated session: markers -> per-view extrinsics -> calib/ -> session_geometry ->
// observation map, against the simulator's ground truth.
#include <gtest/gtest.h>

#include <cstdio>
#include <filesystem>

#include "vdrig/pipeline/pipeline.hpp"
#include "vdrig/sim/sim_rig.hpp"
#include "vdrig/test/temp_dir.hpp"

namespace vdrig::pipeline {
namespace {
namespace fs = std::filesystem;

class Calibrated : public ::testing::Test {
 protected:
  const test::TempDir dir_{"calibrated"};
};

TEST_F(Calibrated, MarkerPosesReplaceGroundTruth) {
  // The simulator's default camera (640x480, distortion on; at the end-to-end test's quarter size the markers are
  // under 5 px in radius and 60 deg views miss the 0.5 mm target), with the surface off the rig's axes.
  CaptureRequest req;
  req.out_dir = dir_ / "session";
  req.rig_config = sim::sim_rig_config({{"scene", "patchwork"},
                                        {"surface_offset_mm", {8.0, -12.0, 5.0}},
                                        {"camera", {{"width", 640}, {"height", 480}}}});
  req.scheme = "latlong:3";
  req.exposures_s = {1.0, 0.25};
  auto session = capture_session(req);
  ASSERT_TRUE(session) << session.error().describe();
  const int n = static_cast<int>(session->manifest().views.size());
  ASSERT_GE(n, 10);
  ASSERT_TRUE(merge_session_hdr(session.value()));

  auto truth = session_geometry(session.value());
  ASSERT_TRUE(truth) << truth.error().describe();
  ASSERT_EQ(truth->source, "simulator ground truth");
  auto truth_map = build_session_obsmap(session.value(), 32, 32);
  ASSERT_TRUE(truth_map) << truth_map.error().describe();

  auto sc = sim::SimConfig::from_json(req.rig_config["sim"]);
  ASSERT_TRUE(sc);
  GeometryCalibrationOptions options;
  options.camera = sc->camera;  // a simulated session has no chessboard views: the caller gives the intrinsics
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
  const Vec3d& o = cal->kinematics->geometry.surface_offset_mm;
  std::printf(
      "%d of %d views usable; fitted offset (%.3f, %.3f, %.3f) mm (truth 8, -12, 5), distance %.3f mm; rms "
      "%.3f mm, %.4f deg\n",
      cal->usable_views, n, o.x(), o.y(), o.z(), cal->kinematics->geometry.camera_distance_mm,
      cal->kinematics->rms_translation_mm, cal->kinematics->rms_rotation_deg);
  EXPECT_LT((o - Vec3d(8.0, -12.0, 5.0)).norm(), 1.0);
  EXPECT_NEAR(cal->kinematics->geometry.camera_distance_mm, sc->geometry.camera_distance_mm, 1.0);

  auto geometry = session_geometry(session.value());
  ASSERT_TRUE(geometry) << geometry.error().describe();
  EXPECT_EQ(geometry->source, "calibrated");
  ASSERT_EQ(geometry->poses.size(), truth->poses.size());
  double worst_rot = 0, worst_t = 0;
  for (int v = 0; v < n; ++v) {
    const double rot = rad_to_deg(Eigen::AngleAxisd(geometry->poses[v].R * truth->poses[v].R.transpose()).angle());
    const double dt = (geometry->poses[v].t - truth->poses[v].t).norm();
    if (geometry->excluded[v]) {
      // Posed by the fitted kinematics: still close.
      EXPECT_LT(rot, 0.2) << "view " << v;
      EXPECT_LT(dt, 2.0) << "view " << v;
      continue;
    }
    EXPECT_LT(rot, 0.1) << "view " << v;
    EXPECT_LT(dt, 0.5) << "view " << v;
    worst_rot = std::max(worst_rot, rot);
    worst_t = std::max(worst_t, dt);
  }
  std::printf("marker poses vs truth: worst rotation %.4f deg, translation %.3f mm\n", worst_rot, worst_t);

  // The observation map from the calibrated geometry samples the same radiance as the ground truth's.
  auto map = build_session_obsmap(session.value(), 32, 32);
  ASSERT_TRUE(map) << map.error().describe();
  double sum_rel = 0;
  size_t count = 0;
  for (int t = 0; t < 32; ++t)
    for (int s = 0; s < 32; ++s)
      for (int v = 0; v < n; ++v) {
        Eigen::Vector3f a, b, da, db;
        if (truth_map->observation(s, t, v, &a, &da) != fitting::kObsValid) continue;
        if (map->observation(s, t, v, &b, &db) != fitting::kObsValid) continue;
        if (!(a.sum() > 1e-6f)) continue;
        sum_rel += std::abs(b.sum() - a.sum()) / a.sum();
        ++count;
      }
  ASSERT_GT(count, 1000u);
  const double mean_rel = sum_rel / count;
  std::printf("observation maps: mean relative radiance difference %.4f %% over %zu observations\n", 100 * mean_rel,
              count);
  EXPECT_LT(mean_rel, 0.01);

  // Corrupt calibration files are errors, not silent fallbacks to the ground truth.
  ASSERT_TRUE(write_file_atomic(session->layout().views_file(), "{\"format_version\": 1"));
  EXPECT_FALSE(session_geometry(session.value()));
}

}  // namespace
}  // namespace vdrig::pipeline
