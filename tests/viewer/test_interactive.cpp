// The interactive viewer loop (viewer/interactive.hpp) driven by scripted input: a frame it saves at captured view k
// must match the headless path, tone_map(render_radiance(same camera, same pose)), since both use the same shader;
// a scripted drag must change the view (to the expected neighbour), and the gamma keys the brightness.
// Needs an X display with OpenGL 3.3 (xvfb-run in CI); skipped with the reason otherwise.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <filesystem>

#include "vdrig/core/image_io.hpp"
#include "vdrig/fitting/parameter_map.hpp"
#include "vdrig/fitting/phong_model.hpp"
#include "vdrig/test/require_gl.hpp"
#include "vdrig/test/temp_dir.hpp"
#include "vdrig/viewer/interactive.hpp"
#include "vdrig/viewer/texel_inspector.hpp"

namespace vdrig::viewer {
namespace {

namespace fs = std::filesystem;

constexpr int kS = 16, kT = 12;
constexpr double kW = 400.0, kH = 300.0, kDistance = 1200.0;
constexpr int kWidth = 160, kHeight = 120;

/// Phong-1 with a diffuse gradient across the surface and a glossy lobe around the mirror of a light at
/// (azimuth 200, zenith 35 degrees): a highlight that moves with the view.
fitting::ParameterMap make_map() {
  fitting::ParameterMap map(fitting::parse_model("phong:1").value(), kS, kT, kW, kH);
  const Vec3d light = direction_from_spherical(deg_to_rad(200), deg_to_rad(35));
  for (int t = 0; t < kT; ++t)
    for (int s = 0; s < kS; ++s) {
      fitting::PhongParams p;
      p.kd = Vec3d(0.15 + 0.4 * s / kS, 0.25, 0.1 + 0.5 * t / kT);
      fitting::PhongLobe lobe;
      lobe.ks = Vec3d(1.6, 1.3, 1.0);
      lobe.direction = mirror_direction(light, Vec3d::UnitZ());
      lobe.shininess = 12.0;
      p.lobes.push_back(lobe);
      fitting::set_phong_texel(map, s, t, p);
    }
  return map;
}

/// Captured views: rings at zenith 20 and 45 degrees, every 60 degrees of azimuth, looking at the centre.
std::vector<ViewPose> captured_views() {
  std::vector<ViewPose> v;
  for (double zen : {20.0, 45.0})
    for (int a = 0; a < 6; ++a)
      v.push_back(orbit_pose(Vec3d::Zero(), deg_to_rad(60.0 * a), deg_to_rad(zen), kDistance));
  return v;
}

class Interactive : public ::testing::Test {
 protected:
  void SetUp() override {
    options_.camera = default_pinhole(kW, kH, kWidth, kHeight, kDistance);
    options_.captured_views = captured_views();
    options_.distance_mm = kDistance;
    options_.max_frames = 3;
    options_.hud = false;  // frames compared pixel by pixel with the headless render
  }

  /// Runs the loop; skips the test without a display.
  ViewerResult run(const ViewerOptions& o) {
    auto r = run_viewer(map_, o);
    if (!r && r.error().code == ErrorCode::kUnsupported) {
      skipped_ = r.error().message;
      return {};
    }
    EXPECT_TRUE(r) << r.error().describe();
    return r ? std::move(r.value()) : ViewerResult{};
  }

  /// The headless path: tone_map(render_radiance(camera, pose)) in an invisible context of its own.
  cv::Mat headless(const CameraModel& cam, const ViewPose& pose, double gamma) {
    auto ctx = GlContext::create(cam.width, cam.height, false);
    if (!ctx) return {};
    auto renderer = SurfaceRenderer::create(map_);
    EXPECT_TRUE(renderer) << renderer.error().describe();
    if (!renderer) return {};
    auto radiance = (*renderer)->render_radiance(cam, pose, options_.render);
    EXPECT_TRUE(radiance) << radiance.error().describe();
    if (!radiance) return {};
    return tone_map(radiance.value(), gamma);
  }

  static double mean_abs_diff(const cv::Mat& a, const cv::Mat& b) {
    cv::Mat d;
    cv::absdiff(a, b, d);
    const cv::Scalar m = cv::mean(d);
    return (m[0] + m[1] + m[2]) / 3.0;
  }
  static double mean_level(const cv::Mat& a) {
    const cv::Scalar m = cv::mean(a);
    return (m[0] + m[1] + m[2]) / 3.0;
  }

  fitting::ParameterMap map_ = make_map();
  ViewerOptions options_;
  const test::TempDir dir_{"interactive"};
  std::string skipped_;
};

#define RUN_OR_SKIP(var, opts)                                                         \
  const ViewerResult var = run(opts);                                                  \
  if (!skipped_.empty()) VDRIG_SKIP_WITHOUT_GL() << "no OpenGL display: " << skipped_; \
  ASSERT_FALSE(var.last_frame.empty())

TEST_F(Interactive, ConstrainedFrameMatchesHeadlessRender) {
  const int k = 8;  // zenith 45, azimuth 120
  ViewerOptions o = options_;
  o.constrained = true;
  o.initial_view = k;
  o.gamma = 1.5;
  o.last_frame_png = dir_ / "frame.png";
  RUN_OR_SKIP(r, o);
  EXPECT_EQ(r.frames, 3);
  EXPECT_EQ(r.mode, ViewCamera::Mode::kConstrained);
  EXPECT_EQ(r.view, k);
  EXPECT_EQ((r.pose.R - o.captured_views[k].R).norm(), 0.0);
  EXPECT_EQ((r.pose.t - o.captured_views[k].t).norm(), 0.0);
  EXPECT_EQ(r.frame_camera.width, kWidth);
  EXPECT_EQ(r.frame_camera.height, kHeight);
  EXPECT_EQ(r.frame_camera.fx, o.camera->fx) << "window framebuffer = camera size: no rescaling";

  auto saved = read_png(o.last_frame_png);
  ASSERT_TRUE(saved) << saved.error().describe();
  ASSERT_EQ(saved->size(), cv::Size(kWidth, kHeight));
  ASSERT_EQ(saved->type(), CV_8UC3);
  const cv::Mat want = headless(r.frame_camera, o.captured_views[k], o.gamma);
  ASSERT_FALSE(want.empty());
  const double mad = mean_abs_diff(saved.value(), want);
  cv::Mat d;
  cv::absdiff(saved.value(), want, d);
  double max_diff = 0;
  cv::minMaxLoc(d.reshape(1), nullptr, &max_diff);
  std::printf("window vs headless at view %d: mean |diff| %.4f codes, max %.0f; mean level %.1f\n", k, mad, max_diff,
              mean_level(want));
  EXPECT_LT(mad, 1.0);
  EXPECT_LE(max_diff, 3.0);
  EXPECT_GT(mean_level(want), 20.0) << "the surface must fill a good part of the frame";
}

TEST_F(Interactive, ScriptedDragMovesToTheNeighbouringView) {
  const int k = 7;  // zenith 45, azimuth 60
  ViewerOptions o = options_;
  o.constrained = true;
  o.initial_view = k;
  RUN_OR_SKIP(still, o);
  o.script = {{1, InputEvent::drag(20, 0)}, {1, InputEvent::drag(20, 0)}, {1, InputEvent::drag_end()}};
  RUN_OR_SKIP(dragged, o);
  // Dragging right moves the camera toward smaller azimuth: the view at azimuth 0 on the same ring.
  EXPECT_EQ(dragged.view, 6);
  EXPECT_EQ(dragged.mode, ViewCamera::Mode::kConstrained);
  const double mad = mean_abs_diff(still.last_frame, dragged.last_frame);
  std::printf("drag view %d -> %d: frames differ by %.2f codes on average\n", k, dragged.view, mad);
  EXPECT_GT(mad, 3.0);
  // And the frame is that view's.
  const cv::Mat want = headless(dragged.frame_camera, o.captured_views[6], o.gamma);
  ASSERT_FALSE(want.empty());
  EXPECT_LT(mean_abs_diff(dragged.last_frame, want), 1.0);

  // Free mode: the drag orbits.
  ViewerOptions f = options_;
  RUN_OR_SKIP(free_still, f);
  f.script = {{1, InputEvent::drag(0, -60)}, {1, InputEvent::drag(-40, 0)}};
  RUN_OR_SKIP(free_dragged, f);
  EXPECT_EQ(free_dragged.mode, ViewCamera::Mode::kFree);
  const SphericalDir s = spherical_from_direction(free_dragged.pose.camera_centre());
  EXPECT_NEAR(rad_to_deg(s.zenith_rad), rad_to_deg(60 * f.camera_settings.rad_per_px), 1e-6);
  EXPECT_NEAR(rad_to_deg(s.azimuth_rad), 270.0 + rad_to_deg(40 * f.camera_settings.rad_per_px), 1e-6);
  EXPECT_GT(mean_abs_diff(free_still.last_frame, free_dragged.last_frame), 1.0);
}

TEST_F(Interactive, GammaKeysChangeBrightness) {
  ViewerOptions o = options_;
  o.constrained = true;
  o.initial_view = 3;
  RUN_OR_SKIP(base, o);
  o.script = {{0, InputEvent::press(ViewerKey::kGammaUp)},
              {1, InputEvent::press(ViewerKey::kGammaUp)},
              {1, InputEvent::press(ViewerKey::kGammaUp)}};
  RUN_OR_SKIP(up, o);
  o.script = {{0, InputEvent::press(ViewerKey::kGammaDown)}, {2, InputEvent::press(ViewerKey::kGammaDown)}};
  RUN_OR_SKIP(down, o);
  EXPECT_NEAR(up.gamma, std::pow(1.25, 3), 1e-12);
  EXPECT_NEAR(down.gamma, std::pow(1.25, -2), 1e-12);
  const double lb = mean_level(base.last_frame), lu = mean_level(up.last_frame), ld = mean_level(down.last_frame);
  std::printf("mean level: gamma 1 %.1f, gamma %.3f %.1f, gamma %.3f %.1f\n", lb, up.gamma, lu, down.gamma, ld);
  EXPECT_GT(lu, lb + 5.0);
  EXPECT_LT(ld, lb - 5.0);
  // The brighter frame is the tone mapping at the new gamma, not just any brightening.
  const cv::Mat want = headless(up.frame_camera, o.captured_views[3], up.gamma);
  ASSERT_FALSE(want.empty());
  EXPECT_LT(mean_abs_diff(up.last_frame, want), 1.0);
}

TEST_F(Interactive, ScreenshotKeyAndQuit) {
  ViewerOptions o = options_;
  o.max_frames = 10;
  o.screenshot_dir = dir_;
  o.script = {{1, InputEvent::press(ViewerKey::kScreenshot)}, {2, InputEvent::press(ViewerKey::kQuit)}};
  RUN_OR_SKIP(r, o);
  EXPECT_EQ(r.frames, 2) << "Q stops the loop before frame 2";
  ASSERT_EQ(r.screenshots.size(), 1u);
  EXPECT_EQ(r.screenshots[0].filename(), "vdrig_view_001.png");
  auto shot = read_png(r.screenshots[0]);
  ASSERT_TRUE(shot) << shot.error().describe();
  EXPECT_EQ(mean_abs_diff(shot.value(), r.last_frame), 0.0);
}

/// The map with every parameter channel scaled (a different, equally valid model of the same surface).
fitting::ParameterMap scaled_map(const fitting::ParameterMap& map, double kd_factor) {
  // A new map: copies of a ParameterMap share their channel planes (cv::Mat).
  fitting::ParameterMap m(map.model_ptr(), map.texels_s(), map.texels_t(), map.width_mm(), map.height_mm());
  for (int t = 0; t < m.texels_t(); ++t)
    for (int s = 0; s < m.texels_s(); ++s) {
      fitting::PhongParams p = fitting::phong_texel(map, s, t);
      p.kd *= kd_factor;
      fitting::set_phong_texel(m, s, t, p);
    }
  return m;
}

TEST_F(Interactive, PhotographAndDifferenceAtACapturedView) {
  const int k = 8;
  // The "photograph": what a brighter surface (Kd x 1.3) would give, so the difference is visible and known.
  const fitting::ParameterMap brighter = scaled_map(map_, 1.3);
  cv::Mat photo, render;
  {
    auto ctx = GlContext::create(kWidth, kHeight, false);
    if (!ctx) VDRIG_SKIP_WITHOUT_GL() << "no OpenGL display: " << ctx.error().message;
    photo =
        (*SurfaceRenderer::create(brighter))->render_radiance(*options_.camera, options_.captured_views[k], {}).value();
    render =
        (*SurfaceRenderer::create(map_))->render_radiance(*options_.camera, options_.captured_views[k], {}).value();
  }
  int photo_loads = 0;
  ViewerOptions o = options_;
  o.photo = [&](int view) -> Result<cv::Mat> {
    EXPECT_EQ(view, k);
    ++photo_loads;
    return photo;
  };
  o.constrained = true;
  o.initial_view = k;
  o.gamma = 1.5;
  o.script = {{0, InputEvent::press(ViewerKey::kCycleDisplay)}};
  RUN_OR_SKIP(shown_photo, o);
  EXPECT_EQ(shown_photo.display, ViewerDisplay::kPhotograph);
  EXPECT_EQ(photo_loads, 1) << "loaded once, kept";
  EXPECT_LT(mean_abs_diff(shown_photo.last_frame, tone_map(photo, 1.5)), 0.01);

  o.script.push_back({1, InputEvent::press(ViewerKey::kCycleDisplay)});
  RUN_OR_SKIP(shown_diff, o);
  EXPECT_EQ(shown_diff.display, ViewerDisplay::kDifference);
  cv::Mat want;
  cv::absdiff(tone_map(render, 1.5), tone_map(photo, 1.5), want);
  want.convertTo(want, CV_8UC3, o.difference_gain);
  std::printf("difference display: mean level %.1f, mean |window - expected| %.3f\n", mean_level(want),
              mean_abs_diff(shown_diff.last_frame, want));
  EXPECT_GT(mean_level(want), 10.0);
  EXPECT_LT(mean_abs_diff(shown_diff.last_frame, want), 0.5);

  // Leaving the captured view shows the render again.
  o.script.push_back({2, InputEvent::press(ViewerKey::kToggleMode)});
  RUN_OR_SKIP(left, o);
  EXPECT_EQ(left.display, ViewerDisplay::kRender);
}

TEST_F(Interactive, SeveralMapsAndTheInspectorOverlay) {
  const std::vector<fitting::ParameterMap> maps = {map_, scaled_map(map_, 0.5)};
  ViewerOptions o = options_;
  o.constrained = true;
  o.initial_view = 3;
  o.script = {{1, InputEvent::press(ViewerKey::kNextModel)}};
  auto cycled = run_viewer(maps, o);
  if (!cycled && cycled.error().code == ErrorCode::kUnsupported) GTEST_SKIP() << cycled.error().message;
  ASSERT_TRUE(cycled) << cycled.error().describe();
  EXPECT_EQ(cycled->model, 1);
  const cv::Mat want = [&] {
    const fitting::ParameterMap first = map_;
    map_ = maps[1];  // what headless() renders
    const cv::Mat m = headless(cycled->frame_camera, o.captured_views[3], o.gamma);
    map_ = first;
    return m;
  }();
  EXPECT_LT(mean_abs_diff(cycled->last_frame, want), 1.0) << "the second map is shown";

  // A click on the frame's centre opens the inspector on the texel there, drawn over the lower right.
  int loads = 0;
  o.observations = [&](int, int) -> Result<fitting::TexelObservations> {
    ++loads;
    return fitting::TexelObservations{};
  };
  o.script = {{1, InputEvent::pick(kWidth / 2.0, kHeight / 2.0)}};
  auto picked = run_viewer(maps, o);
  ASSERT_TRUE(picked) << picked.error().describe();
  const auto texel = pick_texel(picked->frame_camera, o.captured_views[3], map_, Vec2d(kWidth / 2.0, kHeight / 2.0));
  ASSERT_TRUE(texel);
  EXPECT_EQ(picked->inspected, texel);
  EXPECT_EQ(loads, 1);
  const cv::Rect corner(kWidth / 2 + 2, kHeight * 3 / 4, kWidth / 2 - 4, kHeight / 4 - 2);
  const cv::Mat plain = headless(picked->frame_camera, o.captured_views[3], o.gamma);
  EXPECT_GT(mean_abs_diff(picked->last_frame(corner), plain(corner)), 20.0) << "the plot covers the corner";
  const cv::Rect top_left(0, 0, kWidth / 4, kHeight / 4);  // outside the overlay (3/4 of the window at most)
  EXPECT_LT(mean_abs_diff(picked->last_frame(top_left), plain(top_left)), 1.0);

  // Maps of different sizes are refused with the reason.
  fitting::ParameterMap other(fitting::parse_model("phong:1").value(), kS + 1, kT, kW, kH);
  const std::vector<fitting::ParameterMap> mixed = {map_, other};
  auto refused = run_viewer(mixed, o);
  ASSERT_FALSE(refused);
  EXPECT_EQ(refused.error().code, ErrorCode::kInvalidArgument);
  EXPECT_NE(refused.error().message.find("17x12 texels, not 16x12"), std::string::npos) << refused.error().message;
}

// The controller alone: no window needed.
TEST(ViewerController, ModelsDisplaysInspectorAndHud) {
  ViewerOptions o;
  o.captured_views = captured_views();
  o.distance_mm = kDistance;
  ViewerController no_photos(o, 500.0, {"phong:1", "sh-ls:4"});
  no_photos.handle(InputEvent::press(ViewerKey::kToggleMode));
  no_photos.handle(InputEvent::press(ViewerKey::kCycleDisplay));
  EXPECT_EQ(no_photos.display(), ViewerDisplay::kRender) << "no photographs: the render only";

  o.photo = [](int) -> Result<cv::Mat> { return cv::Mat(); };
  ViewerController c(o, 500.0, {"phong:1", "sh-ls:4", "hsh:5"});
  EXPECT_EQ(c.model(), 0);
  EXPECT_NE(c.title().find("phong:1 (map 0 of 0..2)"), std::string::npos) << c.title();
  c.handle(InputEvent::press(ViewerKey::kNextModel));
  c.handle(InputEvent::press(ViewerKey::kNextModel));
  EXPECT_EQ(c.model(), 2);
  c.handle(InputEvent::press(ViewerKey::kNextModel));
  EXPECT_EQ(c.model(), 0) << "wraps";

  c.handle(InputEvent::press(ViewerKey::kCycleDisplay));  // free mode: nothing to compare with
  EXPECT_EQ(c.display(), ViewerDisplay::kRender);
  c.handle(InputEvent::press(ViewerKey::kNext));  // a captured view
  for (const ViewerDisplay want :
       {ViewerDisplay::kPhotograph, ViewerDisplay::kDifference, ViewerDisplay::kRender, ViewerDisplay::kPhotograph}) {
    c.handle(InputEvent::press(ViewerKey::kCycleDisplay));
    EXPECT_EQ(c.display(), want);
  }
  c.handle(InputEvent::press(ViewerKey::kNext));
  EXPECT_EQ(c.display(), ViewerDisplay::kPhotograph) << "kept from view to view";
  c.handle(InputEvent::press(ViewerKey::kToggleMode));
  EXPECT_EQ(c.display(), ViewerDisplay::kRender) << "free mode shows the render";
  const std::string hud = c.hud_line(12.34);
  EXPECT_NE(hud.find("phong:1 (map 0 of 0..2)"), std::string::npos) << hud;
  EXPECT_NE(hud.find("azimuth"), std::string::npos) << hud;
  EXPECT_NE(hud.find("gamma 1"), std::string::npos) << hud;
  EXPECT_NE(hud.find("render - 12.3 ms"), std::string::npos) << hud;
  EXPECT_TRUE(c.hud());
  c.handle(InputEvent::press(ViewerKey::kToggleHud));
  EXPECT_FALSE(c.hud());

  EXPECT_FALSE(c.take_pick_request());
  c.handle(InputEvent::pick(10.5, 20));
  EXPECT_EQ(c.take_pick_request().value(), Vec2d(10.5, 20));
  EXPECT_FALSE(c.take_pick_request());
  c.inspect(std::make_pair(3, 4));
  c.handle(InputEvent::press(ViewerKey::kHideInspector));
  EXPECT_FALSE(c.inspected());
}

TEST(ViewerController, MapsOfOneSessionAndSize) {
  const fitting::ParameterMap a = make_map();
  fitting::ParameterMap b = a;
  const std::vector<std::string> names = {"a.exr", "b.exr"};
  EXPECT_TRUE(check_maps_compatible(std::vector{a, b}, names));
  b.set_source_session("/data/s2");
  EXPECT_TRUE(check_maps_compatible(std::vector{a, b}, names)) << "one map without a recorded session";
  fitting::ParameterMap c = a;
  c.set_source_session("/data/s1");
  const Status other = check_maps_compatible(std::vector{c, b}, names);
  ASSERT_FALSE(other);
  EXPECT_NE(other.error().message.find("b.exr comes from session /data/s2, not /data/s1"), std::string::npos)
      << other.error().message;
  fitting::ParameterMap wide(fitting::parse_model("phong:1").value(), kS, kT, kW + 10, kH);
  EXPECT_FALSE(check_maps_compatible(std::vector{a, wide}, names));
}

TEST(ViewerController, KeysDriveModeStepsGammaAndTitle) {
  ViewerOptions o;
  o.captured_views = captured_views();
  o.distance_mm = kDistance;
  ViewerController c(o, 500.0);
  EXPECT_NE(c.title().find("free"), std::string::npos);
  c.handle(InputEvent::press(ViewerKey::kToggleMode));  // snaps: reset view (zenith 0) -> a zenith-20 view
  EXPECT_EQ(c.camera().mode(), ViewCamera::Mode::kConstrained);
  const int v = c.camera().current_view();
  EXPECT_GE(v, 0);
  EXPECT_LT(v, 6);
  c.handle(InputEvent::press(ViewerKey::kNext));
  EXPECT_EQ(c.camera().current_view(), v + 1);
  EXPECT_NE(c.title().find("captured view " + std::to_string(v + 1) + " of 0..11"), std::string::npos) << c.title();
  c.handle(InputEvent::press(ViewerKey::kGammaUp));
  EXPECT_NE(c.title().find("gamma 1.25"), std::string::npos) << c.title();
  c.handle(InputEvent::scroll(2));  // ignored on a captured view
  c.handle(InputEvent::press(ViewerKey::kReset));
  EXPECT_EQ(c.camera().mode(), ViewCamera::Mode::kFree);
  c.handle(InputEvent::scroll(2));
  EXPECT_NEAR(c.camera().distance_mm(), kDistance * 0.81, 1e-9);
  c.handle(InputEvent::pan(10, 0));  // 10 px at 500 px focal, 972 mm away: 19.44 mm
  EXPECT_NEAR(c.camera().target_mm().x(), -10.0 * kDistance * 0.81 / 500.0, 1e-9);
  EXPECT_FALSE(c.take_screenshot_request());
  c.handle(InputEvent::press(ViewerKey::kScreenshot));
  EXPECT_TRUE(c.take_screenshot_request());
  EXPECT_FALSE(c.take_screenshot_request());
  EXPECT_FALSE(c.quit_requested());
  c.handle(InputEvent::press(ViewerKey::kQuit));
  EXPECT_TRUE(c.quit_requested());

  ViewerOptions bad = o;
  bad.captured_views.clear();
  bad.constrained = true;
  std::string why;
  EXPECT_FALSE(bad.is_valid(&why));
  EXPECT_NE(why.find("captured views"), std::string::npos);
}

TEST(ViewerCameraFit, DefaultPinholeAndFitCamera) {
  const CameraModel c = default_pinhole(400, 300, 1024, 768, 2500);
  // The surface edges at 2500 mm fall 10% inside the limiting image dimension.
  const double half_w_px = c.fx * 200.0 / 2500.0, half_h_px = c.fy * 150.0 / 2500.0;
  EXPECT_NEAR(std::max(half_w_px / 512.0, half_h_px / 384.0), 1.0 / 1.1, 1e-12);
  // Half size: same field of view.
  const CameraModel h = fit_camera(c, 512, 384);
  EXPECT_NEAR(h.fx, c.fx / 2, 1e-12);
  EXPECT_NEAR(h.cx, 255.5, 1e-12);
  // Wider window: letterboxed, centred.
  const CameraModel w = fit_camera(c, 2048, 768);
  EXPECT_NEAR(w.fx, c.fx, 1e-12);
  EXPECT_NEAR(w.cx, c.cx + 512.0, 1e-12);
  EXPECT_NEAR(w.cy, c.cy, 1e-12);
}

}  // namespace
}  // namespace vdrig::viewer
