// Per-view extrinsics from the corner markers and the kinematic fit, against the simulator's ground truth.
#include <gtest/gtest.h>

#include <cstdio>
#include <filesystem>
#include <opencv2/imgproc.hpp>

#include "vdrig/calib/extrinsics.hpp"
#include "vdrig/calib/kinematic.hpp"
#include "vdrig/sim/renderer.hpp"
#include "vdrig/sim/scene.hpp"
#include "vdrig/sim/sim_rig.hpp"
#include "vdrig/test/temp_dir.hpp"

namespace vdrig::calib {
namespace {

struct Fixture {
  sim::SimConfig config;  // default sim camera: 640x480, fx 800, k1 -0.08, k2 0.02
  sim::Scene scene;
  std::shared_ptr<sim::RayTable> rays;
  MarkerLayout layout;

  Fixture() {
    scene = sim::make_scene("patchwork").value();
    rays = std::make_shared<sim::RayTable>(config.camera, config.samples_per_axis);
    layout.centres_mm = scene.marker_centres_mm();
    layout.radius_mm = scene.markers.front().radius_mm;
  }
  cv::Mat render(const rig::RigGeometry& g, const PanTilt& pt) const {
    return sim::render_radiance(scene, *rays, rig::surface_pose(g, pt));
  }
};

Fixture& fixture() {
  static Fixture f;
  return f;
}

PanTilt deg(double pan, double tilt) { return {deg_to_rad(pan), deg_to_rad(tilt)}; }

/// A rough pose as from the commanded position through a nominal rig model: 1 deg and 20 mm off.
ViewPose rough_pose(const PanTilt& pt) {
  rig::RigGeometry nominal;
  nominal.camera_distance_mm += 20.0;
  return rig::surface_pose(nominal, {pt.pan_rad + deg_to_rad(1.0), pt.tilt_rad - deg_to_rad(1.0)});
}

double rotation_error_deg(const Mat3d& a, const Mat3d& b) {
  return rad_to_deg(Eigen::AngleAxisd(a * b.transpose()).angle());
}

TEST(Extrinsics, PosesFromMarkersMatchTruth) {
  const Fixture& f = fixture();
  rig::RigGeometry truth;  // ideal rig
  double worst_rot = 0, worst_t = 0, worst_err = 0, worst_rot_uncorrected = 0;
  for (const PanTilt pt : {deg(0, 0), deg(30, 20), deg(-60, 40), deg(120, 60), deg(200, 60), deg(300, 45)}) {
    const cv::Mat img = f.render(truth, pt);
    const ViewPose gt = rig::surface_pose(truth, pt);
    auto markers = detect_markers(img, f.config.camera, rough_pose(pt), f.layout);
    ASSERT_TRUE(markers) << markers.error().describe();
    auto v = solve_view_extrinsics(markers.value(), f.config.camera, f.layout);
    ASSERT_TRUE(v) << v.error().describe();
    ExtrinsicsOptions no_bias;
    no_bias.correct_centroid_bias = false;
    auto u = solve_view_extrinsics(markers.value(), f.config.camera, f.layout, no_bias);
    ASSERT_TRUE(u);
    const double rot = rotation_error_deg(v->pose.R, gt.R), dt = (v->pose.t - gt.t).norm();
    std::printf(
        "pan %6.1f tilt %5.1f: rotation %.4f deg (uncorrected %.4f), translation %.3f mm (uncorrected %.3f), "
        "reprojection %.4f px\n",
        rad_to_deg(pt.pan_rad), rad_to_deg(pt.tilt_rad), rot, rotation_error_deg(u->pose.R, gt.R), dt,
        (u->pose.t - gt.t).norm(), v->reprojection_error_px);
    EXPECT_LT(rot, 0.1);
    EXPECT_LT(dt, 0.5);
    EXPECT_FALSE(v->excluded);
    worst_rot = std::max(worst_rot, rot);
    worst_t = std::max(worst_t, dt);
    worst_err = std::max(worst_err, v->reprojection_error_px);
    worst_rot_uncorrected = std::max(worst_rot_uncorrected, rotation_error_deg(u->pose.R, gt.R));
  }
  std::printf("worst: rotation %.4f deg (without bias correction %.4f), translation %.3f mm, reprojection %.4f px\n",
              worst_rot, worst_rot_uncorrected, worst_t, worst_err);
}

TEST(Extrinsics, KinematicFitRecoversSurfaceOffset) {
  const Fixture& f = fixture();
  rig::RigGeometry truth;
  truth.camera_distance_mm = 2480.0;
  truth.surface_offset_mm = {12.0, -18.0, 6.0};
  std::vector<KinematicObservation> obs;
  for (const PanTilt pt : {deg(0, 10), deg(90, 30), deg(180, 50), deg(270, 30), deg(45, 60), deg(-135, 45)}) {
    auto v = calibrate_view(f.render(truth, pt), f.config.camera, rough_pose(pt), f.layout);
    ASSERT_TRUE(v) << v.error().describe();
    obs.push_back({static_cast<int>(obs.size()), pt, v->pose});
  }
  auto fit = fit_rig_geometry(obs);
  ASSERT_TRUE(fit) << fit.error().describe();
  const Vec3d& o = fit->geometry.surface_offset_mm;
  std::printf(
      "fitted offset (%.3f, %.3f, %.3f) mm (truth 12, -18, 6), distance %.3f mm (truth 2480); rms residual "
      "%.3f mm, %.4f deg\n",
      o.x(), o.y(), o.z(), fit->geometry.camera_distance_mm, fit->rms_translation_mm, fit->rms_rotation_deg);
  EXPECT_LT((o - truth.surface_offset_mm).norm(), 1.0);
  EXPECT_NEAR(fit->geometry.camera_distance_mm, truth.camera_distance_mm, 1.0);
  EXPECT_LT(fit->max_rotation_deg, 0.1);
  // The ideal model (no offset) departs from the measured poses by about the offset: the residuals can tell.
  const auto ideal = kinematic_residuals(rig::RigGeometry{}, obs);
  EXPECT_GT(ideal.front().translation_mm, 15.0);

  // Too few or degenerate views are errors, not garbage.
  EXPECT_FALSE(fit_rig_geometry(std::span(obs).first(1)));
  std::vector<KinematicObservation> same(3, obs.front());
  EXPECT_FALSE(fit_rig_geometry(same));
}

TEST(Extrinsics, BadInputGivesErrors) {
  const Fixture& f = fixture();
  const PanTilt pt = deg(30, 30);
  const cv::Mat good = f.render(rig::RigGeometry{}, pt);

  const cv::Mat blank = cv::Mat::zeros(good.size(), good.type());
  auto r = calibrate_view(blank, f.config.camera, rough_pose(pt), f.layout);
  ASSERT_FALSE(r);
  EXPECT_EQ(r.error().code, ErrorCode::kNotFound);
  EXPECT_NE(r.error().message.find("found 0 of 4"), std::string::npos) << r.error().message;

  const cv::Mat white(good.size(), good.type(), cv::Scalar::all(0.5));
  EXPECT_FALSE(calibrate_view(white, f.config.camera, rough_pose(pt), f.layout));

  // Marker 2 covered by a patch of paper-like radiance.
  cv::Mat occluded = good.clone();
  const ViewPose gt = rig::surface_pose(rig::RigGeometry{}, pt);
  const Vec2d m2 = f.config.camera.project(gt.to_camera(f.layout.centres_mm[2]));
  const cv::Scalar paper = good.at<cv::Vec3f>(static_cast<int>(m2.y()) + 25, static_cast<int>(m2.x()));
  cv::circle(occluded, cv::Point(static_cast<int>(m2.x()), static_cast<int>(m2.y())), 18, paper, cv::FILLED);
  r = calibrate_view(occluded, f.config.camera, rough_pose(pt), f.layout);
  ASSERT_FALSE(r);
  EXPECT_NE(r.error().message.find("found 3 of 4"), std::string::npos) << r.error().message;
  EXPECT_NE(r.error().message.find("marker 2"), std::string::npos) << r.error().message;

  // A rough pose pointing elsewhere entirely (markers projected off the image).
  const ViewPose away = rig::surface_pose(rig::RigGeometry{}, deg(0, 85));
  EXPECT_FALSE(detect_markers(good, f.config.camera, away, f.layout));

  // Wrong sizes and types.
  EXPECT_FALSE(detect_markers(cv::Mat(), f.config.camera, gt, f.layout));
  EXPECT_FALSE(detect_markers(cv::Mat(100, 100, CV_32FC3, cv::Scalar::all(0.3)), f.config.camera, gt, f.layout));
  EXPECT_FALSE(solve_view_extrinsics({{1, 2}, {3, 4}}, f.config.camera, f.layout));

  // A bad point set is flagged excluded by the reprojection threshold.
  auto markers = detect_markers(good, f.config.camera, rough_pose(pt), f.layout);
  ASSERT_TRUE(markers);
  auto moved = markers.value();
  moved[1].x() += 4.0;
  auto v = solve_view_extrinsics(moved, f.config.camera, f.layout);
  ASSERT_TRUE(v);
  EXPECT_TRUE(v->excluded) << v->reprojection_error_px;
}

TEST(Extrinsics, EightBitFrameGivesNearlyTheSamePose) {
  // Camera codes through the simulator's S-curve: the non-linear response biases partial pixels a little.
  const Fixture& f = fixture();
  const PanTilt pt = deg(60, 35);
  const cv::Mat radiance = f.render(rig::RigGeometry{}, pt);
  const cv::Mat codes = sim::expose(radiance, 0.5 / 0.2, 1.0, f.config.sensor, 1);
  auto v = calibrate_view(codes, f.config.camera, rough_pose(pt), f.layout);
  ASSERT_TRUE(v) << v.error().describe();
  const ViewPose gt = rig::surface_pose(rig::RigGeometry{}, pt);
  const double rot = rotation_error_deg(v->pose.R, gt.R), dt = (v->pose.t - gt.t).norm();
  std::printf("8-bit frame: rotation %.4f deg, translation %.3f mm, reprojection %.4f px\n", rot, dt,
              v->reprojection_error_px);
  EXPECT_LT(rot, 0.3);
  EXPECT_LT(dt, 1.5);
}

TEST(Extrinsics, ViewsJsonRoundTrip) {
  const Fixture& f = fixture();
  ViewsFile file;
  file.layout = f.layout;
  file.max_error_px = 0.5;
  ViewRecord a;
  a.index = 0;
  a.measured = deg(10, 20);
  ViewExtrinsics e;
  e.pose = rig::surface_pose(rig::RigGeometry{}, a.measured);
  e.reprojection_error_px = 0.02;
  e.markers_px = {{1, 2}, {3, 4}, {5, 6}, {7, 8}};
  a.extrinsics = e;
  ViewRecord b;
  b.index = 1;
  b.error = "found 3 of 4 markers";
  file.views = {a, b};
  const test::TempDir dir("views");
  const auto path = dir / "views.json";
  ASSERT_TRUE(write_views_json(path, file));
  auto back = read_views_json(path);
  ASSERT_TRUE(back) << back.error().describe();
  ASSERT_EQ(back->views.size(), 2u);
  EXPECT_TRUE(back->views[0].usable());
  EXPECT_LT(rotation_error_deg(back->views[0].extrinsics->pose.R, e.pose.R), 1e-9);
  EXPECT_LT((back->views[0].extrinsics->pose.t - e.pose.t).norm(), 1e-9);
  EXPECT_NEAR(back->views[0].measured.tilt_rad, a.measured.tilt_rad, 1e-12);
  EXPECT_FALSE(back->views[1].usable());
  EXPECT_EQ(back->views[1].error, b.error);
  EXPECT_DOUBLE_EQ(back->max_error_px, 0.5);
  EXPECT_FALSE(views_from_json(nlohmann::json{{"format_version", 99}}));
}

}  // namespace
}  // namespace vdrig::calib
