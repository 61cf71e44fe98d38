// The texel inspector (viewer/texel_inspector.hpp): the data it plots must be the observation map's observations
// and the map's model, the curve must follow the great circle through the peak, held-out views must be marked;
// pick_texel must find the texel under a pixel; `vdrig inspect` must plot a fitted session's texel.
#include <gtest/gtest.h>

#include <cstdlib>
#include <filesystem>

#include "../pipeline/small_session.hpp"
#include "vdrig/core/image_io.hpp"
#include "vdrig/fitting/harmonic_model.hpp"
#include "vdrig/fitting/phong_model.hpp"
#include "vdrig/test/process.hpp"
#include "vdrig/test/temp_dir.hpp"
#include "vdrig/viewer/interactive.hpp"
#include "vdrig/viewer/texel_inspector.hpp"

namespace vdrig::viewer {
namespace {
namespace fs = std::filesystem;

constexpr int kS = 8, kT = 6;

fitting::ParameterMap make_map(const Vec3d& lobe_direction) {
  fitting::ParameterMap map(fitting::parse_model("phong:1").value(), kS, kT, 400.0, 300.0);
  for (int t = 0; t < kT; ++t)
    for (int s = 0; s < kS; ++s) {
      fitting::PhongParams p;
      p.kd = Vec3d(0.2 + 0.05 * s, 0.3, 0.1 + 0.05 * t);
      p.lobes.push_back({Vec3d(1.5, 1.2, 0.9), lobe_direction, 20.0});
      fitting::set_phong_texel(map, s, t, p);
    }
  return map;
}

TEST(Inspect, PlottedDataAreTheObservationsAndTheModel) {
  const Vec3d lobe = direction_from_spherical(deg_to_rad(120), deg_to_rad(30));
  const fitting::ParameterMap map = make_map(lobe);
  // An observation map over 24 views: rings of directions, radiance = model x (1 + a view-dependent error).
  fitting::ObservationMapSpec spec{kS, kT, 400.0, 300.0};
  constexpr int kViews = 24;
  fitting::ObservationMap obs(spec, kViews);
  std::vector<Vec3d> dirs;
  for (int v = 0; v < kViews; ++v) {
    const Vec3d d = direction_from_spherical(deg_to_rad(15.0 * v), deg_to_rad(10.0 + 60.0 * (v % 4) / 3.0));
    dirs.push_back(d);
    for (int t = 0; t < kT; ++t)
      for (int s = 0; s < kS; ++s) {
        const Vec3d rgb = map.evaluate(s, t, d) * (1.0 + 0.01 * (v % 5));
        obs.set(s, t, v, rgb.cast<float>(), d.cast<float>(),
                v == 7 ? fitting::kObsOutside : fitting::kObsValid);  // view 7 never saw the texel
      }
  }
  const int s = 5, t = 2;
  const std::vector<int> held = {3, 11};
  const TexelInspection r = inspect_texel(map, s, t, obs.texel(s, t), held);

  EXPECT_EQ(r.model, "phong:1");
  ASSERT_EQ(r.parameters.size(), map.parameters(s, t).size());
  for (size_t i = 0; i < r.parameters.size(); ++i) EXPECT_EQ(r.parameters[i].second, map.parameters(s, t)[i]);
  // Every valid observation, as stored, with the model's value toward it and its residual.
  ASSERT_EQ(r.observations.size(), static_cast<size_t>(kViews - 1));
  for (const auto& o : r.observations) {
    ASSERT_NE(o.view, 7);
    const Vec3d want = map.evaluate(s, t, dirs[o.view]) * (1.0 + 0.01 * (o.view % 5));
    EXPECT_LT((o.observed - want).norm(), 1e-5 * want.norm()) << "view " << o.view;
    EXPECT_LT((o.model - map.evaluate(s, t, o.direction)).norm(), 1e-12);
    EXPECT_NEAR(o.residual(), (o.model - o.observed).mean(), 1e-12);
    EXPECT_EQ(o.held_out, o.view == 3 || o.view == 11);
    // Its place relative to the great circle through the normal and the lobe.
    const Vec3d u = r.circle_u;
    EXPECT_NEAR(o.circle_deg, rad_to_deg(std::atan2(o.direction.dot(u), o.direction.z())), 1e-9);
  }
  // Peak: the lobe; the curve: the model along d(a) = cos a n + sin a u, through the lobe at a = +30 degrees.
  EXPECT_LT((r.peak_direction - lobe).norm(), 1e-6);  // stored as float
  EXPECT_LT((r.circle_u - Vec3d(lobe.x(), lobe.y(), 0).normalized()).norm(), 1e-6);
  ASSERT_EQ(r.curve.size(), r.curve_deg.size());
  ASSERT_EQ(r.curve_deg.front(), -90.0);
  ASSERT_EQ(r.curve_deg.back(), 90.0);
  size_t peak = 0;
  for (size_t i = 0; i < r.curve.size(); ++i) {
    const double a = deg_to_rad(r.curve_deg[i]);
    const Vec3d d = std::cos(a) * Vec3d::UnitZ() + std::sin(a) * r.circle_u;
    EXPECT_LT((r.curve[i] - map.evaluate(s, t, d)).norm(), 1e-12);
    if (r.curve[i].sum() > r.curve[peak].sum()) peak = i;
  }
  EXPECT_NEAR(r.curve_deg[peak], 30.0, 1.0);
  // Views 8 (azimuth 120, zenith 10) and 10 (azimuth 150) lie on / near the circle's plane.
  for (const auto& o : r.observations)
    if (o.view == 8) {
      EXPECT_NEAR(o.off_circle_deg, 0.0, 1e-6);
    }

  const cv::Mat plot = plot_inspection(r, 800, 450);
  ASSERT_EQ(plot.size(), cv::Size(800, 450));
  ASSERT_EQ(plot.type(), CV_8UC3);
  EXPECT_GT(cv::countNonZero(plot.reshape(1) < 200), 2000) << "the plot draws something";
}

TEST(Inspect, PeakIsTheStrongestLobeOrTheBrightestDirection) {
  // Phong-2: the stronger lobe is the peak, whichever order the lobes are stored in.
  fitting::ParameterMap phong2(fitting::parse_model("phong:2").value(), kS, kT, 400.0, 300.0);
  const Vec3d weak = direction_from_spherical(deg_to_rad(30), deg_to_rad(20));
  const Vec3d strong = direction_from_spherical(deg_to_rad(300), deg_to_rad(40));
  fitting::PhongParams p;
  p.kd = Vec3d(0.2, 0.2, 0.2);
  p.lobes = {{Vec3d(0.3, 0.3, 0.3), weak, 20.0}, {Vec3d(2.0, 2.0, 2.0), strong, 20.0}};
  fitting::set_phong_texel(phong2, 1, 1, p);
  const fitting::ObservationMapSpec spec{kS, kT, 400.0, 300.0};
  const TexelInspection r = inspect_texel(phong2, 1, 1, fitting::ObservationMap(spec, 1).texel(1, 1));
  EXPECT_TRUE(r.observations.empty());
  EXPECT_LT((r.peak_direction - strong).norm(), 1e-6);

  // Another model: the brightest direction of the hemisphere search (1 x 2 degree grid).
  fitting::ParameterMap sh(fitting::parse_model("sh-ls:3").value(), kS, kT, 400.0, 300.0);
  Eigen::MatrixXd c = Eigen::MatrixXd::Zero(9, 3);
  c.row(0).setConstant(1.0);
  c.row(2).setConstant(0.8);  // Y_1^0 ~ z: brightest toward the normal
  fitting::set_harmonic_coefficients(sh, 2, 3, c);
  const TexelInspection q = inspect_texel(sh, 2, 3, fitting::ObservationMap(spec, 1).texel(2, 3));
  double best = 0;
  for (int i = 0; i < 2000; ++i) {
    const Vec3d d = direction_from_spherical(deg_to_rad(i * 0.18), deg_to_rad(89.0 * (i % 97) / 96.0));
    best = std::max(best, sh.evaluate(2, 3, d).mean());
  }
  EXPECT_GE(sh.evaluate(2, 3, q.peak_direction).mean(), best - 1e-3);
}

TEST(Inspect, HeldOutViewsFromTheMapsAttribute) {
  fitting::ParameterMap map = make_map(Vec3d::UnitZ());
  EXPECT_TRUE(held_out_views(map).empty());
  map.image().string_attributes["vdrig.held_out_views"] = "12,4";
  EXPECT_EQ(held_out_views(map), (std::vector<int>{4, 12}));
}

TEST(Inspect, PickTexelFindsTheTexelUnderThePixel) {
  const fitting::ParameterMap map = make_map(Vec3d::UnitZ());
  const CameraModel camera = default_pinhole(400.0, 300.0, 160, 120, 1200.0);
  const ViewPose pose = orbit_pose(Vec3d::Zero(), deg_to_rad(40), deg_to_rad(35), 1200.0);
  for (int t = 0; t < kT; ++t)
    for (int s = 0; s < kS; ++s) {
      const Vec3d centre = texel_centre_mm(s, t, kS, kT, 400.0, 300.0);
      const Vec2d px = camera.project(pose.R * centre + pose.t);
      const auto picked = pick_texel(camera, pose, map, px);
      ASSERT_TRUE(picked) << s << "," << t;
      EXPECT_EQ(*picked, std::make_pair(s, t));
    }
  EXPECT_FALSE(pick_texel(camera, pose, map, Vec2d(-5000, -5000)));
}

TEST(Inspect, CommandPlotsAFittedTexel) {
  const vdrig::test::TempDir dir("inspect_cli");
  auto session = pipeline::test::small_merged_session(dir / "session");
  ASSERT_TRUE(session) << session.error().describe();
  using vdrig::test::run_vdrig;
  using vdrig::test::shell_quote;
  const std::string session_dir = shell_quote((dir / "session").string()),
                    map_file = shell_quote((dir / "map.exr").string());
  const auto fitted = run_vdrig("fit " + session_dir + " --res 8x8 --holdout 2 --out " + map_file, {120});
  ASSERT_EQ(fitted.exit_code, 0) << fitted.err;
  auto map = fitting::ParameterMap::read(dir / "map.exr");
  ASSERT_TRUE(map) << map.error().describe();
  EXPECT_EQ(held_out_views(map.value()).size(), 2u) << "vdrig fit records the held-out views";
  const auto inspected = run_vdrig("inspect " + map_file + " --session " + session_dir + " --texel 3,4 --out " +
                                       shell_quote((dir / "plot.png").string()),
                                   {120});
  ASSERT_EQ(inspected.exit_code, 0) << inspected.err;
  auto plot = read_png(dir / "plot.png");
  ASSERT_TRUE(plot) << plot.error().describe();
  EXPECT_EQ(plot->cols, 960);
  EXPECT_EQ(plot->rows, 540);
  // A texel outside the map is a usage error.
  const auto bad = run_vdrig("inspect " + map_file + " --session " + session_dir + " --texel 8,0 --out " +
                                 shell_quote((dir / "bad.png").string()),
                             {120});
  EXPECT_EQ(bad.exit_code, 2);
}

}  // namespace
}  // namespace vdrig::viewer
