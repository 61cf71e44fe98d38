// ViewCamera (viewer/view_camera.hpp): orbit poses against their definition (camera centre on the sphere, target at
// the principal point, image axes), continuity across the azimuth wrap and at zenith 0, clamping, snapping to the
// nearest captured view, stepping with wrap-around, and drag-to-neighbour on a latitude-longitude set of views.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <random>

#include "vdrig/viewer/view_camera.hpp"

namespace vdrig::viewer {
namespace {

CameraModel test_camera() {
  CameraModel cam;
  cam.width = 640;
  cam.height = 480;
  cam.fx = cam.fy = 800.0;
  cam.cx = 319.5;
  cam.cy = 239.5;
  return cam;
}

double rotation_distance_rad(const Mat3d& a, const Mat3d& b) { return Eigen::AngleAxisd(a.transpose() * b).angle(); }

TEST(ViewCamera, OrbitPoseCentreAndTargetRoundTrip) {
  const CameraModel cam = test_camera();
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> az(0.0, 2 * kPi), zen(0.0, deg_to_rad(89)), dist(200, 6000), off(-150, 150);
  double worst_centre = 0, worst_px = 0, worst_ortho = 0;
  for (int i = 0; i < 200; ++i) {
    const Vec3d target(off(rng), off(rng), 0.0);
    const double a = az(rng), z = zen(rng), d = dist(rng);
    const ViewPose p = orbit_pose(target, a, z, d);
    // Camera centre at the spherical position around the target.
    const Vec3d want = target + d * Vec3d(std::sin(z) * std::cos(a), std::sin(z) * std::sin(a), std::cos(z));
    worst_centre = std::max(worst_centre, (p.camera_centre() - want).norm());
    // The target projects to the principal point, in front of the camera.
    const Vec3d pc = p.to_camera(target);
    EXPECT_GT(pc.z(), 0.0);
    worst_px = std::max(worst_px, (cam.project(pc) - Vec2d(cam.cx, cam.cy)).norm());
    // A proper rotation.
    worst_ortho = std::max(worst_ortho, (p.R * p.R.transpose() - Mat3d::Identity()).norm());
    EXPECT_NEAR(p.R.determinant(), 1.0, 1e-12);
    // Image 'up' (-y) leans toward the surface normal: the far edge of the surface is at the top.
    EXPECT_LE(p.R.row(1).z(), 1e-12);
  }
  std::printf("orbit poses: worst centre error %.2e mm, target off principal point %.2e px, |RR^T - I| %.2e\n",
              worst_centre, worst_px, worst_ortho);
  EXPECT_LT(worst_centre, 1e-9);
  EXPECT_LT(worst_px, 1e-9);
  EXPECT_LT(worst_ortho, 1e-12);
}

TEST(ViewCamera, ResetViewLooksStraightDownWithSurfaceAxes) {
  ViewCamera c(2500.0);
  const ViewPose p = c.pose();
  EXPECT_LT((p.camera_centre() - Vec3d(0, 0, 2500)).norm(), 1e-9);
  // Image x = surface +x, image y (down) = surface -y.
  EXPECT_LT((p.R.row(0).transpose() - Vec3d::UnitX()).norm(), 1e-12);
  EXPECT_LT((p.R.row(1).transpose() + Vec3d::UnitY()).norm(), 1e-12);
}

TEST(ViewCamera, NoFlipAcrossAzimuthWrap) {
  ViewCamera c(1000.0);
  c.set_orbit(deg_to_rad(359.9), deg_to_rad(40), 1000);
  const ViewPose before = c.pose();
  c.drag(-deg_to_rad(0.2) / c.settings().rad_per_px, 0.0);  // drag left: azimuth +0.2 deg, across 0
  EXPECT_NEAR(rad_to_deg(c.azimuth_rad()), 0.1, 1e-9) << "azimuth wrapped into [0, 360)";
  const ViewPose after = c.pose();
  const double turn = rad_to_deg(rotation_distance_rad(before.R, after.R));
  std::printf("azimuth 359.9 -> 0.1 deg: camera turned %.4f deg, moved %.3f mm\n", turn,
              (before.camera_centre() - after.camera_centre()).norm());
  EXPECT_LT(turn, 0.25);
  // Image 'up' keeps its sense (no 180 degree roll).
  EXPECT_GT(before.R.row(1).dot(after.R.row(1)), 0.999);
  // Sweeping the whole turn in small steps never jumps.
  ViewPose prev = c.pose();
  for (int i = 0; i < 400; ++i) {
    c.drag(10.0, 0.0);
    const ViewPose cur = c.pose();
    EXPECT_LT(rotation_distance_rad(prev.R, cur.R), 10.0 * c.settings().rad_per_px + 1e-9) << "step " << i;
    prev = cur;
  }
}

TEST(ViewCamera, ZenithZeroIsWellDefinedAndContinuous) {
  const CameraModel cam = test_camera();
  for (double az_deg : {0.0, 90.0, 200.0, 270.0}) {
    const ViewPose p0 = orbit_pose(Vec3d::Zero(), deg_to_rad(az_deg), 0.0, 1500);
    EXPECT_TRUE(p0.R.allFinite());
    EXPECT_NEAR(p0.R.determinant(), 1.0, 1e-12);
    EXPECT_LT((p0.R.row(2).transpose() + Vec3d::UnitZ()).norm(), 1e-12) << "looks straight down";
    EXPECT_LT((cam.project(p0.to_camera(Vec3d::Zero())) - Vec2d(cam.cx, cam.cy)).norm(), 1e-9);
    // Continuous as the zenith leaves 0 at this azimuth.
    const ViewPose p1 = orbit_pose(Vec3d::Zero(), deg_to_rad(az_deg), 1e-6, 1500);
    EXPECT_LT(rotation_distance_rad(p0.R, p1.R), 1e-5);
  }
  // Dragging down from the pole clamps at zenith 0 rather than going through it.
  ViewCamera c(1500);
  c.set_orbit(deg_to_rad(30), deg_to_rad(5), 1500);
  c.drag(0.0, 1000.0);
  EXPECT_EQ(c.zenith_rad(), 0.0);
  EXPECT_NEAR(rad_to_deg(c.azimuth_rad()), 30.0, 1e-9);
}

TEST(ViewCamera, ClampsZenithAndDistance) {
  ViewCameraSettings s;
  s.min_distance_mm = 300;
  s.max_distance_mm = 5000;
  ViewCamera c(2500, s);
  c.drag(0.0, -1e5);  // drag up far: zenith increases to the limit
  EXPECT_NEAR(rad_to_deg(c.zenith_rad()), 89.0, 1e-9);
  for (int i = 0; i < 200; ++i) c.scroll(1.0);
  EXPECT_NEAR(c.distance_mm(), 300.0, 1e-9);
  for (int i = 0; i < 200; ++i) c.scroll(-1.0);
  EXPECT_NEAR(c.distance_mm(), 5000.0, 1e-9);
  c.scroll(2.0);
  EXPECT_NEAR(c.distance_mm(), 5000.0 * 0.81, 1e-9);
  c.reset();
  EXPECT_NEAR(c.distance_mm(), 2500.0, 1e-9);
  EXPECT_EQ(c.zenith_rad(), 0.0);
}

TEST(ViewCamera, PanMovesTargetWithTheScene) {
  ViewCamera c(2000);  // reset view: image x = +x, image y = -y
  c.pan_by(Vec2d(10.0, 0.0));
  EXPECT_LT((c.target_mm() - Vec3d(-10, 0, 0)).norm(), 1e-12);
  c.pan_by(Vec2d(0.0, 5.0));
  EXPECT_LT((c.target_mm() - Vec3d(-10, 5, 0)).norm(), 1e-12);
  EXPECT_LT((c.pose().camera_centre() - Vec3d(-10, 5, 2000)).norm(), 1e-9);
}

/// Captured poses on a latitude-longitude set: the pole, then rings at zenith 30 and 60 every 45 degrees.
struct LatLongSet {
  std::vector<ViewPose> poses;
  std::vector<std::pair<double, double>> az_zen_deg;
  int index(double az, double zen) const {
    for (size_t i = 0; i < az_zen_deg.size(); ++i)
      if (std::abs(az_zen_deg[i].first - az) < 1e-9 && std::abs(az_zen_deg[i].second - zen) < 1e-9)
        return static_cast<int>(i);
    return -1;
  }
};
LatLongSet latlong_set() {
  LatLongSet s;
  s.az_zen_deg.push_back({270.0, 0.0});
  for (double zen : {30.0, 60.0})
    for (int a = 0; a < 8; ++a) s.az_zen_deg.push_back({45.0 * a, zen});
  for (const auto& [az, zen] : s.az_zen_deg)
    s.poses.push_back(orbit_pose(Vec3d::Zero(), deg_to_rad(az), deg_to_rad(zen), 2500));
  return s;
}

TEST(ViewCamera, SnapPicksNearestCapturedView) {
  const LatLongSet set = latlong_set();
  ViewCamera c(2500);
  c.set_captured_views(set.poses);
  EXPECT_EQ(c.mode(), ViewCamera::Mode::kFree);
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> az(0, 360), zen(0, 85);
  for (int i = 0; i < 300; ++i) {
    c.set_orbit(deg_to_rad(az(rng)), deg_to_rad(zen(rng)), 2500);
    const Vec3d d = c.free_direction();
    // Brute force over the known directions.
    int want = -1;
    double best = 1e9;
    for (size_t k = 0; k < set.az_zen_deg.size(); ++k) {
      const double a = angle_between(
          d, direction_from_spherical(deg_to_rad(set.az_zen_deg[k].first), deg_to_rad(set.az_zen_deg[k].second)));
      if (a < best) {
        best = a;
        want = static_cast<int>(k);
      }
    }
    c.set_mode(ViewCamera::Mode::kFree);
    c.set_orbit(spherical_from_direction(d).azimuth_rad, spherical_from_direction(d).zenith_rad, 2500);
    EXPECT_EQ(c.snap(), want);
    EXPECT_EQ(c.mode(), ViewCamera::Mode::kConstrained);
    EXPECT_EQ(c.current_view(), want);
    // The pose rendered is the captured one, exactly.
    EXPECT_EQ((c.pose().R - set.poses[want].R).norm(), 0.0);
    EXPECT_EQ((c.pose().t - set.poses[want].t).norm(), 0.0);
  }
  // A few hand-checked ones.
  c.set_mode(ViewCamera::Mode::kFree);
  c.set_orbit(deg_to_rad(100), deg_to_rad(33), 2500);
  EXPECT_EQ(c.snap(), set.index(90, 30));
  c.set_mode(ViewCamera::Mode::kFree);
  c.set_orbit(deg_to_rad(350), deg_to_rad(70), 2500);
  EXPECT_EQ(c.snap(), set.index(0, 60));
  c.set_mode(ViewCamera::Mode::kFree);
  c.set_orbit(deg_to_rad(123), deg_to_rad(10), 2500);
  EXPECT_EQ(c.snap(), set.index(270, 0));
}

TEST(ViewCamera, ToggleWithoutViewsStaysFreeAndLeavingKeepsTheView) {
  ViewCamera c(2500);
  EXPECT_FALSE(c.toggle_mode());
  EXPECT_EQ(c.mode(), ViewCamera::Mode::kFree);
  EXPECT_EQ(c.current_view(), -1);
  const LatLongSet set = latlong_set();
  c.set_captured_views(set.poses);
  c.select_view(set.index(135, 60));
  ASSERT_TRUE(c.toggle_mode());
  EXPECT_EQ(c.mode(), ViewCamera::Mode::kFree);
  EXPECT_NEAR(rad_to_deg(c.azimuth_rad()), 135.0, 1e-9);
  EXPECT_NEAR(rad_to_deg(c.zenith_rad()), 60.0, 1e-9);
  EXPECT_NEAR(c.distance_mm(), 2500.0, 1e-9);
  EXPECT_LT((c.pose().camera_centre() - set.poses[set.index(135, 60)].camera_centre()).norm(), 1e-9);
  ASSERT_TRUE(c.toggle_mode());
  EXPECT_EQ(c.current_view(), set.index(135, 60));
}

TEST(ViewCamera, StepWrapsAround) {
  const LatLongSet set = latlong_set();
  const int n = static_cast<int>(set.poses.size());
  ViewCamera c(2500);
  c.set_captured_views(set.poses);
  c.step(-1);  // previous from view 0 wraps to the last
  EXPECT_EQ(c.mode(), ViewCamera::Mode::kConstrained);
  EXPECT_EQ(c.current_view(), n - 1);
  c.step(+1);
  EXPECT_EQ(c.current_view(), 0);
  for (int i = 0; i < n + 3; ++i) c.step(+1);
  EXPECT_EQ(c.current_view(), 3);
  c.select_view(-2 * n - 1);
  EXPECT_EQ(c.current_view(), n - 1);
  // Scrolling does not move a captured view.
  const Vec3d t = c.pose().t;
  c.scroll(3.0);
  EXPECT_EQ((c.pose().t - t).norm(), 0.0);
}

TEST(ViewCamera, DragMovesToNeighbourInThatDirection) {
  const LatLongSet set = latlong_set();
  ViewCamera c(2500);
  c.set_captured_views(set.poses);
  const double step = c.settings().drag_step_px;
  struct Case {
    double az, zen;  // from
    double dx, dy;   // drag, pixels
    double want_az, want_zen;
  };
  // Free-mode image axes at (az, zen): x = e_az, y = e_zen; the camera moves opposite to the drag, so a drag right
  // decreases the azimuth, a drag down decreases the zenith, as a free-mode drag would.
  const Case cases[] = {
      {90, 30, step, 0, 45, 30},    // right: azimuth down one ring step
      {90, 30, -step, 0, 135, 30},  // left: azimuth up
      {90, 30, 0, step, 270, 0},    // down: toward the pole
      {90, 30, 0, -step, 90, 60},   // up: toward the horizon
      {0, 60, step, 0, 315, 60},    // right across the azimuth wrap
      {0, 60, 0, step, 0, 30},      // down from the outer ring
      {0, 60, 0, -step, -1, -1},    // up from the outer ring: nothing that way, stay
  };
  for (const Case& k : cases) {
    const int from = set.index(k.az, k.zen);
    ASSERT_GE(from, 0);
    c.select_view(from);
    c.drag(0.4 * k.dx, 0.4 * k.dy);  // below the step threshold: no move yet
    EXPECT_EQ(c.current_view(), from);
    c.drag(0.6 * k.dx, 0.6 * k.dy);
    const int want = k.want_az < 0 ? from : set.index(k.want_az, k.want_zen);
    EXPECT_EQ(c.current_view(), want) << "from (" << k.az << ", " << k.zen << ") drag (" << k.dx << ", " << k.dy
                                      << ") reached (" << set.az_zen_deg[c.current_view()].first << ", "
                                      << set.az_zen_deg[c.current_view()].second << ")";
  }
  // A partial drag is forgotten on release.
  c.select_view(set.index(90, 30));
  c.drag(0.7 * step, 0);
  c.end_drag();
  c.drag(0.7 * step, 0);
  EXPECT_EQ(c.current_view(), set.index(90, 30));
}

TEST(ViewCamera, DragNeighbourFollowsTheCapturedImageAxes) {
  // Captured views with the image rolled by 180 degrees (as the rig's camera sees some views): the same drag on the
  // screen must then move the other way on the sphere, since the neighbour is chosen in that view's image.
  LatLongSet set = latlong_set();
  const Mat3d roll = Eigen::AngleAxisd(kPi, Vec3d::UnitZ()).toRotationMatrix();
  for (auto& p : set.poses) {
    p.R = roll * p.R;
    p.t = roll * p.t;
  }
  ViewCamera c(2500);
  c.set_captured_views(set.poses);
  c.select_view(set.index(90, 30));
  c.drag(c.settings().drag_step_px, 0);
  EXPECT_EQ(c.current_view(), set.index(135, 30));
  c.select_view(set.index(90, 30));
  c.drag(0, c.settings().drag_step_px);
  EXPECT_EQ(c.current_view(), set.index(90, 60));
}

}  // namespace
}  // namespace vdrig::viewer
