// The real calibration chain on images vdrig did not render: a short session of the "blender" camera (Cycles, the
// simulator's sensor model on its linear render) on the simulated stage, then response recovery from the brackets,
// HDR merge, extrinsics from the corner markers and the kinematic fit (intrinsics given, as a real camera's come from
// its calibration file), observation map, Phong fit with held-out views, and `vdrig compare` on those views. No
// simulator truth reaches the pipeline; the test reads the truth only to measure the extrinsics. Figures and bounds:
// docs/blender.md. Skipped when Blender is not installed or without an OpenGL display.
#include <gtest/gtest.h>

#include <chrono>
#include <cstdio>
#include <filesystem>

#include "vdrig/pipeline/pipeline.hpp"
#include "vdrig/rig/kinematics.hpp"
#include "vdrig/sim/sim_rig.hpp"
#include "vdrig/test/temp_dir.hpp"

namespace vdrig::pipeline {
namespace {
namespace fs = std::filesystem;

double since_s(std::chrono::steady_clock::time_point t) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t).count();
}

TEST(BlenderSession, CalibratedChainPredictsHeldOutViews) {
  if (std::system("command -v blender >/dev/null 2>&1") != 0) GTEST_SKIP() << "blender is not installed";
  const test::TempDir dir("blender_session");
  const auto t0 = std::chrono::steady_clock::now();
  CaptureRequest req;
  req.out_dir = dir.path() / "session";
  // The demo's field of view at 320 x 240, lens distortion on; Cycles at 16 samples a pixel.
  req.rig_config = {
      {"stage", {{"backend", "sim"}}},
      {"camera", {{"backend", "blender"}, {"samples", 16}}},
      {"light", {{"backend", "sim"}}},
      {"sim", {{"scene", "patchwork"}, {"camera", {{"width", 320}, {"height", 240}, {"fx", 400.0}, {"fy", 400.0}}}}}};
  req.scheme = "latlong:4";
  req.exposures_s = {1.0, 0.25, 0.0625};
  auto session = capture_session(req);
  ASSERT_TRUE(session) << session.error().describe();
  const int n = static_cast<int>(session->manifest().views.size());
  ASSERT_GE(n, 20);
  ASSERT_EQ(session->completed_view_count(), n);
  const double capture_s = since_s(t0);

  auto response = calibrate_session_response(session.value());
  ASSERT_TRUE(response) << response.error().describe();
  ASSERT_TRUE(merge_session_hdr(session.value()));
  const auto sc = sim::SimConfig::from_json(req.rig_config["sim"]);
  ASSERT_TRUE(sc);
  GeometryCalibrationOptions options;
  options.camera = sc->camera;  // the rig config's intrinsics, as a real camera's calibration file
  auto cal = calibrate_session_geometry(session.value(), options);
  ASSERT_TRUE(cal) << cal.error().describe();
  auto geometry = session_geometry(session.value());
  ASSERT_TRUE(geometry) << geometry.error().describe();
  // Extrinsics against the truth the Blender scene was rendered with (read here only, to measure them).
  double worst_rot_deg = 0, worst_t_mm = 0;
  for (const auto& rec : cal->views.views) {
    if (!rec.usable()) continue;
    const ViewPose truth = rig::surface_pose(sc->geometry, rec.measured);
    const ViewPose& got = geometry->poses[rec.index];
    worst_rot_deg = std::max(worst_rot_deg, rad_to_deg(Eigen::AngleAxisd(got.R * truth.R.transpose()).angle()));
    worst_t_mm = std::max(worst_t_mm, (got.t - truth.t).norm());
  }

  const std::vector<int> held_out = spread_holdout_views(n, 3);
  auto obs_path = session_obsmap_file(session.value(), 32, 32);
  ASSERT_TRUE(obs_path) << obs_path.error().describe();
  auto obs = fitting::ObsMapReader::open(obs_path.value());
  ASSERT_TRUE(obs) << obs.error().describe();
  fitting::MapFitOptions fit_options;
  fit_options.held_out = held_out;
  auto map = fitting::fit_parameter_map(obs.value(), fit_options);
  ASSERT_TRUE(map) << map.error().describe();
  const fs::path map_path = session->layout().parameter_map_file("phong:1");
  fs::create_directories(map_path.parent_path());
  ASSERT_TRUE(map->write(map_path));
  auto compared = compare_maps(session.value(), {map_path}, held_out);
  if (!compared && compared.error().code == ErrorCode::kUnsupported)
    GTEST_SKIP() << "no OpenGL display: " << compared.error().message;
  ASSERT_TRUE(compared) << compared.error().describe();
  double diffuse = 0, highlight = 0;
  long long diffuse_n = 0, highlight_n = 0;
  for (const ViewComparison& row : compared->rows) {
    diffuse += row.diffuse.mean * row.diffuse.samples;
    diffuse_n += row.diffuse.samples;
    highlight += row.highlight.mean * row.highlight.samples;
    highlight_n += row.highlight.samples;
  }
  ASSERT_GT(diffuse_n, 10000);
  ASSERT_GT(highlight_n, 100);
  diffuse /= diffuse_n;
  highlight /= highlight_n;
  std::printf(
      "%d views (capture %.1f s, all %.1f s); response from view %d; %d views posed by markers, worst %.3f "
      "deg %.2f mm; held out %zu views: mean |render - photo| %.2f diffuse, %.2f highlight (8-bit codes)\n",
      n, capture_s, since_s(t0), response->view, cal->usable_views, worst_rot_deg, worst_t_mm, held_out.size(), diffuse,
      highlight);
  // Bounds: about 1.5x the figures measured (docs/blender.md).
  EXPECT_GE(cal->usable_views, n / 2);
  EXPECT_LT(worst_rot_deg, 0.15);
  EXPECT_LT(worst_t_mm, 1.5);
  EXPECT_LT(diffuse, 3.0);
  EXPECT_LT(highlight, 20.0);
}

}  // namespace
}  // namespace vdrig::pipeline
